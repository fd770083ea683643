"""Known-truth approach ramps and holds of cells whose cortex relaxes as a power law
(SPEC 11-12), made by the time-domain shell (`solver.time_domain`,
`solver.protocol_simulation.simulate` at FINE, the contact search as the tension model
has it: `powerlaw_simulated.CONTACT_HISTORY`).

The cell: radius R (µm), active tension γ_a (mN/m), K_B(t) = K_B(1 s) t^-β and
K_S(t) = K̃_S K_B(t) (`power_law_cortex`, one β). The dish at 0, so the gap is the wedge
height x. The plate starts `above_um` above the free sphere (x = 2R + above) and moves
down at `speed_um_per_s` to the deformation `depth_um` (δ = 2R - x), then holds that
height (`hold_kind` "height") or the force it reached ("force": the plate creeps) for
`hold_s` (0: no hold). The cortex is stress-free as the droplet at
x = 2R - START_UM (`analysis.afm.tension.powerlaw_simulated`); above it the force is the
exact droplet's tension force (0 above 2R). Samples at `rate_hz`; the recorded force
F + s (x - 2R) + noise: a baseline tilt s (nN/µm) and white noise of SD `noise_nN`.
"""

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from analysis.afm.tension.powerlaw_simulated import CONTACT_HISTORY, SAMPLE_HZ, START_UM
from solver.model import Shell
from solver.protocol import Hold, Protocol, Ramp
from solver.protocol_simulation import FINE, Sampling, simulate
from solver.time_domain import power_law_cortex
from studies.tension_synth import droplet_force_nN

if TYPE_CHECKING:
    from analysis.afm.formats.recording import Recording

Array = npt.NDArray[np.float64]


@dataclass(frozen=True)
class Cell:
    """The truth of one recording (module doc)."""

    radius_um: float
    tension_mN_per_m: float
    bulk_1s_mN_per_m: float
    shear_tilde: float
    beta: float
    speed_um_per_s: float
    depth_um: float
    hold_s: float = 0.0
    tilt_nN_per_um: float = 0.0
    noise_nN: float = 0.02
    above_um: float = 1.5
    rate_hz: float = 200.0
    hold_kind: str = "height"


@dataclass(frozen=True)
class Made:
    """A made recording: times (s), wedge heights (µm), forces (nN), how many samples are
    the ramp's (the rest the hold's)."""

    time_s: Array
    x_um: Array
    force_nN: Array
    ramp_samples: int


def recording(cell: Cell, seed: int = 0) -> Made:
    """The cell's ramp and hold (module doc)."""
    R, v = cell.radius_um, cell.speed_um_per_s
    top = 2.0 * R
    t_c = (cell.above_um + START_UM) / v
    t_end = (cell.above_um + cell.depth_um) / v
    n_ramp = int(np.floor(t_end * cell.rate_hz)) + 1
    t_ramp = np.r_[np.arange(n_ramp - 1) / cell.rate_hz, t_end]
    t_hold = t_end + np.arange(1, int(round(cell.hold_s * cell.rate_hz)) + 1) / cell.rate_hz
    t = np.r_[t_ramp, t_hold]
    x = np.where(t <= t_end, top + cell.above_um - v * t, top - cell.depth_um)
    shell = Shell(volume_um3=4.0 * np.pi / 3.0 * R ** 3, h0_um=top - START_UM,
                  bulk_mN_per_m=cell.bulk_1s_mN_per_m, shear_mN_per_m=cell.shear_tilde * cell.bulk_1s_mN_per_m,
                  tension_mN_per_m=cell.tension_mN_per_m)
    steps: tuple[Ramp | Hold, ...] = (Ramp(to_um=top - cell.depth_um, speed_um_per_s=v),)
    if cell.hold_s > 0:
        steps += (Hold(cell.hold_s, cell.hold_kind),)
    cortex = power_law_cortex(cell.bulk_1s_mN_per_m, cell.shear_tilde * cell.bulk_1s_mN_per_m, cell.beta, cell.beta)
    rec = simulate(shell, cortex, Protocol(top - START_UM, steps, start_s=t_c), FINE,
                   Sampling(approach_hz=max(SAMPLE_HZ, cell.rate_hz)), contact_history=CONTACT_HISTORY)
    volume = 4.0 * np.pi / 3.0 * R ** 3
    if cell.hold_kind == "force":                  # the plate creeps: the gap as simulated
        x = np.where(t <= t_end, x, np.interp(t, rec.time_s, rec.height_um))
    force = np.where(t > t_c, np.interp(t, rec.time_s, rec.force_nN),
                     droplet_force_nN(volume, cell.tension_mN_per_m, np.maximum(x, top - START_UM)))
    rng = np.random.default_rng(seed)
    force = force + cell.tilt_nN_per_um * (x - top) + cell.noise_nN * rng.standard_normal(t.size)
    return Made(t, x, force, n_ramp)


RANGES = {"radius_um": (5.0, 10.0), "tension_mN_per_m": (0.2, 2.0), "bulk_1s_mN_per_m": (5.0, 50.0),
          "shear_tilde": (0.1, 2.0), "beta": (0.1, 0.3), "speed_um_per_s": (0.3, 3.0),
          "hold_s": (10.0, 30.0), "tilt_nN_per_um": (0.0, 0.15)}
LOG = ("tension_mN_per_m", "bulk_1s_mN_per_m", "shear_tilde", "speed_um_per_s")


def cells(n: int, seed: int = 0, depth_over_radius: float = 0.14) -> list[Cell]:
    """n cells drawn over RANGES (uniform, in log for LOG; seed `seed`), every other one
    without a hold, each pressed to `depth_over_radius` R."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        p: dict[str, Any] = {}
        for key, (lo, hi) in RANGES.items():
            u = rng.random()
            p[key] = float(np.exp(np.log(lo) + u * np.log(hi / lo)) if key in LOG else lo + u * (hi - lo))
        if i % 2:
            p["hold_s"] = 0.0
        out.append(Cell(depth_um=depth_over_radius * p["radius_um"], **p))
    return out


def as_recording(made: Made, cell_id: str = "synthetic", spring_N_per_m: float = 0.1) -> "Recording":
    """The made ramp and hold as an instrument `Recording` (dish at 0: the height channel
    z = x - F/k): an approach, a pause (where there is a hold) and a retract mirroring the
    approach at its baseline force."""
    from analysis.afm.formats.recording import RecordedSegment, Recording
    t, x, f, n = made.time_s, made.x_um, made.force_nN, made.ramp_samples
    z = x - 1e-3 * f / spring_N_per_m
    parts = [("approach", slice(0, n))] + ([("pause", slice(n, t.size))] if t.size > n else [])
    segs = [RecordedSegment(kind, float(t[s][-1] - t[s][0]), t[s], f[s], z[s]) for kind, s in parts]
    back = t[-1] + (t[1] - t[0]) + (t[n - 1] - t[:n][::-1])
    segs.append(RecordedSegment("retract", float(back[-1] - back[0]), back, np.full(n, f[0]), x[:n][::-1] - 1e-3 * f[0]
                                / spring_N_per_m))
    return Recording(cell_id=cell_id, spring_constant_N_per_m=spring_N_per_m, segments=segs,
                     source="synthetic power-law ramp and hold (studies.powerlaw_ramps)")
