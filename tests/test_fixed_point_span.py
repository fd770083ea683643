"""The exponents' intervals of the protocol-aware reading's fixed point (analysis/afm/fixed_point_span.py):
the correction's feedback on the laws, and the interval it widens."""

import math

import numpy as np
import pandas as pd
import pytest

from analysis.afm.fixed_point_span import LAWS, MAX_WIDENING, MOVED, jacobian, shifted, widened, widening
from analysis.afm.law_rounds import in_units, of_units

THETA = {"bulk_1s": 30.0, "shear_1s": 10.0, "tension": 1.0, "bulk_beta": 0.1, "shear_beta": 0.3}


def test_each_law_is_moved_by_two_settled_units():
    """β by 0.02 (down where up would pass EXPONENT_RANGE's 0.9), K(1 s) and γ_a by e^0.04; the
    other laws kept."""
    assert shifted(THETA, "shear_beta") == pytest.approx({**THETA, "shear_beta": 0.32})
    assert shifted({**THETA, "bulk_beta": 0.89}, "bulk_beta")["bulk_beta"] == pytest.approx(0.87)
    assert shifted(THETA, "tension") == pytest.approx({**THETA, "tension": math.exp(0.04)})


def _refit(A: np.ndarray, star: dict[str, float], laws: dict[str, float]) -> dict[str, float]:
    """A point fit whose correction feeds back linearly in the settled units: g(z) = z* + A (z - z*)."""
    z0 = in_units(star)
    return of_units(z0 + A @ (in_units(laws) - z0), laws)


def test_the_widening_carries_the_feedback_through_both_exponents():
    """On a linear feedback J over the exponents is read back to 1e-9. β_S's own feedback is 0.05,
    but through β_B (a β_S too high corrects β_B up by 0.6 of it, which pulls β_S up by 0.5 of that)
    M_SS = 1/(0.95 - 0.3) = 1.54, not the 1.05 of its own alone, and M_BB = 0.95/0.65; a feedback
    through γ_a is not looked at (module docstring); a feedback past the rounds' bound is clipped to
    MAX_WIDENING, one that pulls β back to 1."""
    A = np.zeros((5, 5))
    i = {law: LAWS.index(law) for law in LAWS}
    A[i["shear_beta"], i["shear_beta"]] = 0.05
    A[i["bulk_beta"], i["shear_beta"]] = 0.6
    A[i["shear_beta"], i["bulk_beta"]] = 0.5
    A[i["tension"], i["shear_beta"]] = 0.4
    moved = [shifted(THETA, law) for law in MOVED]
    J = jacobian(THETA, _refit(A, THETA, THETA), moved, [_refit(A, THETA, m) for m in moved])
    rows = [i[law] for law in MOVED]
    assert J == pytest.approx(A[np.ix_(rows, rows)], abs=1e-9)
    w = widening(J)
    assert w["shear_exponent"] == pytest.approx(1 / 0.65)
    assert w["bulk_exponent"] == pytest.approx(0.95 / 0.65)
    assert widening(np.diag([0.95, 0.0]))["bulk_exponent"] == MAX_WIDENING == 5.0
    assert widening(np.diag([0.0, -0.5]))["shear_exponent"] == 1.0


def test_the_widened_interval_covers_the_fixed_point_the_point_fits_does_not():
    """A cell's data y ~ N(β*, σ²) read through a correction with feedback s: g(θ; y) = y + s (θ - β*).
    The fixed point θ* = β* + (y - β*)/(1 - s) spreads 1/(1 - s) times the point fit's σ, so the
    point fit's 95 % interval about θ* (± 1.96 σ) holds β* in 68 % of 4000 cells at s = 0.5 and the
    one widened by M = 2 in 95 %."""
    rng = np.random.default_rng(3)
    sigma, s, star = 0.02, 0.5, 0.3
    y = rng.normal(star, sigma, 4000)
    theta = star + (y - star) / (1 - s)
    table = pd.DataFrame({"cell_id": [f"c{i}" for i in range(y.size)], "bulk_exponent": 0.1,
                          "bulk_exponent_lo95": 0.09, "bulk_exponent_hi95": 0.11, "shear_exponent": theta,
                          "shear_exponent_lo95": theta - 1.96 * sigma, "shear_exponent_hi95": theta + 1.96 * sigma})
    wide = widened(table, {c: widening(np.diag([0.0, s])) for c in table["cell_id"]})
    held = lambda t: float(((t["shear_exponent_lo95"] <= star) & (star <= t["shear_exponent_hi95"])).mean())  # noqa: E731
    assert held(table) == pytest.approx(0.68, abs=0.03)
    assert held(wide) == pytest.approx(0.95, abs=0.015)
    assert (wide["bulk_exponent_hi95"] - wide["bulk_exponent_lo95"]).to_numpy() == pytest.approx(0.02)
    assert (wide["shear_exponent_widening"] == 2.0).all() and (wide["bulk_exponent_widening"] == 1.0).all()
    other = widened(table.head(3), {})                          # a reading without rounds: unchanged
    pd.testing.assert_frame_equal(other.drop(columns=["bulk_exponent_widening", "shear_exponent_widening"]),
                                  table.head(3))
