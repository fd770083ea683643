"""A whole cell's protocol in time (`solver.protocol.Protocol.stepped`, simulated by
`solver.protocol_simulation.simulate`): heights one after another, one cortex history (or each
height from its own relaxed droplet), sampled as an instrument samples; a step without
equilibrium taken in halves; holds at constant force and ramps to a force."""

from dataclasses import replace

import numpy as np
import pytest

from common.errors import InputError, SolverError
from solver.compression import compress
from solver.geometry import droplet
from solver.model import Shell
from solver.prony import Prony
from solver.protocol import Hold, Oscillate, Protocol, Ramp
from solver.protocol_simulation import Sampling, _advance, simulate
from solver.time_domain import Cortex, TimeShell, power_law_cortex

SHELL = Shell(volume_um3=4300.0, h0_um=13.0, bulk_mN_per_m=25.0, shear_mN_per_m=8.33, tension_mN_per_m=1.5)
PROTOCOL = Protocol.stepped(13.0, (12.5, 12.0, 11.0), (1.0,), (2,), wait_s=5.0)


def cell_recording(shell, cortex, protocol, history="carried"):
    """The recording with every ramp and its hold as one approach stretch, as the synth stores it."""
    from analysis.afm.synth.time_domain import segments_of
    rec = simulate(shell, cortex, protocol, history=history)
    rec.stretches = segments_of(rec)
    return rec


def test_an_elastic_cortex_gives_the_elastic_force_at_every_height():
    """β = 0 (constant moduli): after each ramp and wait, and after the oscillations that
    follow, the plate force is the elastic solver's for h0 -> h_i (found 1e-4; asked 0.5 %),
    whatever came before; segments are where the protocol puts them."""
    rec = cell_recording(SHELL, Cortex(Prony(25.0), Prony(8.33)), PROTOCOL)
    approaches = [s for s in rec.stretches if s.kind == "approach"]
    oscillations = [s for s in rec.stretches if s.kind == "oscillation"]
    assert len(approaches) == len(oscillations) == 3
    for h, a, o in zip((12.5, 12.0, 11.0), approaches, oscillations):
        elastic = compress(replace(SHELL, dh_um=SHELL.h0_um - h)).solution.force_nN
        assert rec.height_um[a.stop - 1] == pytest.approx(h, abs=1e-12)
        assert rec.force_nN[a.stop - 1] == pytest.approx(elastic, rel=5e-3)
        assert rec.force_nN[o.stop - 1] == pytest.approx(elastic, rel=5e-3)
        assert o.frequency_hz == 1.0 and o.stop - o.start == 200          # 2 periods at 100 Hz
        assert np.ptp(rec.height_um[o.start:o.stop]) == pytest.approx(0.5, abs=1e-3)
    assert np.all(np.diff(rec.time_s) > 0) and rec.stretches[-1].stop == len(rec.time_s)


def test_a_power_law_cortex_relaxes_and_carries_its_history():
    """β_B 0.1, β_S 0.3: the force relaxes during each wait (lower at its end than where the
    ramp ends); at the last height it is below that of the same cortex taken there in one
    ramp from the reference and waited as long: the earlier heights' strain has had longer
    to relax (found: 1.5-6 nN relaxed in 5 s waits; 106.8 against 108.2 nN; an elastic cortex
    gives both the same force, the test above)."""
    cortex = power_law_cortex(25.0, 8.33, 0.1, 0.3)
    rec = cell_recording(SHELL, cortex, PROTOCOL)
    approaches = [s for s in rec.stretches if s.kind == "approach"]
    for a in approaches:
        ramp_end = a.start + int(np.argmin(rec.height_um[a.start:a.stop]))
        assert rec.force_nN[a.stop - 1] < rec.force_nN[ramp_end] - 0.5
    direct = cell_recording(SHELL, cortex, Protocol.stepped(13.0, (11.0,), (1.0,), (2,), wait_s=5.0))
    last, first = approaches[-1], direct.stretches[0]
    assert rec.force_nN[last.stop - 1] < direct.force_nN[first.stop - 1] - 1.0


def test_the_relaxed_history_starts_every_height_from_its_own_relaxed_droplet():
    """history "relaxed": the second height (12.0 µm) is recorded as a cell of reference droplet
    one step (0.5 µm) above it, 12.5 µm, taken to 12.0 µm alone (same samples, to round-off:
    found identical; its times after the first height's); the first height is the carried
    history's. With the history carried the force there is higher: the earlier step's stress
    is kept (found +7.1 nN on average over the height's samples, of 56 nN)."""
    cortex = power_law_cortex(25.0, 8.33, 0.1, 0.3)
    two = Protocol.stepped(13.0, (12.5, 12.0), (1.0,), (2,), wait_s=5.0)
    relaxed = cell_recording(SHELL, cortex, two, history="relaxed")
    carried = cell_recording(SHELL, cortex, two)
    fresh = cell_recording(SHELL, cortex, Protocol.stepped(12.5, (12.0,), (1.0,), (2,), wait_s=5.0))
    second = relaxed.stretches[2].start                 # the second height's approach
    assert relaxed.stretches == carried.stretches and relaxed.steps == carried.steps
    assert np.array_equal(relaxed.force_nN[:second], carried.force_nN[:second])
    assert np.allclose(relaxed.force_nN[second:], fresh.force_nN[1:], rtol=1e-12, atol=1e-9)
    assert np.allclose(relaxed.height_um[second:], fresh.height_um[1:], atol=1e-12)
    assert np.allclose(relaxed.time_s[second:] - relaxed.time_s[second - 1], fresh.time_s[1:], atol=1e-9)
    assert np.mean(carried.force_nN[second:] - fresh.force_nN[1:]) > 5.0


def test_bad_cell_protocols_are_refused():
    """One clear InputError each: an unknown history, a ramp to a height <= 0, a negative hold, a
    relaxed history whose first ramp does not go down, steps of other kinds, no steps, a ramp to
    both a height and a force, an oscillation of no whole period, a hold of an unknown kind."""
    elastic = Cortex(Prony(25.0), Prony(8.33))
    with pytest.raises(InputError, match="history"):
        simulate(SHELL, elastic, PROTOCOL, history="forgotten")
    with pytest.raises(InputError, match="to_um"):
        Protocol.stepped(13.0, (11.0, -1.0), (1.0,), (5,))
    with pytest.raises(InputError, match="duration_s"):
        Protocol.stepped(13.0, (11.0,), (1.0,), (5,), wait_s=-1.0)
    with pytest.raises(InputError, match="below the protocol's start"):
        simulate(SHELL, elastic, Protocol.stepped(12.0, (12.5,), (1.0,), (2,)), history="relaxed")
    for bad in ((), ("ramp",)):
        with pytest.raises(InputError, match="non-empty list"):
            Protocol(13.0, bad)
    with pytest.raises(InputError, match="one of them"):
        Ramp(to_um=12.0, to_nN=50.0)
    with pytest.raises(InputError, match="whole period"):
        Oscillate(1.0, periods=0)
    with pytest.raises(InputError, match="constant height or force"):
        Hold(5.0, "position")


def test_the_first_sample_is_the_reference_droplets_tension_force():
    """The protocol's start, before any step, is the stress-free reference droplet: its force is
    the tension's, F_a = 2 γ_a H A_c at (V, h0) (35.0 nN here; the unsolved reference mesh read
    -83.6), to 1e-6, and again after a step is undone; the first three steps of 0.005 µm
    extrapolate back to it (found 5e-5 relative; asked 1e-3): the later samples join on."""
    f_a = SHELL.tension_mN_per_m * float(droplet(SHELL.volume_um3, SHELL.h0_um).force_per_tension_um)
    rec = simulate(SHELL, power_law_cortex(25.0, 8.33, 0.1, 0.3), Protocol(13.0, (Ramp(to_um=12.9),)))
    assert rec.time_s[0] == 0.0 and rec.force_nN[0] == pytest.approx(f_a, rel=1e-6)
    assert np.all(np.diff(rec.force_nN) > 0)
    state = TimeShell(SHELL, power_law_cortex(25.0, 8.33, 0.1, 0.3))
    start = state.saved()
    f1, f2, f3 = (state.step(SHELL.h0_um - k * 0.005, 0.025) for k in (1, 2, 3))
    assert 3.0 * f1 - 3.0 * f2 + f3 == pytest.approx(f_a, rel=1e-3)
    state.restore(start)
    assert state.force_nN() == pytest.approx(f_a, rel=1e-6)


def test_a_step_without_equilibrium_is_taken_in_two_halves(monkeypatch):
    """A step that fails (here: one longer than 0.3 s, after it has changed the state) is undone
    and taken as two halves, the gap linear between: the force and the state are those of the
    two half steps taken directly (to round-off)."""
    cortex = power_law_cortex(25.0, 8.33, 0.1, 0.3)
    direct = TimeShell(SHELL, cortex)
    direct.step(SHELL.h0_um - 0.05, 0.25)
    expected = direct.step(SHELL.h0_um - 0.1, 0.25)
    original, calls = TimeShell.step, []

    def failing(self, h_um, dt_s):
        calls.append(dt_s)
        force = original(self, h_um, dt_s)
        if dt_s > 0.3:
            raise SolverError("no equilibrium")
        return force
    monkeypatch.setattr(TimeShell, "step", failing)
    state = TimeShell(SHELL, cortex)
    assert _advance(state, SHELL.h0_um - 0.1, 0.5) == pytest.approx(expected, rel=1e-12)
    assert calls == [0.5, 0.25, 0.25]
    assert np.allclose(state.channels[1].viscous, direct.channels[1].viscous, rtol=1e-12, atol=1e-15)
    monkeypatch.setattr(TimeShell, "step", lambda self, h_um, dt_s: (_ for _ in ()).throw(SolverError("never")))
    with pytest.raises(SolverError):
        _advance(TimeShell(SHELL, cortex), SHELL.h0_um - 0.1, 0.5)


def test_a_constant_force_hold_creeps_and_a_ramp_to_a_force_stops_there():
    """A ramp to 40 nN (sampled at 10 Hz) rises to it and stops there; the hold at constant force
    keeps it at every sample (to 1e-6) while the plate creeps down, step after step, as the
    power-law cortex relaxes (found 0.037 µm in 5 s); held at the same height instead, the force
    falls (found to 39.0 nN). An elastic cortex holds the force without creeping (1e-6 µm). A
    ramp to a force the cell exceeds at once is one InputError."""
    cortex = power_law_cortex(25.0, 8.33, 0.1, 0.3)
    by_force = Protocol(13.0, (Ramp(to_nN=40.0), Hold(5.0, "force")))
    rec = simulate(SHELL, cortex, by_force, sampling=Sampling(approach_hz=10.0))
    ramp, hold = rec.stretches
    assert np.all(np.diff(rec.force_nN[ramp.start:ramp.stop]) > 0) and rec.force_nN[ramp.stop - 1] < 40.0
    assert np.allclose(rec.force_nN[hold.start:hold.stop], 40.0, rtol=1e-6)
    h_start = rec.height_um[hold.start]
    assert rec.height_um[-1] < h_start - 0.02 and np.all(np.diff(rec.height_um[hold.start:]) < 0)
    ramp_s = (SHELL.h0_um - h_start) / 0.2
    held = Protocol(13.0, (Ramp(to_um=float(h_start)), Hold(5.0 + rec.time_s[hold.start] - ramp_s)))
    assert simulate(SHELL, cortex, held).force_nN[-1] < 40.0 - 0.5
    still = simulate(SHELL, Cortex(Prony(25.0), Prony(8.33)), by_force, sampling=Sampling(approach_hz=10.0))
    assert np.ptp(still.height_um[still.stretches[1].start:]) < 1e-6
    with pytest.raises(InputError, match="the tension's, is already 35"):    # below F_a at the start
        simulate(SHELL, cortex, Protocol(13.0, (Ramp(to_nN=10.0),)))
