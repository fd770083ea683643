"""Banded LU factorisation with partial pivoting, compiled (LAPACK's gbtf2 and gbtrs).

A square matrix A (n × n) with kl sub- and ku super-diagonals is held in
LAPACK band storage with kl extra rows for the fill-in of the row swaps:

    ab[kv + i - j, j] = A[i, j],   kv = kl + ku,   ab of shape (2 kl + ku + 1, n).

`factor` overwrites ab with P A = L U column by column: the pivot of column
j is its largest entry on or below the diagonal (the first of equal ones),
rows j and the pivot row are swapped over the columns the factor reaches,
the multipliers l_ij = a_ij / a_jj are stored below the diagonal (scaled by
the reciprocal 1/a_jj, as LAPACK does) and the trailing block updated,
a_ic -= l_ij a_jc. `solve` applies the swaps and L forwards, then U
backwards, to the columns of B. The operations are those of the reference
LAPACK/BLAS routines; an optimised BLAS may group them differently, so
results agree with scipy's gbsv to round-off. Called from compiled code
(`solver.fast.newton`), so no Python is crossed per solve.
"""

import numpy as np
import numpy.typing as npt

from solver.jit import njit


@njit(cache=True)
def factor(ab: npt.NDArray[np.float64], kl: int, ku: int, ipiv: npt.NDArray[np.int64]) -> int:
    """LU-factorise the band matrix in ab in place (module docstring); the
    pivot rows go to ipiv. Returns 0, or j + 1 if U's diagonal entry j is
    zero (the matrix is singular)."""
    n, kv, ju, info = ab.shape[1], kl + ku, 0, 0
    for j in range(n):
        km = min(kl, n - 1 - j)
        jp = 0
        for i in range(1, km + 1):
            if abs(ab[kv + i, j]) > abs(ab[kv + jp, j]):
                jp = i
        ipiv[j] = j + jp
        if ab[kv + jp, j] == 0.0:
            info = j + 1 if info == 0 else info
            continue
        ju = max(ju, min(j + ku + jp, n - 1))
        if jp != 0:
            for c in range(ju - j + 1):
                ab[kv + jp - c, j + c], ab[kv - c, j + c] = ab[kv - c, j + c], ab[kv + jp - c, j + c]
        if km > 0:
            rec = 1.0 / ab[kv, j]
            for i in range(1, km + 1):
                ab[kv + i, j] *= rec
            for c in range(1, ju - j + 1):
                y = ab[kv - c, j + c]
                if y != 0.0:
                    for i in range(1, km + 1):
                        ab[kv + i - c, j + c] -= ab[kv + i, j] * y
    return info


@njit(cache=True)
def solve(ab: npt.NDArray[np.float64], kl: int, ku: int, ipiv: npt.NDArray[np.int64], B: npt.NDArray[np.float64]) -> None:
    """Overwrite B (n × m) with A⁻¹ B, ab and ipiv from `factor`."""
    n, kv = ab.shape[1], kl + ku
    for j in range(n - 1):
        lm, p = min(kl, n - 1 - j), ipiv[j]
        for c in range(B.shape[1]):
            if p != j:
                B[p, c], B[j, c] = B[j, c], B[p, c]
            y = B[j, c]
            if y != 0.0:
                for i in range(1, lm + 1):
                    B[j + i, c] -= ab[kv + i, j] * y
    for j in range(n - 1, -1, -1):      # the columns side by side: independent chains overlap
        for c in range(B.shape[1]):
            if B[j, c] != 0.0:
                B[j, c] /= ab[kv, j]
                y = B[j, c]
                for i in range(j - 1, max(0, j - kv) - 1, -1):
                    B[i, c] -= ab[kv + i - j, j] * y
