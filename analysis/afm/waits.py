"""How long after its height step each oscillation comes: the age of the step's stress (SPEC 12).

A viscoelastic cortex stepped to the mean height h_m at time t_s still holds the part
K(t - t_s) ε of the step's stress while it oscillates (docs/viscoelastic.md, "The protocol in
time"). For oscillation segment j starting at t_j the step's end t_s is read off the recording:

- a file with `pause` segments after its approach (JPK): t_s is the approach's last sample, and
  the pauses' lengths follow (in a constant-force pause the height creeps: it is not read);
- the native format, whose `approach` segment holds the step and its wait: t_s is the first
  sample of that segment from which on the height stays within STEP_TOL_UM of its last value.

The age is a_j = t_j - t_s: the wait T_w before the first frequency at a height, T_w plus the
oscillations before it for the later ones. Given a wait S (`afm analyze --wait-s S`), T_w is
S at every height and the rest stays as recorded: a_j = S + (t_j - t_first), t_first the start
of the first oscillation after the same step. NaN where no approach precedes the oscillation.
"""

import math

import numpy as np

from analysis.afm.cell import Cell, Segment

STEP_TOL_UM = 0.05   # µm: the plate has stopped once it stays this close to the height it holds


def step_end_s(cell: Cell, oscillation: Segment) -> float:
    """t_s (s) of the height step before `oscillation` (module docstring); NaN if none."""
    before = [s for s in cell.segments if s.kind == "approach" and s.stop <= oscillation.start]
    if not before:
        return math.nan
    approach = before[-1]
    if any(s.kind == "pause" and approach.stop <= s.start < oscillation.start for s in cell.segments):
        return float(cell.time_s[approach.stop - 1])
    h = cell.height_um[approach.start:approach.stop]
    moved = np.flatnonzero(np.abs(h - h[-1]) > STEP_TOL_UM)
    return float(cell.time_s[approach.start + (moved[-1] + 1 if moved.size else 0)])


def step_ages_s(cell: Cell, wait_s: float | None = None) -> list[float]:
    """a_j (s) of every oscillation segment of `cell`, in order; with `wait_s`, T_w = wait_s."""
    ages: list[float] = []
    first: dict[float, float] = {}
    for seg in cell.oscillations():
        t_s, t_j = step_end_s(cell, seg), float(cell.time_s[seg.start])
        if math.isnan(t_s):
            ages.append(math.nan)
            continue
        t_first = first.setdefault(t_s, t_j)
        ages.append((t_first - t_s if wait_s is None else wait_s) + (t_j - t_first))
    return ages
