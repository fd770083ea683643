"""The droplet shape's compiled numerics (`solver.geometry` has the math and
the public functions; this module is imported, and numba with it, only
when a shape is first integrated).

`integrate`: the quadrature of the half integrals, for R_eq = 1, R_c = k,
from the contact line (ψ = 0) to ψ_end,

    z = ∫ dz,  V = π ∫ r² dz,  A = 2π ∫ r ds   (ds/dψ = (1 + sin ψ / q)/(2H),
    r = (sin ψ + q)/(2H), dz = sin ψ ds, q = sqrt(sin² ψ + β²), H = 1/(1 - k²), β = 2Hk),

composite Gauss-Legendre on [0, lo] and on m ≤ `intervals` intervals from
lo = min(β/8, ψ_end/2) to ψ_end growing geometrically by (ψ_end/lo)^(1/m)
≤ `growth`.

`solve`: for each h̃, the k with h̃(k) = h̃ and that shape's half integrals,
h̃(k) = 2z / (2 cbrt(3 · 2V / 4π)): the start k₀ and slope dk/du of the
cubic through the four table points (u, k) around u = sqrt(1 - h̃)
(Newton's divided differences), then at most two Newton steps
k ← clip(k + (u - u(k)) dk/du, 0, k_max), the second only where the first
moved k by more than 1e-9 k. Every operation is the one numpy did before
these were compiled, in the same order: the same bits.
"""

from typing import Any

import numpy as np
import numpy.typing as npt

from solver.jit import njit


@njit(cache=True, error_model="numpy")
def half_integrals(k: float, psi_end: float, gl_x: npt.NDArray[np.float64], gl_w: npt.NDArray[np.float64], intervals: int,
                   growth: float) -> tuple[float, float, float]:
    """(z, V, A) of one shape, up to ψ_end (module docstring)."""
    H = 1.0 / (1.0 - k * k)
    beta = 2.0 * H * k
    lo = min(max(beta, 1e-14) / 8.0, psi_end / 2.0)
    ratio = psi_end / lo
    m = min(max(int(np.ceil(np.log(ratio) / np.log(growth))), 1), intervals)
    zi, vi, ai, a = 0.0, 0.0, 0.0, 0.0
    for j in range(m + 1):
        b = lo * ratio ** (j / m) if j < m else psi_end
        mid, half = 0.5 * (a + b), 0.5 * (b - a)
        for node in range(gl_x.size):
            psi = mid + half * gl_x[node]
            w = half * gl_w[node]
            s = np.sin(psi)
            q = np.sqrt(s * s + beta * beta)
            g = (1.0 + s / q) / (2.0 * H)            # ds/dψ
            r = (s + q) / (2.0 * H)
            dz = s * g
            zi += w * dz
            vi += w * r * r * dz
            ai += w * r * g
        a = b
    return zi, np.pi * vi, 2.0 * np.pi * ai


@njit(cache=True, error_model="numpy")
def integrate(k: npt.NDArray[np.float64], psi_end: npt.NDArray[np.float64], gl_x: npt.NDArray[np.float64], gl_w: npt.NDArray[np.float64], intervals: int,
              growth: float) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """`half_integrals` of every (k, ψ_end): arrays z, V, A."""
    z, vol, area = np.empty(k.size), np.empty(k.size), np.empty(k.size)
    for i in range(k.size):
        z[i], vol[i], area[i] = half_integrals(k[i], psi_end[i], gl_x, gl_w, intervals, growth)
    return z, vol, area


@njit(cache=True, error_model="numpy")
def height_ratio(z: float | npt.NDArray[np.float64], vol: float | npt.NDArray[np.float64]) -> Any:    # z's kind: a number or an array
    """h̃ = 2z / (2 cbrt(3 · 2V / 4π)) of half integrals (z, V) to the equator
    (numbers or arrays)."""
    return (2.0 * z) / (2.0 * np.cbrt(3.0 * (2.0 * vol) / (4.0 * np.pi)))


@njit(cache=True, error_model="numpy")
def _start(u, xs, ys):
    """k₀(u) and dk/du of the cubic through the four table points around u."""
    i = min(max(np.searchsorted(xs, u) - 2, 0), xs.size - 4)
    X, Y = xs[i:i + 4], ys[i:i + 4]
    d10, d11, d12 = (Y[1] - Y[0]) / (X[1] - X[0]), (Y[2] - Y[1]) / (X[2] - X[1]), (Y[3] - Y[2]) / (X[3] - X[2])
    d20, d21 = (d11 - d10) / (X[2] - X[0]), (d12 - d11) / (X[3] - X[1])
    d3 = (d21 - d20) / (X[3] - X[0])
    a, b, c = u - X[0], u - X[1], u - X[2]
    q2 = d20 + c * d3
    q1 = d10 + b * q2
    return Y[0] + a * q1, q1 + a * (q2 + b * d3)


@njit(cache=True, error_model="numpy")
def solve(h_tilde: npt.NDArray[np.float64], xs: npt.NDArray[np.float64], ys: npt.NDArray[np.float64], k_max: float, gl_x: npt.NDArray[np.float64], gl_w: npt.NDArray[np.float64], intervals: int,
          growth: float) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """k and the half integrals (z, V, A) to the equator of every h̃."""
    n = h_tilde.size
    k, z, vol, area = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    for i in range(n):
        u = np.sqrt(max(1.0 - h_tilde[i], 0.0))
        ki, slope = _start(u, xs, ys)
        for _ in range(2):
            zi, vi, _a = half_integrals(ki, np.pi / 2, gl_x, gl_w, intervals, growth)
            uk = np.sqrt(max(1.0 - height_ratio(zi, vi), 0.0))
            step = min(max(ki + (u - uk) * slope, 0.0), k_max)
            moved = np.abs(step - ki) > 1e-9 * step
            ki = step
            if not moved:
                break
        k[i] = ki
        z[i], vol[i], area[i] = half_integrals(ki, np.pi / 2, gl_x, gl_w, intervals, growth)
    return k, z, vol, area
