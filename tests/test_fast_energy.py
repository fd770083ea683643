"""The fast solver's discrete Lagrangian: exact gradient and Hessian, checked
against central differences of the energy and of the gradient."""

import numpy as np
import pytest

from solver import fast
from solver.model import Shell


@pytest.mark.parametrize("bending,shear", [("standard", 8.33), ("none", 25.0), ("double", 15.0)])
def test_gradient_and_hessian_match_differences(bending, shear):
    s = Shell(volume_um3=4300.0, h0_um=12.0, bulk_mN_per_m=25.0, shear_mN_per_m=shear,
              tension_mN_per_m=1.5, bending=bending)
    lag, u, _ = fast.equilibrium(s)
    zp = 0.5 * s.h1_um
    rng = np.random.default_rng(0)
    u = u + 1e-3 * rng.standard_normal(u.size) * np.r_[np.ones(u.size - 2), 10.0, 1.0]
    value, g, dzp, H = lag.evaluate(u, zp)
    h = 1e-6
    fd = np.empty_like(g)
    Hfd = np.empty_like(H)
    for j in range(u.size):
        up, um = u.copy(), u.copy()
        up[j] += h
        um[j] -= h
        fd[j] = (lag.evaluate(up, zp, False)[0] - lag.evaluate(um, zp, False)[0]) / (2 * h)
        Hfd[:, j] = (lag.evaluate(up, zp, False)[1] - lag.evaluate(um, zp, False)[1]) / (2 * h)
    scale = np.abs(g).max()
    assert np.abs(fd - g).max() < 1e-6 * scale
    assert np.abs(Hfd - H).max() < 1e-6 * np.abs(H).max()
    assert np.abs(H - H.T).max() < 1e-9 * np.abs(H).max()
    # the plate-height derivative, by moving the plate
    dz = (lag.evaluate(u, zp + h, False)[0] - lag.evaluate(u, zp - h, False)[0]) / (2 * h)
    assert dzp == pytest.approx(dz, rel=1e-6)


def test_banded_newton_solve_matches_dense():
    s = Shell(volume_um3=4300.0, h0_um=13.0, bulk_mN_per_m=25.0, shear_mN_per_m=15.0,
              tension_mN_per_m=2.0, bending="standard")
    lag, u, _ = fast.equilibrium(s)
    M = lag.newton_system(u, 0.5 * s.h1_um)[3]
    H = lag.dense(M)
    # the compiled parts are the dense Hessian's band and its l and p columns
    back = lag.banded(H)
    for part, again in zip(M, back):
        assert np.array_equal(part, again)
    keep = np.r_[0: lag.size - 2, lag.size - 1]
    rhs = np.random.default_rng(1).standard_normal((keep.size, 2))
    dense = np.linalg.solve(H[np.ix_(keep, keep)], rhs)
    for matrix in (M, H):
        assert np.allclose(lag.solve(matrix, rhs), dense, rtol=1e-8, atol=1e-10 * np.abs(dense).max())
