"""The age of each oscillation's step stress read off the recording (analysis/afm/waits.py):
the native format's approach (step and wait in one segment), a JPK-like recording with pause
segments (the height creeping in a constant-force pause), a given wait, no approach at all."""

import math

import numpy as np
import pytest

from analysis.afm.cell import Cell, Segment
from analysis.afm.waits import step_ages_s, step_end_s


def _native(steps):
    """Per (start height, mean height, ramp µm/s, wait s, frequencies): an approach at 1 Hz
    (ramp then wait) and 5 periods per frequency at 100 Hz, 0.25 µm amplitude."""
    t, h, segs, t0, n = [], [], [], 0.0, 0
    for h_from, h_m, speed, wait, freqs in steps:
        move = (h_from - h_m) / speed
        ta = np.arange(0.0, move + wait, 1.0)
        t.append(t0 + ta)
        h.append(np.where(ta < move, h_from - speed * ta, h_m))
        segs.append(Segment("approach", n, n + ta.size))
        n, t0 = n + ta.size, t0 + ta[-1] + 1.0
        for f in freqs:
            ts = np.arange(0.0, 5 / f, 0.01)
            t.append(t0 + ts)
            h.append(h_m - 0.25 * np.sin(2 * np.pi * f * ts))
            segs.append(Segment("oscillation", n, n + ts.size, f))
            n, t0 = n + ts.size, t0 + ts[-1] + 0.01
    t, h = np.concatenate(t), np.concatenate(h)
    return Cell("c", 4300.0, t, np.zeros_like(t), h, segs)


def test_native_ages_are_the_wait_then_the_oscillations_before():
    cell = _native([(12.0, 11.0, 0.2, 100.0, (0.1, 1.0)), (11.0, 10.5, 0.2, 80.0, (0.1,))])
    ages = step_ages_s(cell)
    assert ages[0] == pytest.approx(100.0, abs=1.0)              # the ramp ends between 1 Hz samples
    assert ages[1] == pytest.approx(ages[0] + 50.0, abs=0.02)    # after 5 periods at 0.1 Hz
    assert ages[2] == pytest.approx(80.0, abs=1.0)
    given = step_ages_s(cell, wait_s=30.0)
    assert given[0] == given[2] == 30.0 and given[1] == pytest.approx(80.0, abs=0.02)


def test_pause_segments_give_the_wait_even_where_the_height_creeps():
    t = np.arange(0.0, 90.0, 0.01)
    h = np.interp(t, [0.0, 10.0, 70.0, 90.0], [20.0, 15.0, 14.6, 14.6])   # extend, pause creeping 0.4 µm
    h[t >= 70.0] -= 0.25 * np.sin(2 * np.pi * 1.0 * (t[t >= 70.0] - 70.0))
    i10, i70 = np.searchsorted(t, 10.0), np.searchsorted(t, 70.0)
    segs = [Segment("approach", 0, i10), Segment("pause", i10, i70), Segment("oscillation", i70, t.size, 1.0)]
    cell = Cell("jpk", 4300.0, t, np.zeros_like(t), h, segs)
    assert step_end_s(cell, segs[2]) == pytest.approx(10.0, abs=0.011)
    assert step_ages_s(cell) == [pytest.approx(60.0, abs=0.011)]


def test_no_approach_no_age():
    t = np.arange(0.0, 5.0, 0.01)
    cell = Cell("o", 4300.0, t, np.zeros_like(t), 10.0 - 0.25 * np.sin(2 * np.pi * t),
                [Segment("oscillation", 0, t.size, 1.0)])
    assert math.isnan(step_ages_s(cell)[0]) and math.isnan(step_ages_s(cell, wait_s=50.0)[0])


def test_visits_are_the_recorded_protocol_or_one_with_a_given_wait():
    """The protocol a replay follows (analysis/afm/replayed.py): h_ref and the time just before
    the first ramp, per oscillation its mean height, frequency, periods and start, and the end of
    the step before the first oscillation at each height; a given wait S moves every later time
    by S minus the recorded wait; an approach that does not hold its height MIN_HOLD_S has no
    recorded wait (None), unless S is given."""
    from analysis.afm.replayed import visits
    cell = _native([(12.0, 11.0, 0.2, 100.0, (0.1, 1.0)), (11.0, 10.5, 0.2, 80.0, (0.1,))])
    p = visits(cell)
    assert (p.reference_um, p.start_s) == (12.0, 0.0)
    assert [(v.mean_um, v.frequency_hz, v.cycles) for v in p.visits] == \
        [(pytest.approx(11.0, abs=1e-3), 0.1, 5), (pytest.approx(11.0, abs=1e-3), 1.0, 5), (pytest.approx(10.5, abs=1e-3), 0.1, 5)]
    assert p.visits[0].start_s - p.visits[0].step_end_s == pytest.approx(100.0, abs=1.0)
    assert math.isnan(p.visits[1].step_end_s) and p.visits[1].start_s == pytest.approx(p.visits[0].start_s + 50.0, abs=0.02)
    assert p.visits[2].start_s - p.visits[2].step_end_s == pytest.approx(80.0, abs=1.0)
    given = visits(cell, wait_s=30.0)
    assert [v.start_s - v.step_end_s for v in given.visits[::2]] == pytest.approx([30.0, 30.0])
    assert given.visits[0].step_end_s == p.visits[0].step_end_s
    assert given.visits[1].start_s - given.visits[0].start_s == pytest.approx(50.0, abs=0.02)
    assert given.visits[2].step_end_s - given.visits[1].start_s == pytest.approx(
        p.visits[2].step_end_s - p.visits[1].start_s)                 # the ramp keeps its length
    no_hold = _native([(12.0, 11.0, 0.2, 0.0, (1.0,))])
    assert visits(no_hold) is None and visits(no_hold, wait_s=30.0) is not None
