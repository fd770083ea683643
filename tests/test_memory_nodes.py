"""Which memories a later round replays (`analysis.afm.memory_nodes`): the nodes that decide a
cell's memory and its interval, and the others carried along by the nearest replayed node's
change; the rounds' state keeps which were replayed at the last laws (`Factors.stale`)."""

import math

import numpy as np
import pandas as pd
import pytest

from analysis.afm.memory_fit import MEMORY_GRID_S, RELAXED, MemoryFit, profile
from analysis.afm.memory_nodes import deciding, merged, merged_waits
from analysis.afm.protocol_factors import Factors
from analysis.afm.wait_relaxation import Waits

NODES = (*MEMORY_GRID_S, RELAXED)
WAIT_S = 100.0
DEPTHS = np.repeat(np.arange(1, 9), 3)         # 8 heights, 3 frequencies each


def _shifts(scale: np.ndarray, more: float = 1.0, at=()) -> dict:
    """Δγ_j at every carried node for a cortex keeping exp(-T_w/τ_c) of each step; the nodes `at`
    `more` times that."""
    kept = {m: 0.0 if m == 0 else math.exp(-WAIT_S / m) for m in MEMORY_GRID_S}
    return {m: scale * kept[m] * (more if m in at else 1.0) for m in MEMORY_GRID_S}


def _drifting(truth_s: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    scale = 0.1 * DEPTHS
    return 1.0 + scale * math.exp(-WAIT_S / truth_s) + rng.normal(0, 0.01, DEPTHS.size), scale


def test_a_memory_and_its_interval_rest_on_its_deciding_nodes_alone():
    """Cells drifting as τ_c = 10, 30, 100 and 300 s would: the nodes outside `deciding` given
    30 % more or less stress leave the memory and its interval as they were; the node beyond an
    interval's end given the stress of the memory read moves that end (so it must be replayed)."""
    for k, truth in enumerate((10.0, 30.0, 100.0, 300.0)):
        tension, scale = _drifting(truth, k)
        exact = profile(tension, _shifts(scale))
        assert exact.identified and exact.lo95_s <= truth <= exact.hi95_s
        near = deciding(exact, NODES)
        assert 0.0 in near and exact.lo95_s in near and exact.hi95_s in near and len(near) < len(MEMORY_GRID_S)
        far = [m for m in MEMORY_GRID_S if m not in near]
        for more in (0.7, 1.3):
            moved = profile(tension, _shifts(scale, more, far))
            assert (moved.memory_s, moved.lo95_s, moved.hi95_s) == (exact.memory_s, exact.lo95_s, exact.hi95_s)
        beyond = max((m for m in near if m < exact.lo95_s), default=None)
        if beyond:
            stressed = _shifts(scale)
            stressed[beyond] = scale * math.exp(-WAIT_S / exact.memory_s)
            assert profile(tension, stressed).lo95_s < exact.lo95_s


def test_an_undecided_memory_needs_every_node_and_a_relaxed_one_the_relaxed_and_the_carried_ends():
    assert deciding(MemoryFit(math.inf, 0.0, math.inf, False), NODES) == NODES
    relaxed = MemoryFit(math.inf, math.nan, math.nan, True, relaxed=True)
    assert set(deciding(relaxed, NODES)) == {0.0, math.inf, RELAXED}
    never = MemoryFit(math.inf, 3000.0, math.inf, True)
    assert set(deciding(never, NODES)) == {0.0, 1000.0, 3000.0, math.inf}


def test_the_nodes_not_replayed_move_as_the_nearest_replayed_one_did():
    """Factors that move with the laws by one offset per node pair: the nodes not replayed get
    their nearest replayed node's change (in φ = τ_c / (τ_c + 30 s)), RELAXED ∞'s; τ_c = 0 (no
    stress kept) and a node that found no equilibrium stay as they were."""
    rng = np.random.default_rng(0)
    old = {m: rng.normal(size=(4, 3)) for m in (3.0, 10.0, 30.0, 300.0, math.inf, RELAXED)}
    old[0.0], old[1000.0] = np.tile([1.0, 0.0, 0.0], (4, 1)), "the replay found no equilibrium"
    d10, dinf = rng.normal(size=(4, 3)), rng.normal(size=(4, 3))
    new = {10.0: old[10.0] + d10, math.inf: old[math.inf] + dinf}
    got = merged(old, new)
    assert set(got) == set(old)
    np.testing.assert_allclose(got[3.0], old[3.0] + d10)          # φ 0.09: nearer 10 s (0.25) than ∞
    np.testing.assert_allclose(got[30.0], old[30.0] + d10)        # φ 0.5: 10 s at 0.25, ∞ at 1
    np.testing.assert_allclose(got[300.0], old[300.0] + dinf)     # φ 0.91
    np.testing.assert_allclose(got[RELAXED], old[RELAXED] + dinf)
    assert got[0.0] is old[0.0] and got[1000.0] == old[1000.0]
    assert got[10.0] is new[10.0]


def test_the_waits_force_is_carried_along_as_the_factors_are():
    t = np.arange(5.0)
    waits = Waits(t, t, np.zeros(5, dtype=np.int64), (0,), {10.0: t, 100.0: 2 * t, RELAXED: 3 * t})
    fresh = Waits(t, t, np.zeros(5, dtype=np.int64), (0,), {10.0: t + 1.0})
    got = merged_waits(waits, fresh)
    np.testing.assert_allclose(got.model[100.0], 2 * t + 1.0)
    np.testing.assert_allclose(got.model[RELAXED], 3 * t)         # ∞ was not replayed
    assert merged_waits(None, fresh) is fresh and merged_waits(waits, None) is waits


def test_the_rounds_state_knows_which_nodes_were_replayed_at_the_last_laws():
    """A first replay at every node; a later one at some: those fresh, the rest stale until
    replayed at the same laws (`new_laws` False), which joins them to the fresh ones."""
    raw = pd.DataFrame({"cell_id": ["a"] * 3, "tension_mN_per_m": [1.0, 1.0, 1.0],
                        "frequency_hz": [1.0, 1.0, 1.0]})
    state = Factors(raw, {"a": np.arange(3)}, {})
    grid = {m: np.tile([1.0, 0.0, 0.01 * k], (3, 1)) for k, m in enumerate(NODES)}
    state.replayed({"a": (grid, None)})
    assert state.stale(NODES) == {} and state.at_memories["a"] == len(NODES) - 1
    state.memory["a"], state.source["a"] = MemoryFit(100.0, 30.0, 300.0, True), "fitted"
    state.replayed({"a": ({30.0: grid[30.0], 100.0: grid[100.0]}, None)})
    assert state.stale(NODES) == {"a": (10.0, 300.0, 1000.0)}
    state.replayed({"a": ({m: grid[m] for m in (10.0, 300.0, 1000.0)}, None)}, new_laws=False)
    assert state.stale(NODES) == {} and state.at_memories["a"] == len(NODES) - 1 + 5
    assert set(state.grids["a"]) == set(NODES)


def test_a_node_whose_replay_failed_carries_nothing_along():
    """The nearest replayed node found no equilibrium: the next nearest that did moves the stale one."""
    old = {3.0: np.zeros(2), 10.0: np.ones(2), 100.0: np.full(2, 2.0)}
    new = {10.0: "the replay found no equilibrium", 100.0: np.full(2, 2.5)}
    np.testing.assert_allclose(merged(old, new)[3.0], np.full(2, 0.5))
