"""The fast solver's Newton iteration at fixed contact label, compiled.

Unknowns u = (x, l, p) as in `solver.fast.lagrangian` (x the node positions, l =
log ψ_c, p the pressure). At fixed l, Newton's method on ∇L = 0 for (x, p)
solves at each iteration the saddle-point system

    [A b; b^T 0] [dx; dp] = -[g_x; g_p],   A = ∂²L/∂x², b = ∂²L/∂x∂p,

by block elimination: A (banded in node order, half-bandwidth BAND) is
LU-factorised once (`solver.fast.banded`), A [X_f, X_b] = [f, b], then
dp = (b·X_f - f_p) / (b·X_b) and dx = X_f - X_b dp. The step u + t (dx, dp)
is halved (t = 1, 1/2, ...) while it leaves the admissible shapes (nodes off
the axis and in order along the plate, no element of zero length, no fold:
neighbouring elements turn by less than π/2) or makes the residual force
|g_x| grow a hundredfold; below t = 1e-3 the step is rejected. Converged when
max |g_x| < tol · force_scale and |g_p| = |V - V0| < 1e-9 V0.

The whole iteration (kernel evaluation `solver.fast.kernel.evaluate`, solve,
admissibility, step halving) is one compiled call, so a solve crosses from
Python into compiled code a few times instead of a few hundred. Its cached
machine code includes the kernel and the LU; `solver.jit` keeps the cache
per version of all the compiled sources, so an edit to either compiles the
iteration afresh.
"""

import numpy as np
import numpy.typing as npt

from solver.fast import banded
from solver.fast.kernel import Terms, evaluate
from solver.jit import njit

CONVERGED, SINGULAR, REJECTED, NOT_CONVERGED = 0, 1, 2, 3   # `newton`'s status


@njit(cache=True)
def nodes(u: npt.NDArray[np.float64], zp: float, N: int, kc: int) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """(r, z) of every node from the unknowns: the pole at r = 0, nodes up
    to k_c on the plate z = z_p, the equator on z = 0 (`Lagrangian.nodes`)."""
    r, z = np.empty(N + 1), np.empty(N + 1)
    r[0] = 0.0
    r[1:] = u[:N]
    z[: kc + 1] = zp
    z[kc + 1: N] = u[N: 2 * N - kc - 1]
    z[N] = 0.0
    return r, z


@njit(cache=True)
def shape_ok(r: npt.NDArray[np.float64], z: npt.NDArray[np.float64], kc: int) -> bool:
    """The admissible shapes: r > 0 off the pole, increasing along the plate
    (nodes up to kc), every element of nonzero length, dr_e dr_e+1 + dz_e dz_e+1 > 0
    between neighbours (no fold)."""
    for k in range(1, r.size):
        dr, dz = r[k] - r[k - 1], z[k] - z[k - 1]
        if not r[k] > 0 or (k <= kc and not dr > 0) or not np.hypot(dr, dz) > 0:
            return False
        if k >= 2 and not dr * (r[k - 1] - r[k - 2]) + dz * (z[k - 1] - z[k - 2]) > 0:
            return False
    return True


@njit(cache=True)
def block_solve(band: npt.NDArray[np.float64], pcol: npt.NDArray[np.float64], order: npt.NDArray[np.int64], bw: int, rhs: npt.NDArray[np.float64]) -> tuple[npt.NDArray[np.float64], int]:
    """The saddle-point system's solution (module docstring) for the columns
    of rhs ((n - 1) × m, in the order of the unknowns without l), with A in
    LAPACK band storage in node `order` (half-bandwidth bw) and b = pcol.
    Returns (solution, 0), or (rhs, info ≠ 0) if A is singular."""
    m, nx = rhs.shape[1], order.size
    ab = np.zeros((3 * bw + 1, nx))      # bw rows on top for the LU fill-in
    ab[bw:] = band
    X = np.empty((nx, m + 1))
    for i in range(nx):
        X[i, :m] = rhs[order[i]]
        X[i, m] = pcol[order[i]]
    ipiv = np.empty(nx, np.int64)
    info = banded.factor(ab, bw, bw, ipiv)
    if info != 0:
        return rhs, info
    banded.solve(ab, bw, bw, ipiv, X)
    out = np.empty_like(rhs)
    bxb = 0.0
    for i in range(nx):
        bxb += X[i, m] * pcol[order[i]]
    for c in range(m):
        bxf = 0.0
        for i in range(nx):
            bxf += pcol[order[i]] * X[i, c]
        y = (bxf - rhs[-1, c]) / bxb
        for i in range(nx):
            out[order[i], c] = X[i, c] - X[i, m] * y
        out[-1, c] = y
    return out, 0


@njit(cache=True)
def system(u: npt.NDArray[np.float64], zp: float, ref: tuple[npt.NDArray[np.float64], ...], terms: Terms, N: int,
           V0: float) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """∇L (size n) and the Newton matrix (band, lp) of `evaluate` at u."""
    n = u.size
    r, z = nodes(u, zp, N, terms.kc)
    _, grad, (band, lp) = evaluate((r, z, u[-1]), ref, terms, n, True)
    grad[n - 1] += V0
    return grad[:n], band, lp


@njit(cache=True)
def _residual_norm(g):
    """|g_x|, the Euclidean norm of the position residual g[:-2]."""
    s = 0.0
    for i in range(g.size - 2):
        s += g[i] * g[i]
    return np.sqrt(s)


@njit(cache=True)
def _step(u, dx, t):
    """u + t (dx, dp), l kept (dx in the order of the unknowns without l)."""
    ut = u.copy()
    n = u.size
    ut[: n - 2] += t * dx[: n - 2]
    ut[n - 1] += t * dx[n - 2]
    return ut


@njit(cache=True)
def newton(u: npt.NDArray[np.float64], zp: float, ref: tuple[npt.NDArray[np.float64], ...], terms: Terms, order: npt.NDArray[np.int64], N: int, V0: float,
           force_scale: float, tol: float, maxit: int) -> tuple[int, npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64], int]:
    """Newton's method at fixed l from u (module docstring), ref the
    reference positions at that l. Returns (status, u, g, band, lp,
    iterations): status CONVERGED, or SINGULAR, REJECTED, NOT_CONVERGED
    with the iteration at which it stopped and the last accepted state."""
    n = u.size
    g, band, lp = system(u, zp, ref, terms, N, V0)
    rhs = np.empty((n - 1, 1))
    for it in range(1, maxit + 1):
        rhs[: n - 2, 0] = -g[: n - 2]
        rhs[n - 2, 0] = -g[n - 1]
        dx, info = block_solve(band, lp[1], order, terms.band, rhs)
        if info != 0:
            return SINGULAR, u, g, band, lp, it
        norm0, t = _residual_norm(g), 1.0
        gt, bt, lpt = g, band, lp
        while True:
            ut = _step(u, dx[:, 0], t)
            r, z = nodes(ut, zp, N, terms.kc)
            if np.all(np.isfinite(ut)) and shape_ok(r, z, terms.kc):
                gt, bt, lpt = system(ut, zp, ref, terms, N, V0)
                if np.all(np.isfinite(gt)) and _residual_norm(gt) < 100.0 * norm0:
                    break
            t *= 0.5
            if t < 1e-3:
                return REJECTED, u, g, band, lp, it
        u, g, band, lp = ut, gt, bt, lpt
        if np.abs(g[: n - 2]).max() < tol * force_scale and abs(g[n - 1]) < 1e-9 * V0:
            return CONVERGED, u, g, band, lp, it
    return NOT_CONVERGED, u, g, band, lp, maxit
