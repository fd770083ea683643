"""Each cell's memory chosen in the protocol-aware reading (`analysis.afm.protocol_factors`): its
own where its drift tells, the population's where it does not, the pure power law where nothing
tells; the factors interpolated between the replayed memories, and a refused memory left out."""

import math

import numpy as np
import pandas as pd
import pytest

from analysis.afm.memory_fit import MEMORY_GRID_S, RELAXED, UNDECIDED_S
from analysis.afm.protocol_factors import Factors

WAIT_S = 100.0


def _kept(memory_s: float) -> float:
    return 0.0 if memory_s == 0 else math.exp(-WAIT_S / memory_s)


def _grid(scale: np.ndarray) -> dict:
    """Factors at every candidate: |c| 1 + Δγ, arg c 0, Δγ = scale × the share kept (RELAXED: none drifts)."""
    out = {m: np.column_stack([1 + scale * _kept(m), np.zeros_like(scale), scale * _kept(m)]) for m in MEMORY_GRID_S}
    out[RELAXED] = np.column_stack([np.ones_like(scale), np.zeros_like(scale), np.full_like(scale, scale.mean())])
    return out


def _state(cells: dict) -> Factors:
    raw = pd.concat([pd.DataFrame({"cell_id": c, "tension_mN_per_m": t, "frequency_hz": 1.0})
                     for c, (t, _) in cells.items()], ignore_index=True)
    rows = {c: np.flatnonzero(raw["cell_id"].to_numpy() == c) for c in cells}
    state = Factors(raw, rows, {c: "" for c in cells})
    state.grids = {c: g for c, (_, g) in cells.items()}
    return state


def test_own_pooled_and_assumed_memories_and_their_factors():
    """Cell a drifts as τ_c = 100 s keeps (8 heights, noise 0.005 mN/m): its own memory, and its factors
    at it between the 30 and 300 s replays; cell b, at two heights of flat drift, cannot tell and
    takes the population's (a's); with a alone removed, nothing tells and ∞ is assumed."""
    rng = np.random.default_rng(0)
    depth = np.arange(1.0, 9.0)
    scale = 0.1 * depth
    a = (1.0 + scale * _kept(100.0) + rng.normal(0, 0.005, 8), _grid(scale))
    b = (np.array([1.0, 1.01, 1.0]), _grid(np.array([0.01, 0.01, 0.01])))
    state = _state({"a": a, "b": b})
    state.choose(None)
    assert state.source == {"a": "fitted", "b": "pooled"}
    fit = state.memory["a"]
    assert fit.lo95_s <= 100.0 <= fit.hi95_s and 30.0 < fit.memory_s < 300.0
    shift = state.factors[state.rows["a"], 2]
    assert np.all(shift > scale * _kept(30.0)) and np.all(shift < scale * _kept(300.0))
    assert state.memory["b"].memory_s == fit.memory_s
    alone = _state({"b": b})
    alone.choose(None)
    assert alone.source == {"b": "assumed"} and alone.memory["b"].memory_s == UNDECIDED_S
    assert alone.factors[:, 2] == pytest.approx(0.01)           # the ∞ replay's shift


def test_a_refused_memory_is_left_out_and_a_given_one_is_used():
    """Where τ_c = ∞ would leave a corrected tension ≤ 0, the fit keeps to the others; --memory-s picks
    its replay as it is."""
    scale = np.linspace(0.1, 0.8, 8)
    t = 1.0 + scale * _kept(30.0)
    grid = _grid(scale)
    grid[math.inf][:, 2] = 1.1
    state = _state({"a": (t, grid)})
    state.choose(None)
    assert math.isfinite(state.memory["a"].hi95_s) and state.why["a"] == ""
    given = _state({"a": (t, {300.0: grid[300.0]})})
    given.choose(300.0)
    assert given.source == {"a": "given"} and given.factors[:, 2] == pytest.approx(grid[300.0][:, 2])


def test_the_ends_of_the_memory_interval_carry_the_full_replays_defect():
    """Cell a (τ_c = 100 s, as above): its factors at the ends of its memory's interval are the grid's
    there, every node that keeps stress shifted by its full replay's defect at its memory (τ_c = 0
    keeps nothing and is not shifted); a given memory has no ends: it keeps its own factors."""
    rng = np.random.default_rng(0)
    scale = 0.1 * np.arange(1.0, 9.0)
    state = _state({"a": (1.0 + scale * _kept(100.0) + rng.normal(0, 0.005, 8), _grid(scale))})
    state.choose(None)
    fit, at = state.memory["a"], state.rows["a"]
    defect = np.array([0.01, -0.02, 0.003])
    state.full({"a": state.factors[at] + defect})
    lower, upper, other = state.ends()
    assert fit.lo95_s in MEMORY_GRID_S and fit.hi95_s in MEMORY_GRID_S and fit.lo95_s < fit.memory_s < fit.hi95_s
    np.testing.assert_allclose(lower[at], _grid(scale)[fit.lo95_s] + (defect if fit.lo95_s else 0), atol=1e-12)
    np.testing.assert_allclose(upper[at], _grid(scale)[fit.hi95_s] + defect, atol=1e-12)
    np.testing.assert_allclose(other[at], state.factors[at] if not fit.relaxed_in_set else
                               _grid(scale)[RELAXED] + defect, atol=1e-12)
    assert np.all(lower[at, 2] < state.factors[at, 2]) and np.all(upper[at, 2] > state.factors[at, 2])
    given = _state({"a": (1.0 + scale * _kept(100.0), {300.0: _grid(scale)[300.0]})})
    given.choose(300.0)
    assert all(np.array_equal(e, given.factors) for e in given.ends())


def test_the_exponents_intervals_span_those_at_the_memorys_ends():
    """`memory_span.spanned`: each exponent's interval the union of the reading's and its ends' for
    the same cell, the point estimate the reading's; an end without the cell, or NaN, changes nothing."""
    from analysis.afm.memory_span import spanned

    def table(rows):
        return pd.DataFrame(rows, columns=["cell_id", "bulk_exponent", "bulk_exponent_lo95", "bulk_exponent_hi95",
                                           "shear_exponent", "shear_exponent_lo95", "shear_exponent_hi95"])
    read = table([("a", 0.10, 0.08, 0.12, 0.30, 0.27, 0.33), ("b", 0.20, 0.15, 0.25, 0.40, 0.35, 0.45)])
    lower = table([("a", 0.09, 0.07, 0.11, 0.26, 0.23, 0.29), ("b", 0.2, math.nan, math.nan, 0.4, 0.36, 0.44)])
    upper = table([("a", 0.11, 0.09, 0.13, 0.31, 0.28, 0.34)])
    out = spanned(read, [lower, upper]).set_index("cell_id")
    assert out.loc["a"].to_list() == pytest.approx([0.10, 0.07, 0.13, 0.30, 0.23, 0.34])
    assert out.loc["b"].to_list() == pytest.approx([0.20, 0.15, 0.25, 0.40, 0.35, 0.45])
