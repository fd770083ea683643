"""A recorded protocol replayed in time with a given cortex, coarsely (SPEC 12).

The protocol-aware reading (`analysis.afm.replayed`) asks what a cell with a given power-law
cortex would have recorded under its own protocol: from its stress-free droplet at h0 (the
shell's) at time `start_s`, every height step, every wait and every oscillation at the times the
recording has them, one cortex history through all (`solver.time_domain.TimeShell`, one
equilibrium of the fast solver per step, `solver.time_protocol.step` halving where it must).

Coarser than the synthetic experiments' simulation (`solver.cell_protocol`), for speed:

- a ramp moves the plate at most RAMP_STEP_UM a step, linear in time up to the step's end;
- a wait grows its steps from WAIT_FIRST_S by WAIT_GROWTH up to WAIT_LARGEST_S;
- an oscillation h_m + A sin(2π f (t - t_j)) takes STEPS_PER_PERIOD steps a period over at most
  MAX_CYCLES of its periods, and the force is kept at those steps (the fit of SPEC 6 step 2
  reads them as it reads samples); after it the plate waits at h_m until the next oscillation.

Where a step finds no equilibrium even halved (`solver.time_protocol.step`), the replay starts
again with FINER times as many ramp and oscillation steps.

Against the synthetic experiments' own simulation (64 steps a period, all periods, waits in
steps up to 2 s), read with the true cortex, on two cells of 33 and 18 segments: |K*| within
1.6 % (0.8 % on average), loss angle within 0.014 rad (`tests/test_protocol_replay.py` checks a
small cell). About 1700 steps for a cell of 11 heights at three frequencies, 3 ms a step.
"""

import math
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from common.errors import InputError, SolverError
from solver.model import Shell
from solver.time_domain import Cortex, TimeShell
from solver.time_protocol import step

Array = npt.NDArray[np.float64]
RAMP_STEP_UM = 0.05
WAIT_FIRST_S = 0.01
WAIT_GROWTH = 2.0
WAIT_LARGEST_S = 30.0
STEPS_PER_PERIOD = 16
MAX_CYCLES = 2
AMPLITUDE_UM = 0.25
FINER = 4                # a replay that fails starts again with this many times finer ramps and oscillations


@dataclass(frozen=True)
class Visit:
    """One oscillation of the recording: mean height h_m (µm), frequency (Hz), periods, the time
    of its start (s) and the end of the height step before it (s; NaN: no step, same height)."""

    mean_um: float
    frequency_hz: float
    cycles: int
    start_s: float
    step_end_s: float = math.nan


@dataclass
class Replay:
    """Per visit the replayed oscillation: times from its start (s), gaps (µm), forces (nN)."""

    time_s: list[Array] = field(default_factory=list)
    height_um: list[Array] = field(default_factory=list)
    force_nN: list[Array] = field(default_factory=list)
    steps: int = 0


def _wait(state: TimeShell, now_s: float, until_s: float, h_um: float) -> int:
    """Hold the gap h from now to `until_s` in growing steps; the number of steps."""
    dt, n = WAIT_FIRST_S, 0
    while now_s < until_s - 1e-9:
        d = min(dt, until_s - now_s)
        step(state, h_um, d)
        now_s, dt, n = now_s + d, min(dt * WAIT_GROWTH, WAIT_LARGEST_S), n + 1
    return n


def _ramp(state: TimeShell, now_s: float, end_s: float, h_um: float, fine: bool) -> int:
    """Move the plate to h, linear in time, ending at `end_s`; the number of steps."""
    h_from = state.h_um
    n = max(int(math.ceil(abs(h_um - h_from) / (RAMP_STEP_UM / FINER if fine else RAMP_STEP_UM))), 1)
    dt = max(end_s - now_s, 1e-3) / n
    for k in range(1, n + 1):
        step(state, h_from + (h_um - h_from) * k / n, dt)
    return n


def _oscillate(state: TimeShell, visit: Visit, out: Replay, fine: bool) -> float:
    """The visit's oscillation (at most MAX_CYCLES periods) into `out`; its duration (s)."""
    f, per_period = visit.frequency_hz, STEPS_PER_PERIOD * (FINER if fine else 1)
    t = np.arange(1, per_period * min(visit.cycles, MAX_CYCLES) + 1) / (per_period * f)
    h = visit.mean_um + AMPLITUDE_UM * np.sin(2 * np.pi * f * t)
    force = np.array([step(state, hk, dt) for hk, dt in zip(h, np.diff(t, prepend=0.0))])
    out.time_s.append(t)
    out.height_um.append(h)
    out.force_nN.append(force)
    out.steps += t.size
    return float(t[-1])


def replay(shell: Shell, cortex: Cortex, start_s: float, visits: list[Visit]) -> Replay:
    """The recording's visits replayed on the shell (stress-free droplet at shell.h0_um at
    `start_s`) with `cortex` (module docstring), once more with FINER steps where a step finds no
    equilibrium. SolverError if even that fails."""
    if not visits or any(v.cycles < 1 or not v.frequency_hz > 0 for v in visits):
        raise InputError("a replay needs oscillations of at least one period at a frequency > 0 Hz")
    try:
        return _run(shell, cortex, start_s, visits, False)
    except SolverError:
        return _run(shell, cortex, start_s, visits, True)


def _run(shell: Shell, cortex: Cortex, start_s: float, visits: list[Visit], fine: bool) -> Replay:
    state, out, now = TimeShell(shell, cortex), Replay(), float(start_s)
    for v in visits:
        if not math.isnan(v.step_end_s) and abs(v.mean_um - state.h_um) > 1e-9:
            out.steps += _ramp(state, now, v.step_end_s, v.mean_um, fine)
            now = max(v.step_end_s, now)
        out.steps += _wait(state, now, v.start_s, v.mean_um)
        now = max(now, v.start_s) + _oscillate(state, v, out, fine)
    return out
