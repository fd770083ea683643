"""The AFM protocol at one height, simulated in time (SPEC sections 6 and 12).

From the relaxed droplet at h0 (the stress-free reference, t = 0) the plate

1. ramps to the mean height h_m = h0 - Δh_m at `ramp_um_per_s` (0.2 µm/s as published),
   simulation steps moving it at most RAMP_STEP_UM each;
2. waits T_w at h_m, in steps growing geometrically (ratio WAIT_GROWTH) from one sample
   interval to at most WAIT_LARGEST_S (the strain creeps smoothly there);
3. oscillates h(t) = h_m + A sin(2π f (t - t_osc)) for `cycles` periods (A = 0.25 µm: 0.5 µm
   peak to peak), one simulation step per sample.

The instrument samples at `sample_hz` (100 Hz), or 20 samples a period where f > sample_hz/20.
The returned recording holds every sample: the oscillation's samples are simulation steps;
those of the ramp and the wait are the simulated force interpolated linearly between steps.
"""

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from common.errors import InputError
from solver.model import Shell
from solver.time_domain import Cortex, TimeShell

RAMP_STEP_UM = 0.02       # largest plate move in one step of the ramp
WAIT_GROWTH = 1.2         # ratio of consecutive steps during the wait
WAIT_LARGEST_S = 2.0      # largest step during the wait
MIN_SAMPLES_PER_PERIOD = 20


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
        return min(1.0 / self.sample_hz, 1.0 / (MIN_SAMPLES_PER_PERIOD * self.frequency_hz))


@dataclass
class Recording:
    """Samples of a simulated recording; `oscillation` the samples of the oscillation segment."""

    time_s: npt.NDArray[np.float64]
    force_nN: npt.NDArray[np.float64]
    height_um: npt.NDArray[np.float64]
    oscillation: slice
    frequency_hz: float
    steps: int                 # simulation steps (equilibrium solves)


def _approach(shell: Shell, p: Protocol) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """Simulation times and gaps of the ramp and the wait (t = 0 at h0 excluded)."""
    ramp_s = p.step_um / p.ramp_um_per_s
    n = max(int(np.ceil(p.step_um / RAMP_STEP_UM)), 1)
    t = list(np.linspace(0.0, ramp_s, n + 1)[1:])
    dt, end = p.sample_interval_s, ramp_s + p.wait_s
    while t[-1] < end - 1e-12:
        t.append(min(t[-1] + dt, end))
        dt = min(dt * WAIT_GROWTH, WAIT_LARGEST_S)
    t_arr = np.array(t)
    h = shell.h0_um - p.step_um * np.minimum(t_arr / ramp_s, 1.0)
    return t_arr, h


def run(shell: Shell, cortex: Cortex, protocol: Protocol) -> Recording:
    """Simulate `protocol` on the shell (reference droplet at shell.h0_um) with `cortex`."""
    p = protocol
    if p.step_um + p.amplitude_um >= shell.h0_um:
        raise InputError("the protocol would close the gap")
    state = TimeShell(shell, cortex)
    t_app, h_app = _approach(shell, p)
    f_app, last = np.empty(len(t_app)), 0.0
    for k, (t, h) in enumerate(zip(t_app, h_app)):
        f_app[k], last = state.step(h, t - last), t
    dt = p.sample_interval_s
    t_osc0 = t_app[-1]
    n_osc = int(round(p.cycles / (p.frequency_hz * dt)))
    t_osc = t_osc0 + dt * np.arange(1, n_osc + 1)
    h_m = shell.h0_um - p.step_um
    h_osc = h_m + p.amplitude_um * np.sin(2 * np.pi * p.frequency_hz * (t_osc - t_osc0))
    f_osc = np.array([state.step(h, dt) for h in h_osc])
    # the instrument's samples before the oscillation: the ramp and wait interpolated
    t_pre = np.arange(0.0, t_osc0 - 0.5 * dt, dt)
    t_sim = np.concatenate([[0.0], t_app])
    f_sim = np.concatenate([[TimeShell(shell, cortex).force_nN()], f_app])
    h_pre = np.interp(t_pre, t_sim, np.concatenate([[shell.h0_um], h_app]))
    time_s = np.concatenate([t_pre, [t_osc0], t_osc])
    force = np.concatenate([np.interp(t_pre, t_sim, f_sim), [f_app[-1]], f_osc])
    height = np.concatenate([h_pre, [h_m], h_osc])
    start = len(t_pre) + 1
    return Recording(time_s, force, height, slice(start, start + n_osc), float(p.frequency_hz),
                     steps=len(t_app) + n_osc)
