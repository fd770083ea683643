"""The AFM protocol at one height, simulated in time (SPEC sections 6 and 12).

From the relaxed droplet at h0 (the stress-free reference, t = 0) the plate

1. ramps to the mean height h_m = h0 - Δh_m at `ramp_um_per_s` (0.2 µm/s as published),
   simulation steps moving it at most RAMP_STEP_UM each;
2. waits T_w at h_m, in steps growing geometrically (ratio WAIT_GROWTH) from one sample
   interval to at most WAIT_LARGEST_S (the strain creeps smoothly there);
3. oscillates h(t) = h_m + A sin(2π f (t - t_osc)) for `cycles` periods (A = 0.25 µm: 0.5 µm
   peak to peak) in STEPS_PER_PERIOD equal simulation steps a period, whatever the sampling.

Every step is `TimeShell.advance`, which takes it in the sub-steps its equilibria need.

The instrument samples at `sample_hz` (100 Hz), or 20 samples a period where f > sample_hz/20.
The returned recording holds every sample: the plate's height is h(t) itself; the force of
the oscillation is the simulated force at the steps interpolated by a cubic spline (not-a-knot,
from t_osc on: its error is ~ (5/384) (2π/STEPS_PER_PERIOD)^4 of the force's amplitude, 1e-6),
that of the ramp and the wait linear between steps. `approach` and `oscillate` are the two
pieces, for protocols of several heights (`solver.cell_protocol`).
"""

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.interpolate import CubicSpline

from common.errors import InputError
from solver.model import Shell
from solver.time_domain import Cortex, TimeShell

RAMP_STEP_UM = 0.02       # largest plate move in one step of the ramp
WAIT_GROWTH = 1.2         # ratio of consecutive steps during the wait
WAIT_LARGEST_S = 2.0      # largest step during the wait
MIN_SAMPLES_PER_PERIOD = 20
STEPS_PER_PERIOD = 64     # simulation steps a period of the oscillation

Array = npt.NDArray[np.float64]


@dataclass(frozen=True)
class Protocol:
    """One height of the protocol: step Δh_m below h0, wait, oscillate at f."""

    step_um: float = 0.25
    wait_s: float = 100.0
    frequency_hz: float = 1.0
    amplitude_um: float = 0.25
    cycles: int = 5
    ramp_um_per_s: float = 0.2
    sample_hz: float = 100.0

    def __post_init__(self) -> None:
        for name in ("step_um", "frequency_hz", "amplitude_um", "ramp_um_per_s", "sample_hz"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise InputError(f"{name} must be a finite number > 0 (got {value:g})")
        if not (np.isfinite(self.wait_s) and self.wait_s >= 0) or self.cycles < 1:
            raise InputError("the wait must be >= 0 s and the oscillation at least one cycle")

    @property
    def sample_interval_s(self) -> float:
        """The instrument's sampling interval: 1/sample_hz, or a twentieth of a period if shorter."""
        return sample_interval_s(self.sample_hz, self.frequency_hz)


def sample_interval_s(sample_hz: float, frequency_hz: float) -> float:
    """1/sample_hz, or a twentieth of a period at `frequency_hz` if shorter."""
    return min(1.0 / sample_hz, 1.0 / (MIN_SAMPLES_PER_PERIOD * frequency_hz))


@dataclass
class Recording:
    """Samples of a simulated recording; `oscillation` the samples of the oscillation segment."""

    time_s: Array
    force_nN: Array
    height_um: Array
    oscillation: slice
    frequency_hz: float
    steps: int                 # simulation steps (equilibrium solves)


@dataclass
class Steps:
    """Simulated times (s), gaps (µm) and plate forces (nN) of a stretch of a protocol."""

    time_s: Array
    height_um: Array
    force_nN: Array


def step(state: TimeShell, h_um: float, dt_s: float) -> float:
    """`state.advance(h, Δt)`: the plate to h over Δt in the sub-steps its equilibria need."""
    return state.advance(h_um, dt_s)


def approach(state: TimeShell, t0_s: float, h_um: float, ramp_um_per_s: float, wait_s: float,
             first_step_s: float) -> Steps:
    """Ramp the plate of `state` (at gap state.h_um at time t0) to h at `ramp_um_per_s`, then
    wait `wait_s` there (steps from `first_step_s` growing by WAIT_GROWTH to WAIT_LARGEST_S)."""
    h_from = state.h_um
    ramp_s = abs(h_from - h_um) / ramp_um_per_s
    n = int(np.ceil(abs(h_from - h_um) / RAMP_STEP_UM))
    t = list(np.linspace(0.0, ramp_s, n + 1)[1:])
    dt, end = first_step_s, ramp_s + wait_s
    while (t[-1] if t else 0.0) < end - 1e-12:
        t.append(min((t[-1] if t else 0.0) + dt, end))
        dt = min(dt * WAIT_GROWTH, WAIT_LARGEST_S)
    if not t:
        raise InputError("an approach must move the plate or wait")
    t_rel = np.array(t)
    h = h_from + (h_um - h_from) * (np.minimum(t_rel / ramp_s, 1.0) if n else np.ones(len(t_rel)))
    force, last = np.empty(len(t_rel)), 0.0
    for k, (tk, hk) in enumerate(zip(t_rel, h)):
        force[k], last = step(state, hk, tk - last), tk
    return Steps(t0_s + t_rel, h, force)


def oscillate(state: TimeShell, t0_s: float, h_m_um: float, frequency_hz: float, amplitude_um: float,
              cycles: int, sample_s: float) -> tuple[Steps, int]:
    """Oscillate the plate of `state` (at gap h_m) from time t0: h_m + A sin(2π f (t - t0)),
    `cycles` periods in STEPS_PER_PERIOD steps each; return the instrument's samples every
    `sample_s` after t0 (force by cubic spline through the steps and the force at t0) and the
    number of steps."""
    h_m, f0 = h_m_um, state.force_nN()
    n_samples = int(round(cycles / (frequency_hz * sample_s)))
    t_samples = sample_s * np.arange(1.0, n_samples + 1.0)
    t_steps = _step_times(t_samples[-1], 1.0 / (frequency_hz * STEPS_PER_PERIOD), sample_s)
    h_steps = h_m + amplitude_um * np.sin(2 * np.pi * frequency_hz * t_steps)
    f_steps = np.array([step(state, h, dt) for h, dt in zip(h_steps, np.diff(t_steps, prepend=0.0))])
    spline = CubicSpline(np.r_[0.0, t_steps], np.r_[f0, f_steps])
    h_samples = h_m + amplitude_um * np.sin(2 * np.pi * frequency_hz * t_samples)
    return Steps(t0_s + t_samples, h_samples, np.asarray(spline(t_samples), float)), len(t_steps)


def _step_times(end_s: float, step_s: float, first_s: float) -> Array:
    """Times (s) from the start of an oscillation to cover `end_s`: multiples of `step_s`, and
    before the first of them `first_s` doubling (the plate's speed jumps at the start, and the
    fast Maxwell elements answer within their τ: the force's kink is resolved there)."""
    lead = first_s * 2.0 ** np.arange(max(int(np.ceil(np.log2(step_s / first_s))), 0))
    grid = step_s * np.arange(1, int(np.ceil(end_s / step_s - 1e-9)) + 1)
    return np.r_[lead[lead < 0.75 * step_s], grid]


def run(shell: Shell, cortex: Cortex, protocol: Protocol) -> Recording:
    """Simulate `protocol` on the shell (reference droplet at shell.h0_um) with `cortex`."""
    p = protocol
    if p.step_um + p.amplitude_um >= shell.h0_um:
        raise InputError("the protocol would close the gap")
    state = TimeShell(shell, cortex)
    f_ref = state.force_nN()
    dt = p.sample_interval_s
    app = approach(state, 0.0, shell.h0_um - p.step_um, p.ramp_um_per_s, p.wait_s, dt)
    t_osc0 = float(app.time_s[-1])
    osc, n_steps = oscillate(state, t_osc0, float(app.height_um[-1]), p.frequency_hz, p.amplitude_um,
                             p.cycles, dt)
    # the instrument's samples before the oscillation: the ramp and wait interpolated
    t_pre = np.arange(0.0, t_osc0 - 0.5 * dt, dt)
    t_sim = np.r_[0.0, app.time_s]
    h_pre = np.interp(t_pre, t_sim, np.r_[shell.h0_um, app.height_um])
    f_pre = np.interp(t_pre, t_sim, np.r_[f_ref, app.force_nN])
    time_s = np.concatenate([t_pre, [t_osc0], osc.time_s])
    force = np.concatenate([f_pre, [app.force_nN[-1]], osc.force_nN])
    height = np.concatenate([h_pre, [app.height_um[-1]], osc.height_um])
    start = len(t_pre) + 1
    return Recording(time_s, force, height, slice(start, start + len(osc.time_s)), float(p.frequency_hz),
                     steps=len(app.time_s) + n_steps)
