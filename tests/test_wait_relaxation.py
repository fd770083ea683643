"""The cortex's memory read from the relaxation in a recording's waits
(`analysis.afm.wait_relaxation`, with `analysis.afm.memory_fit`): the waits the simulator keeps,
the samples that read the memory, and known memories read back from cells simulated in time at
the synthetic experiments' resolution, with the instrument's noise and drift, by replays at the
linearised resolution."""

import math

import numpy as np
import pytest

from analysis.afm.memory_fit import MEMORY_GRID_S, RELAXED, profile
from analysis.afm.replayed import cell_replays
from analysis.afm.synth.time_domain import recording_cell
from analysis.afm.timeseries import segment_moduli
from analysis.afm.wait_relaxation import MIN_WAIT_S, Waits, excess, recorded
from solver.model import Shell
from solver.protocol import Protocol
from solver.protocol_simulation import LINEARISED, simulate
from solver.time_domain import power_law_cortex

LAW = {"bulk_1s": 25.0, "shear_1s": 15.0, "bulk_beta": 0.1, "shear_beta": 0.3, "tension": 1.0}
SHELL = Shell(volume_um3=4300.0, h0_um=14.0, bulk_mN_per_m=25.0, shear_mN_per_m=15.0, tension_mN_per_m=1.0,
              bending="none")


def _protocol(wait_s: float) -> Protocol:
    return Protocol.stepped(14.0, (13.4, 12.8, 12.2), (1.0,), (3,), wait_s=wait_s)


def _cell(memory_s: float, seed: int):
    """A cell simulated in time (FINE) with the memory τ_c, its force with noise 0.2 nN and a drift
    of 0.001 nN/s, as `afm synth` records it."""
    cortex = power_law_cortex(25.0, 15.0, 0.1, 0.3, memory_s=memory_s)
    cell = recording_cell(simulate(SHELL, cortex, _protocol(60.0)), SHELL.volume_um3, "c")
    rng = np.random.default_rng(seed)
    cell.force_nN = cell.force_nN + rng.normal(0.0, 0.2, cell.force_nN.size) + 0.001 * cell.time_s
    return cell


def test_the_linearised_replay_keeps_its_waits_stepped_from_one_second():
    """Three 60 s waits, each stepped 1, 2, 4, 8, 16, 16, 13 s (their start first); the half
    oscillations' holds are not waits."""
    rep = simulate(SHELL, power_law_cortex(25.0, 15.0, 0.1, 0.3), _protocol(60.0), LINEARISED)
    assert len(rep.waits) == 3
    for t, f in rep.waits:
        assert np.diff(t) == pytest.approx([1, 2, 4, 8, 16, 16, 13])
        assert np.all(np.diff(f) < 0)          # the force relaxes through the wait


def test_short_waits_read_nothing():
    """A 0.5 s pause (a JPK map's) and a 5 s wait are shorter than MIN_WAIT_S: no samples."""
    assert MIN_WAIT_S > 5.0
    for wait in (0.5, 5.0):
        rep = simulate(SHELL, power_law_cortex(25.0, 15.0, 0.1, 0.3), _protocol(wait), LINEARISED)
        cell = recording_cell(rep, SHELL.volume_um3, "c")
        assert recorded(cell, rep.waits) is None


def test_a_wait_whose_force_does_not_move_cannot_be_fitted():
    """One wait of six samples leaves too few degrees of freedom; two memories are needed."""
    w = Waits(np.arange(6.0), np.ones(6), np.zeros(6, int), (0,), {10.0: np.arange(6.0)})
    assert excess(w) is None


@pytest.mark.parametrize("memory_s", [10.0, math.inf])
def test_a_known_memory_is_read_from_the_waits(memory_s):
    """τ_c = 10 s and ∞, three heights with 60 s waits, 0.2 nN of noise and a drift: replayed with
    the true laws at every node, the waits' profile with the drift of the recorded mean tensions
    holds the truth in its 95 % interval and not the other memory."""
    cell = _cell(memory_s, 1)
    grid, waits = cell_replays(cell, LAW, "none", None, True, (*MEMORY_GRID_S, RELAXED))
    assert waits is not None and waits.count == 3
    witness = excess(waits)
    assert witness is not None
    tension = [s["tension_mN_per_m"] for s in segment_moduli(cell)]
    fit = profile(tension, {m: f[:, 2] for m, f in grid.items() if not isinstance(f, str)}, None, witness)
    assert fit.identified
    assert fit.lo95_s <= memory_s <= fit.hi95_s
    other = math.inf if memory_s == 10.0 else 10.0
    assert not fit.lo95_s <= other <= fit.hi95_s
