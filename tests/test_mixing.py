"""Anderson's mixing (analysis.mixing): the secant on a linear map, and the fixed point of a linear
map in n dimensions after n + 1 mixed rounds of depth n."""

import numpy as np

from analysis.mixing import mixed


def test_one_dimension_is_the_secant_and_exact_for_a_linear_map():
    g = lambda x: 3.0 + 0.9 * (x - 3.0)          # noqa: E731  contracts slowly towards 3
    xs = [np.array([10.0]), np.array([g(10.0)])]
    nxt = mixed(xs, [g(x) for x in xs], depth=1)
    assert np.allclose(nxt, [3.0])
    assert np.allclose(mixed(xs[:1], [g(xs[0])], depth=1), g(xs[0]))     # one round: its output


def test_linear_map_in_three_dimensions():
    rng = np.random.default_rng(0)
    A = np.diag([0.95, 0.5, -0.6]) + 0.05 * rng.standard_normal((3, 3))
    star = np.array([1.0, -2.0, 0.5])
    g = lambda x: star + A @ (x - star)          # noqa: E731
    xs, gs = [np.zeros(3)], [g(np.zeros(3))]
    for _ in range(4):
        xs.append(mixed(xs, gs, depth=3))
        gs.append(g(xs[-1]))
    assert np.allclose(xs[-1], star, atol=1e-8)
    plain = np.zeros(3)
    for _ in range(5):
        plain = g(plain)
    assert np.linalg.norm(plain - star) > 0.5    # five plain rounds are still far
