"""A recording's own protocol, read off its samples and segments (SPEC 6, 12).

`protocol_of(cell)` gives the `solver.protocol.Protocol` a cell went through, whatever file it
came from (native HDF5 or CSV, JPK, Bruker: `analysis.afm.formats.reader`), from the stress-free
height h_ref just before its first approach (at most FREE_SPHERE of the cell's diameter: a
recording that starts out of contact is referenced to the free sphere) at that sample's time.
Per oscillation segment j, starting at t_j at mean height h_j, f_j, n_j periods:

- the first oscillation after a height step is preceded by a ramp to h_j ending at t_s (its
  speed: the height moved over the time since the last oscillation's end) and a hold of
  t_j - t_s. t_s is read off the recording: where `pause` segments follow the approach (JPK),
  the approach's last sample (the pause is timed exactly); a pause whose height creeps more
  than STEP_TOL_UM is a constant-force hold (then the ramp goes to the approach's last height);
  in the native format, whose `approach` segment holds the step and its wait, the first sample
  of that segment from which on the height stays within STEP_TOL_UM of its last value;
- a later oscillation at the same height is preceded by a height hold of the time since the
  last one's end;
- the oscillation is n_j periods at f_j, of AMPLITUDE_UM, rising first (the synthetic
  experiments' own; the replay reads the segments' moduli, not their phase).

With a wait S (`afm analyze --wait-s S`) every height's hold is S instead of the recorded one.
None where an oscillation has no approach before it, where the heights are not gaps from the
dish (`Cell.dish_known`) or, without S, where an approach holds its height less than MIN_HOLD_S
before the oscillations (no recorded wait; the rule of the native format's 1 Hz approach samples:
a hold timed by pause segments counts at any length). `read_protocol` gives the reason instead.

The protocol's `ages_s()` are then the age of each oscillation's step stress: the wait, plus the
oscillations before it at the same height.
"""

import math

import numpy as np

from analysis.afm.cell import Cell, Segment
from solver.geometry import cell_radius
from solver.protocol import Hold, Oscillate, Protocol, Ramp, Step

STEP_TOL_UM = 0.05       # µm: the plate has stopped once it stays this close to the height it holds
FREE_SPHERE = 0.999      # h_ref at most this fraction of the cell's diameter
MIN_HOLD_S = 2.0         # s: an approach that holds its height less long records no wait (1 Hz samples)
AMPLITUDE_UM = 0.25      # µm: the oscillations' amplitude
SHORTEST_RAMP_S = 1e-3   # s: a ramp takes at least this long


def _step_end(cell: Cell, oscillation: Segment) -> tuple[float, str, float, bool]:
    """(t_s, the hold's kind, the height at t_s, whether pause segments time the hold) of the
    height step before `oscillation`; NaN if none."""
    before = [s for s in cell.segments if s.kind == "approach" and s.stop <= oscillation.start]
    if not before:
        return math.nan, "height", math.nan, False
    approach = before[-1]
    pauses = [s for s in cell.segments if s.kind == "pause" and approach.stop <= s.start < oscillation.start]
    if pauses:
        h = np.concatenate([cell.height_um[p.start:p.stop] for p in pauses])
        kind = "force" if np.ptp(h) > STEP_TOL_UM else "height"
        return float(cell.time_s[approach.stop - 1]), kind, float(cell.height_um[approach.stop - 1]), True
    h = cell.height_um[approach.start:approach.stop]
    moved = np.flatnonzero(np.abs(h - h[-1]) > STEP_TOL_UM)
    at = approach.start + (int(moved[-1]) + 1 if moved.size else 0)
    return float(cell.time_s[at]), "height", float(cell.height_um[at]), False


def _periods(cell: Cell, seg: Segment) -> int:
    t = cell.time_s[seg.start:seg.stop]
    step = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    return max(int(round((float(t[-1] - t[0]) + step) * seg.frequency_hz)), 1)


def protocol_of(cell: Cell, wait_s: float | None = None) -> Protocol | None:
    """The cell's protocol (module docstring); None where it is not recorded."""
    found = read_protocol(cell, wait_s)
    return found if isinstance(found, Protocol) else None


def read_protocol(cell: Cell, wait_s: float | None = None) -> Protocol | str:
    """The cell's protocol (module docstring), or why it is not recorded."""
    osc = cell.oscillations()
    if not cell.dish_known:
        return "heights not gaps from the dish"
    first = next((s for s in cell.segments if s.kind == "approach"), None)
    if not osc or first is None or first.start >= osc[0].start:
        return "no approach before the oscillations"
    at = max(first.start - 1, 0)
    ref = min(float(cell.height_um[at]), FREE_SPHERE * 2 * float(cell_radius(cell.volume_um3)))
    steps: list[Step] = []
    now, level, shift, last_end = float(cell.time_s[at]), ref, 0.0, math.nan
    for seg in osc:
        end, kind, h_end, timed = _step_end(cell, seg)
        start, mean = float(cell.time_s[seg.start]), float(cell.height_um[seg.start:seg.stop].mean())
        if math.isnan(end):
            return f"no approach before the oscillation at {start:g} s"
        if end != last_end:                          # the first oscillation after a height step
            held = start - end
            if wait_s is None and not timed and held < MIN_HOLD_S:
                return (f"the approach holds its height {held:.2g} s before the oscillation at {start:g} s "
                        f"(< {MIN_HOLD_S:g} s of untimed approach samples: no recorded wait)")
            target = h_end if kind == "force" else mean
            if abs(target - level) > 1e-9:
                ramp_s = max(end + shift - now, SHORTEST_RAMP_S)
                steps.append(Ramp(to_um=target, speed_um_per_s=abs(target - level) / ramp_s))
                now, level = now + ramp_s, target
            shift += 0.0 if wait_s is None else wait_s - held
            steps.append(Hold(max(start + shift - now, 0.0), kind))
            last_end = end
        else:
            steps.append(Hold(max(start + shift - now, 0.0)))
        periods = _periods(cell, seg)
        steps.append(Oscillate(float(seg.frequency_hz), AMPLITUDE_UM, periods))
        now, level = max(start + shift, now) + periods / seg.frequency_hz, mean
    return Protocol(ref, tuple(steps), float(cell.time_s[at]))
