"""The rounds' next laws (analysis.afm.law_rounds): Anderson's mixing reaches a slowly contracting
fixed point that the plain iteration stops short of."""

import math

import numpy as np

from analysis.afm.law_rounds import MAX_EXTRAPOLATION, moved, next_laws

TRUTH = {"bulk_1s": 24.0, "shear_1s": 12.0, "bulk_beta": 0.05, "shear_beta": 0.29, "tension": 1.05}
START = {"bulk_1s": 31.0, "shear_1s": 9.7, "bulk_beta": 0.25, "shear_beta": 0.37, "tension": 1.3}
RATES = {"bulk_1s": 0.5, "shear_1s": 0.3, "bulk_beta": 0.8, "shear_beta": 0.6, "tension": 0.2}


def _g(laws):
    """A fit that contracts towards TRUTH at RATES (in ln for the moduli and γ_a), with a coupling
    of β_S to β_B."""
    out = {}
    for k, rate in RATES.items():
        if k.endswith("beta"):
            out[k] = TRUTH[k] + rate * (laws[k] - TRUTH[k])
        else:
            out[k] = TRUTH[k] * (laws[k] / TRUTH[k]) ** rate
    out["shear_beta"] += 0.2 * (laws["bulk_beta"] - TRUTH["bulk_beta"])
    return out


def _rounds(accelerated, limit=30):
    """Replays until the next laws do not move (law_rounds.moved); the laws replayed last, how many."""
    laws, rounds = START, []
    for n in range(1, limit + 1):
        found = _g(laws)
        rounds.append((laws, found))
        following = next_laws(rounds) if accelerated else found
        if not moved(laws, following):
            return laws, n
        laws = following
    return laws, limit


def test_mixing_settles_near_the_fixed_point_where_plain_rounds_stop_short():
    plain, n_plain = _rounds(False)
    mixed, n_mixed = _rounds(True)
    assert abs(plain["bulk_beta"] - TRUTH["bulk_beta"]) > 0.03       # crept to within 0.01 a step
    assert abs(mixed["bulk_beta"] - TRUTH["bulk_beta"]) < 0.005
    assert abs(mixed["shear_beta"] - TRUTH["shear_beta"]) < 0.005
    assert abs(math.log(mixed["bulk_1s"] / TRUTH["bulk_1s"])) < 0.01
    assert n_mixed < n_plain


def test_one_round_is_the_plain_step_and_a_long_jump_is_capped():
    found = _g(START)
    assert next_laws([(START, found)]) == found
    # a residual that barely changes between rounds asks for a huge extrapolation: capped
    a = dict(START, bulk_beta=0.30)
    b = dict(START, bulk_beta=0.29)
    ga, gb = dict(a, bulk_beta=0.35), dict(b, bulk_beta=0.3401)
    nxt = next_laws([(a, ga), (b, gb)])
    step = (nxt["bulk_beta"] - gb["bulk_beta"]) / 0.01
    residual = (gb["bulk_beta"] - b["bulk_beta"]) / 0.01
    assert abs(step) <= MAX_EXTRAPOLATION * abs(residual) + 1e-9
    assert np.isclose(abs(step), MAX_EXTRAPOLATION * abs(residual))


def test_exponents_stay_in_range():
    a, b = dict(START, bulk_beta=0.02), dict(START, bulk_beta=0.01)
    nxt = next_laws([(a, dict(a, bulk_beta=0.0)), (b, dict(b, bulk_beta=0.0))])
    assert nxt["bulk_beta"] >= 0.0
