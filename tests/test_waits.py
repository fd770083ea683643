"""A recording's protocol read off it (`analysis.afm.recorded_protocol.protocol_of`) and the age
of each oscillation's step stress (`Protocol.ages_s`): the native format's approach (step and
wait in one segment), a JPK-like recording with pause segments (the height creeping in a
constant-force pause: a force hold), a given wait, no approach at all."""

import math

import numpy as np
import pytest

from analysis.afm.cell import Cell, Segment
from analysis.afm.recorded_protocol import MIN_HOLD_S, protocol_of, read_protocol
from solver.protocol import Hold, Oscillate, Protocol


def step_ages_s(cell, wait_s=None):
    return protocol_of(cell, wait_s).ages_s()


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
    ramp, hold, osc = protocol_of(cell).steps
    assert ramp.to_um == pytest.approx(15.0, abs=0.01) and ramp.speed_um_per_s == pytest.approx(0.5, rel=0.01)
    assert hold.kind == "force" and hold.duration_s == pytest.approx(60.0, abs=0.011)
    assert osc == Oscillate(1.0, 0.25, 20)
    assert step_ages_s(cell) == [pytest.approx(60.0, abs=0.011)]
    flat = np.where((t >= 10.0) & (t < 70.0), 15.0, h)                  # a pause at constant height
    still = Cell("jpk", 4300.0, t, np.zeros_like(t), flat, segs)
    assert protocol_of(still).steps[1].kind == "height"


def test_no_approach_no_age():
    t = np.arange(0.0, 5.0, 0.01)
    cell = Cell("o", 4300.0, t, np.zeros_like(t), 10.0 - 0.25 * np.sin(2 * np.pi * t),
                [Segment("oscillation", 0, t.size, 1.0)])
    assert protocol_of(cell) is None and protocol_of(cell, wait_s=50.0) is None
    assert math.isnan(Protocol(12.0, (Oscillate(1.0),)).ages_s()[0])


def test_protocol_of_is_the_recorded_protocol_or_one_with_a_given_wait():
    """The protocol a replay follows: from h_ref at the time just before the first ramp, per
    height a ramp to the mean height ending where the step ends (its speed the recorded one), a
    hold to the first oscillation, each oscillation's frequency and periods and a hold to the
    next; a given wait S makes every height's hold S and keeps the rest (the ramps' lengths, the
    oscillations); an approach that does not hold its height MIN_HOLD_S has no recorded wait
    (None), unless S is given."""
    cell = _native([(12.0, 11.0, 0.2, 100.0, (0.1, 1.0)), (11.0, 10.5, 0.2, 80.0, (0.1,))])
    p = protocol_of(cell)
    assert (p.start_um, p.start_s) == (12.0, 0.0)
    kinds = [type(s).__name__ for s in p.steps]
    assert kinds == ["Ramp", "Hold", "Oscillate", "Hold", "Oscillate", "Ramp", "Hold", "Oscillate"]
    r1, h1, o1, h2, o2, r2, h3, o3 = p.steps
    assert [r1.to_um, r2.to_um] == pytest.approx([11.0, 10.5], abs=1e-3)
    assert [(o.frequency_hz, o.periods) for o in (o1, o2, o3)] == [(0.1, 5), (1.0, 5), (0.1, 5)]
    assert r1.speed_um_per_s == pytest.approx(0.2, rel=0.2) and r2.speed_um_per_s == pytest.approx(0.2, rel=0.4)
    assert h1.duration_s == pytest.approx(100.0, abs=1.0) and h2.duration_s == pytest.approx(0.0, abs=0.02)
    assert h3.duration_s == pytest.approx(80.0, abs=1.0)
    assert all(h.kind == "height" for h in (h1, h2, h3))
    given = protocol_of(cell, wait_s=30.0)
    assert [s.duration_s for s in given.steps if isinstance(s, Hold)] == pytest.approx([30.0, 0.0, 30.0], abs=0.02)
    assert [s for s in given.steps if not isinstance(s, Hold)] == [s for s in p.steps if not isinstance(s, Hold)]
    no_hold = _native([(12.0, 11.0, 0.2, 0.0, (1.0,))])
    assert protocol_of(no_hold) is None and protocol_of(no_hold, wait_s=30.0) is not None


def test_a_short_pause_timed_by_pause_segments_is_a_wait_an_untimed_one_is_not():
    """JPK times its pauses exactly: a 0.5 s pause before the oscillations is a 0.5 s wait (the
    MIN_HOLD_S rule is for holds inferred from 1 Hz approach samples, which say why not)."""
    t = np.arange(0.0, 15.5, 0.01)
    h = np.interp(t, [0.0, 10.0, 15.5], [20.0, 15.0, 15.0])
    osc = t >= 10.5
    h[osc] -= 0.25 * np.sin(2 * np.pi * (t[osc] - 10.5))
    i10, i105 = np.searchsorted(t, 10.0), np.searchsorted(t, 10.5)
    segs = [Segment("approach", 0, i10), Segment("pause", i10, i105), Segment("oscillation", i105, t.size, 1.0)]
    cell = Cell("jpk", 4300.0, t, np.zeros_like(t), h, segs)
    assert step_ages_s(cell) == [pytest.approx(0.5, abs=0.011)]
    native = _native([(12.0, 11.0, 0.2, 1.0, (1.0,))])
    assert 1.0 < MIN_HOLD_S and protocol_of(native) is None
    assert "no recorded wait" in read_protocol(native)
