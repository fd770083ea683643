"""The force of the time-domain shell (`solver.time_domain`, a power-law cortex) on an
approach ramp from its free sphere and the hold after it, as a recording of them gives
the protocol (SPEC 11-12).

A cell of radius R, active tension γ_a, K_B(t) = K_B(1 s) t^-β, K_S(t) = K̃_S K_B(t)
(`solver.time_domain.power_law_cortex`, one β), standard bending at K(1 s). The
recording's samples (t_i, δ_i), δ = x0 - x, give the protocol: the cell is its
stress-free droplet at the gap 2R - START_UM at the time t_c where δ passes START_UM
(by the ramp's line), the plate ramps at the recorded speed v (the line of δ against t
over the ramp's contact) to the deepest deformation, then holds as the recording held
(`_hold`): at constant height one Hold "height"; at constant force one Hold "force",
which keeps the force the model's ramp reached and lets its plate creep, so that the
input is the held force, not the recorded (noisy) creep. The recording's pause then
checks the model's creep: the model's force at each recorded gap, to first order,
F_hold + k (x_model(t) - x(t)), k the model's stiffness dF/dδ over the last
STIFFNESS_SHARE of its ramp's depth (a gap off by Δx is a force off by about k Δx at
the ramp's time scale; at the truth x_model = x and the term vanishes). It is simulated by
`solver.protocol_simulation.simulate` at RESOLUTION (FINE, the synthetic experiments'
own) and read at the sample times (linear between the simulation's samples); before
t_c the force is the tension's alone, γ_a R ĝ(δ/R) (`shell_ramp`).

The contact search carries the history's share G_hist of dE*/dl in the contact line's balance
(CONTACT_HISTORY, `solver.time_domain`'s `contact_history`): with it the ramp's steps agree
within 0.1 % and a hold's first step moves its force by 7e-5 (without it FINE reads 5 % below
the converged force and swings with the step; docs/studies/contact-history.md), so the force
is the shell's, not its step's, and scales as `powerlaw_grid` tables it. RESOLUTION and
CONTACT_HISTORY are the ones that make the synthetic recordings (`studies.powerlaw_ramps`) and
the power-law table (`powerlaw_grid`).
"""

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from common.errors import InputError, SolverError
from common.names import HOLD_KINDS
from solver.droplet_table import DEPTH_MAX, unit_force_per_tension
from solver.model import Shell
from solver.protocol import Hold, Protocol, Ramp
from solver.protocol_simulation import FINE, Recording, Sampling, simulate
from solver.time_domain import power_law_cortex

START_UM = 0.01          # the stress-free droplet's gap below 2R (µm)
RESOLUTION = FINE
SAMPLE_HZ = 100.0        # the simulation's samples on ramp and hold, read linearly between
STIFFNESS_SHARE = 0.1    # the ramp's stiffness at its end: over this share of its depth (`_stiffness_nN_per_um`)
CONTACT_HISTORY = True   # the history's share of dE*/dl in the contact search (module doc)


@dataclass(frozen=True)
class RampHold:
    """A recorded ramp and the hold after it: sample times (s), wedge heights x (µm),
    how many of the samples are the ramp's (the rest the hold's), and how it was held
    ("height" or "force")."""

    time_s: npt.NDArray[np.float64]
    x_um: npt.NDArray[np.float64]
    ramp_samples: int
    hold: str = "height"

    def __post_init__(self) -> None:
        if self.hold not in HOLD_KINDS:
            raise InputError(f"a hold is at constant {' or '.join(HOLD_KINDS)} (got {self.hold!r})")
        if self.time_s.shape != self.x_um.shape or not 2 <= self.ramp_samples <= self.time_s.size:
            raise InputError("a ramp and hold needs matching times and heights and at least two ramp samples")
        if np.any(np.diff(self.time_s) < 0):
            raise InputError("a ramp and hold's sample times must not decrease")

    def speed_um_per_s(self, x0_um: float) -> tuple[float, float]:
        """(v, t_c): the ramp's speed (µm/s) from the line of x against t over its contact
        (x < x0), and the time where δ = x0 - x passes START_UM on that line."""
        t, x = self.time_s[:self.ramp_samples], self.x_um[:self.ramp_samples]
        on = x < x0_um
        if on.sum() < 2:
            raise InputError("the ramp has fewer than two samples in contact")
        slope, icpt = np.polyfit(t[on], x[on], 1)
        if slope >= 0:
            raise InputError("the ramp does not press the cell (its height does not fall)")
        return float(-slope), float((x0_um - START_UM - icpt) / slope)


def _hold(history: RampHold, t_end: float) -> tuple[Hold, ...]:
    """The hold after the ramp, as recorded (module doc): none, or one Hold of its kind."""
    duration = float(history.time_s[-1] - t_end)
    return (Hold(duration, history.hold),) if history.time_s.size > history.ramp_samples and duration > 0 else ()


def _stiffness_nN_per_um(rec: Recording, t_end: float, top_um: float, depth_um: float) -> float:
    """dF/dδ (nN/µm) of the simulated ramp over its last STIFFNESS_SHARE of depth, at least
    its last three samples (a line)."""
    ramp = np.nonzero(rec.time_s <= t_end + 1e-9)[0]
    delta = top_um - rec.height_um[ramp]
    last = ramp[max(min(int(np.searchsorted(delta, (1.0 - STIFFNESS_SHARE) * depth_um)), ramp.size - 3), 0):]
    return float(np.polyfit(top_um - rec.height_um[last], rec.force_nN[last], 1)[0])


def simulated(radius_um: float, tension_mN_per_m: float, bulk_1s_mN_per_m: float, beta: float, shear_tilde: float,
              speed_um_per_s: float, depth_um: float, hold: tuple[Hold, ...] = (), start_s: float = 0.0,
              sample_hz: float = SAMPLE_HZ) -> Recording:
    """The time-domain shell's recording (RESOLUTION, CONTACT_HISTORY) of the cell stress-free as
    its droplet at the gap 2R - START_UM at `start_s`, pressed at `speed_um_per_s` to the
    deformation `depth_um` (δ from the free sphere) and held by `hold`; SolverError where the
    simulator finds no equilibrium."""
    top = 2.0 * radius_um
    shell = Shell(volume_um3=4.0 * np.pi / 3.0 * radius_um ** 3, h0_um=top - START_UM,
                  bulk_mN_per_m=bulk_1s_mN_per_m, shear_mN_per_m=shear_tilde * bulk_1s_mN_per_m,
                  tension_mN_per_m=tension_mN_per_m)
    steps = (Ramp(to_um=top - depth_um, speed_um_per_s=speed_um_per_s),) + hold
    return simulate(shell, power_law_cortex(bulk_1s_mN_per_m, shear_tilde * bulk_1s_mN_per_m, beta, beta),
                    Protocol(top - START_UM, steps, start_s=start_s), RESOLUTION, Sampling(approach_hz=sample_hz),
                    contact_history=CONTACT_HISTORY)


def force_nN(history: RampHold, x0_um: float, radius_um: float, tension_mN_per_m: float,
             bulk_1s_mN_per_m: float, beta: float, shear_tilde: float) -> npt.NDArray[np.float64]:
    """The simulated plate force (nN) at the history's samples (module doc); SolverError
    where the simulator finds no equilibrium."""
    v, t_c = history.speed_um_per_s(x0_um)
    t = history.time_s
    t_end = float(t[history.ramp_samples - 1])
    depth = START_UM + v * (t_end - t_c)
    if depth <= 2 * START_UM:
        raise SolverError("the ramp reaches no depth in contact")
    top = 2.0 * radius_um
    rec = simulated(radius_um, tension_mN_per_m, bulk_1s_mN_per_m, beta, shear_tilde, v, depth,
                    _hold(history, t_end), t_c)
    d = np.clip(x0_um - history.x_um, 0.0, None) / radius_um
    before = tension_mN_per_m * radius_um * unit_force_per_tension(np.minimum(d, DEPTH_MAX))
    force = np.where(t > t_c, np.interp(t, rec.time_s, rec.force_nN), before)
    if history.hold == "force" and t.size > history.ramp_samples:
        pause = slice(history.ramp_samples, None)
        x_model = x0_um - top + np.interp(t[pause], rec.time_s, rec.height_um)
        force[pause] += _stiffness_nN_per_um(rec, t_end, top, depth) * (x_model - history.x_um[pause])
    return force
