"""The cortex's memory from the drift of a cell's mean tension across heights
(`analysis.afm.memory_fit`): the profile's estimate and 95 % interval on drifts of a known memory,
the relaxed and the undecidable cases, and the population's pooled memory."""

import math

import numpy as np
import pytest

from analysis.afm.memory_fit import MEMORY_GRID_S, UNDECIDED_S, carried, pooled, profile, seconds

WAIT_S = 100.0
DEPTHS = np.repeat(np.arange(1, 9), 3)         # 8 heights, 3 frequencies each: 24 segments


def _kept(memory_s: float) -> float:
    """The share of a step's stress kept after the wait by a cortex forgetting with τ_c."""
    return 0.0 if memory_s == 0 else math.exp(-WAIT_S / memory_s)


def _shifts(scale_mN_per_m: np.ndarray) -> dict[float, np.ndarray]:
    """Δγ_j(τ_c) at the grid's nodes: each height keeps `scale` times the share kept."""
    return {m: scale_mN_per_m * _kept(m) for m in MEMORY_GRID_S}


def test_carried_coordinate_maps_zero_and_infinity_to_the_ends():
    assert carried([0.0, 30.0, math.inf]).tolist() == [0.0, 0.5, 1.0]
    assert seconds(0.5) == pytest.approx(30.0) and seconds(1.0) == math.inf and seconds(0.0) == 0.0


def test_a_drift_of_known_memory_is_read_back_within_its_interval():
    """Tension 1 mN/m, each height keeping 0.1 mN/m per step depth times exp(-T_w/τ_c) at τ_c = 100 s
    (e^-1 of the pure power law's), noise 0.02 mN/m: the interval holds 100 s in ≥ 85 % of 200 draws,
    excludes 0 and ∞ in all of them, and the median estimate is within a factor 1.5 of the truth."""
    rng = np.random.default_rng(1)
    scale = 0.1 * DEPTHS
    truth = 100.0
    fits = [profile(1.0 + scale * _kept(truth) + rng.normal(0, 0.02, DEPTHS.size), _shifts(scale)) for _ in range(200)]
    held = np.mean([f.lo95_s <= truth <= f.hi95_s for f in fits])
    assert held >= 0.85
    assert all(f.identified and f.lo95_s > 0 and math.isfinite(f.hi95_s) for f in fits)
    assert np.median([f.memory_s for f in fits]) == pytest.approx(truth, rel=0.5)


def test_a_relaxed_cell_reads_a_short_memory_and_no_drift_none():
    """No drift at all: the interval starts at 0 and ends at a node no later than the wait; a drift the same at
    every height (absorbed by γ_a) decides nothing, and the population of such cells neither."""
    rng = np.random.default_rng(2)
    scale = 0.1 * DEPTHS
    relaxed = profile(1.0 + rng.normal(0, 0.02, DEPTHS.size), _shifts(scale))
    assert relaxed.identified and relaxed.lo95_s == 0.0 and relaxed.hi95_s <= WAIT_S
    flat = np.full(DEPTHS.size, 0.3)
    fits = [profile(1.2 + rng.normal(0, 0.02, DEPTHS.size), _shifts(flat)) for _ in range(5)]
    assert not any(f.identified for f in fits)
    assert not pooled(fits).identified and pooled(fits).memory_s == UNDECIDED_S


def test_the_population_pools_cells_that_cannot_tell_alone():
    """Twenty cells whose largest drift (0.016 mN/m at τ_c = ∞) is below their noise (0.02 mN/m):
    no cell tells τ_c = 100 s from both ends, the population's summed profile does (its set found
    22-414 s), and its interval, widened to the nodes outside the set, holds 100 s and not 0."""
    rng = np.random.default_rng(3)
    scale = 0.002 * DEPTHS
    fits = [profile(1.0 + scale * _kept(100.0) + rng.normal(0, 0.02, DEPTHS.size), _shifts(scale)) for _ in range(20)]
    assert sum(f.identified for f in fits) <= 2
    pool = pooled(fits)
    assert pool.identified and 0.0 < pool.lo95_s <= 100.0 <= pool.hi95_s


def test_too_few_segments_or_nodes_decide_nothing():
    assert not profile([1.0, 1.1], {0.0: np.zeros(2), math.inf: np.ones(2)}).identified
    assert not profile([1.0, 1.1, 1.2], {0.0: np.zeros(3)}).identified


def test_two_witnesses_add_and_their_set_holds_where_they_agree():
    """The drift read at τ_c = 100 s (no noise) and a waits' witness whose own minimum is at 30 s:
    the sum's estimate lies between them, its set is not empty (the sum's own minimum is taken
    off), and its interval's ends are nodes of the grid."""
    scale = 0.1 * DEPTHS
    tension = 1.0 + scale * _kept(100.0) + np.random.default_rng(4).normal(0, 0.02, DEPTHS.size)
    phi = np.append(np.linspace(0.0, 1.0, 401), 0.0)
    waits = (((phi - float(carried(30.0))) / 0.02) ** 2, 500)
    waits[0][-1] = np.inf                                  # no relaxed-history replay
    alone, both = profile(tension, _shifts(scale)), profile(tension, _shifts(scale), None, waits)
    assert alone.memory_s > both.memory_s > 30.0
    assert both.identified and both.lo95_s in MEMORY_GRID_S and both.hi95_s in MEMORY_GRID_S
    assert both.lo95_s <= 30.0 and both.memory_s <= both.hi95_s
