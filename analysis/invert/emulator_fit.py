"""Inversion by the emulator (SPEC 9): per cell, K_B and K̃_S from the measured
K(h̃), γ_a measured.

Model of cell i at its used heights j (`analysis.invert.inversion.used_heights`):

    K_ij = K_B,i f(h̃_ij, K̃_S,i, γ_a,i / K_B,i; V_i)       (f: `analysis.calibration.emulator`)

Unknowns θ_i = (ln K_B,i, ln K̃_S,i); least squares of the residuals
r_ij = K_ij(θ_i) - K_ij^measured (mN/m), all cells in one
`scipy.optimize.least_squares` call (trust-region reflective, a sparse block
Jacobian: the cells are independent), with

    ∂K/∂ln K_B  = K (1 - ∂ln f/∂ln γ̃_a),     ∂K/∂ln K̃_S = K ∂ln f/∂ln K̃_S.

Start: for 25 values of K̃_S spaced in ln over the bounds, K_B by the fixed
point K_B = Σ K f / Σ f² (f at γ_a/K_B, three sweeps); the best of them.
Bounds: K̃_S within the emulator's grid widened by KS_MARGIN on both sides;
a fit at a bound is excluded (the answer lies beyond the tabulated ν).
Then ν = (1 - K̃_S)/(1 + K̃_S), R² = 1 - SS_res/SS_tot over the used heights,
and the published filters (`analysis.invert.inversion.exclusions`). `outside_emulator`
flags a fit whose K̃_S, γ̃_a, heights or volume leave the tabulated grid (the
spline extrapolates there); `nu_beyond_isotropic` flags ν > 0.5, the limit of
an isotropic 3-D material (reported as it is).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
import numpy.typing as npt
import pandas as pd
from scipy import sparse
from scipy.optimize import least_squares

from analysis.calibration.emulator import OFFSET
from analysis.invert.inversion import exclusions, used_heights
from solver.elasticity import poisson_of_ratio

if TYPE_CHECKING:
    from analysis.calibration.emulator import Emulator

KS_MARGIN = 2.0          # K̃_S bounds: the grid's range widened by this factor
START_POINTS = 25
NU_ISOTROPIC_MAX = 0.5


class CurveArrays(NamedTuple):
    """The emulator fit's arrays of many cells' K(h̃) curves (the labelled table is
    `analysis.invert.curves.Curves`), NaN-padded rows: h̃, K (mN/m), the heights used,
    γ_a (mN/m) and V (µm³) per cell."""

    h: Any
    k: Any
    use: Any
    tension: Any
    volume: Any


def ks_bounds(emulator: Emulator, bending: str) -> tuple[float, float]:
    """The fit's bounds of ln K̃_S: the emulator's grid widened by KS_MARGIN."""
    lo, hi = emulator.domain(bending)["ks_tilde"]
    return np.log(lo / KS_MARGIN), np.log(hi * KS_MARGIN)


def filled_heights(h: npt.ArrayLike, use: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """h̃ with unused entries replaced by a harmless value (they are masked out)."""
    return np.where(use, h, 0.6)


def _start(emulator: Emulator, bending: str, curves: CurveArrays) -> Any:
    """θ0 per cell: the best of START_POINTS values of ln K̃_S, K_B by three
    fixed-point steps of the linear least squares at each."""
    h, k, use, tension, volume = curves
    lo, hi = ks_bounds(emulator, bending)
    best_ss = np.full(h.shape[0], np.inf)
    best = np.zeros((h.shape[0], 2))
    mean_k = np.nanmean(np.where(use, k, np.nan), axis=1)
    for lks in np.linspace(lo + 1e-6, hi - 1e-6, START_POINTS):
        bulk = mean_k.copy()
        for _ in range(3):
            f = emulator.ratio(h, np.exp(lks), tension[:, None] / bulk[:, None], volume[:, None], bending, use)
            bulk = np.sum(np.where(use, k * f, 0), axis=1) / np.sum(np.where(use, f * f, 0), axis=1)
            bulk = np.clip(np.nan_to_num(bulk, nan=1.0), 1e-3, 1e4)
        f = emulator.ratio(h, np.exp(lks), tension[:, None] / bulk[:, None], volume[:, None], bending, use)
        ss = np.sum(np.where(use, (bulk[:, None] * f - k) ** 2, 0), axis=1)
        better = ss < best_ss
        best_ss[better] = ss[better]
        best[better] = np.column_stack([np.log(bulk), np.full(h.shape[0], lks)])[better]
    return best


def model(emulator: Emulator, bending: str, theta: npt.NDArray[np.float64], h: npt.ArrayLike,
          tension: npt.NDArray[np.float64],
          volume: npt.NDArray[np.float64]) -> tuple[Any, Any, Any]:
    """K (mN/m) and its derivatives by (ln K_B, ln K̃_S), for θ of shape (cells, 2)."""
    bulk, ks = np.exp(theta[:, 0])[:, None], np.exp(theta[:, 1])[:, None]
    lr, d_ks, d_g = emulator.grad_log(h, ks, tension[:, None] / bulk, volume[:, None], bending)
    K = bulk * np.exp(lr)
    return K, K * (1.0 - d_g), K * d_ks


class _Model:
    """`model` split for the least squares: K at θ (the spline's value only) for the residuals,
    its derivatives for the Jacobian, which the solver asks at the θ it has just evaluated K at,
    so that evaluation is kept; only at the heights used (NaN at the others, masked out); the
    same arithmetic as `model`, number for number."""

    def __init__(self, table: Any, h: Any, use: Any, tension: Any, volume: Any) -> None:
        self.table, self.h, self.use, self.tension, self.volume = table, h, use, tension, volume
        self.key: bytes | None = None

    def moduli(self, theta: npt.NDArray[np.float64]) -> Any:
        """K (mN/m) at θ (cells, 2)."""
        key = theta.tobytes()
        if key != self.key:
            bulk, ks = np.exp(theta[:, 0])[:, None], np.exp(theta[:, 1])[:, None]
            self.args = (self.h, ks, self.tension[:, None] / bulk, self.volume[:, None])
            self.ey = np.exp(self.table.log_excess(*self.args, where=self.use))
            self.ratio = 1.0 - OFFSET + self.ey
            self.K = bulk * np.exp(np.log(self.ratio))
            self.key = key
        return self.K

    def slopes(self, theta: npt.NDArray[np.float64]) -> tuple[Any, Any]:
        """∂K/∂ln K_B and ∂K/∂ln K̃_S at θ."""
        K = self.moduli(theta)
        share = self.ey / self.ratio
        d_ks = share * self.table.log_excess(*self.args, nu=(0, 0, 1, 0), where=self.use)
        d_g = share * self.table.log_excess(*self.args, nu=(0, 0, 0, 1), where=self.use)
        return K * (1.0 - d_g), K * d_ks


def fit(emulator: Emulator, bending: str, curves: CurveArrays) -> npt.NDArray[np.float64]:
    """θ = (ln K_B, ln K̃_S) per cell (rows of `CurveArrays`), least squares over all
    cells at once. Cells without usable heights get NaN."""
    h, k, use, tension, volume = curves
    n, m = h.shape
    ok = use.sum(axis=1) >= 2
    theta = np.full((n, 2), np.nan)
    if not ok.any():
        return theta
    sub = CurveArrays(filled_heights(h[ok], use[ok]), np.where(use[ok], k[ok], 0), use[ok], tension[ok], volume[ok])
    hs, ks, us, ts, vs = sub
    cells = hs.shape[0]
    rows = np.repeat(np.arange(cells * m), 2)
    cols = (np.repeat(np.arange(cells), m)[:, None] * 2 + np.arange(2)).ravel()

    at = _Model(emulator[bending], hs, us, ts, vs)

    def residuals(x: Any) -> Any:
        return np.where(us, at.moduli(x.reshape(-1, 2)) - ks, 0.0).ravel()

    def jacobian(x: Any) -> Any:
        dkb, dks = at.slopes(x.reshape(-1, 2))
        vals = np.stack([np.where(us, dkb, 0.0), np.where(us, dks, 0.0)], axis=-1).ravel()
        return sparse.csr_matrix((vals, (rows, cols)), shape=(cells * m, cells * 2))

    lo, hi = ks_bounds(emulator, bending)
    x0 = _start(emulator, bending, sub)
    lower = np.tile([np.log(1e-3), lo], cells)
    upper = np.tile([np.log(1e4), hi], cells)
    x0 = np.clip(x0.ravel(), lower + 1e-9, upper - 1e-9)
    sol = least_squares(residuals, x0, jac=jacobian, bounds=(lower, upper), method="trf",
                        tr_solver="lsmr", x_scale="jac", ftol=1e-12, xtol=1e-12, gtol=1e-12, max_nfev=200)
    theta[ok] = sol.x.reshape(-1, 2)
    return theta


def invert_curves_emulator(h_tilde: npt.ArrayLike, modulus: npt.ArrayLike, tension: npt.ArrayLike,
                           volume: npt.ArrayLike, emulator: Emulator,
                           bending: str = "standard") -> pd.DataFrame:
    """Invert many cells (rows of NaN-padded (cells, heights) arrays; `tension` γ_a
    and `volume` V per cell). Returns a DataFrame with the columns of
    `analysis.invert.inversion.invert_curves` (α is NaN: the emulator has none) plus
    `outside_emulator`, `nu_beyond_isotropic`, `rms_mN_per_m`."""
    h = np.atleast_2d(np.asarray(h_tilde, float))
    k = np.atleast_2d(np.asarray(modulus, float))
    tension = np.broadcast_to(np.asarray(tension, float), h.shape[:1]).copy()
    volume = np.broadcast_to(np.asarray(volume, float), h.shape[:1]).copy()
    use, n, top = used_heights(h, k)
    use &= (tension > 0)[:, None]
    curves = CurveArrays(h, k, use, tension, volume)
    theta = fit(emulator, bending, curves)
    bulk, ks = np.exp(theta[:, 0]), np.exp(theta[:, 1])
    nu = poisson_of_ratio(ks)
    r2, rms = _goodness(emulator, bending, theta, curves)
    lo, hi = ks_bounds(emulator, bending)
    at_bound = np.isfinite(theta[:, 1]) & ((theta[:, 1] <= lo + 1e-6) | (theta[:, 1] >= hi - 1e-6))
    gamma_tilde = tension / bulk
    hmin = np.where(use, h, np.inf).min(axis=1)
    outside = ~(emulator.inside(hmin, ks, gamma_tilde, volume, bending)
                & emulator.inside(np.where(n > 0, top, hmin), ks, gamma_tilde, volume, bending))
    extra = [(at_bound, lambda i: f"K_S/K_B = {ks[i]:.3g} lies at the limit of the fit "
                                  f"({np.exp(lo):.3g}-{np.exp(hi):.3g}): nu beyond the tabulated range"),
             (~np.isfinite(nu), lambda i: "the emulator fit found no solution")]
    reasons = exclusions(n, top, bulk=bulk, tension=tension, nu=nu, r2=r2, extra=extra)
    return pd.DataFrame({"nu": nu, "ks_tilde": ks, "bulk_mN_per_m": bulk, "alpha": np.nan, "r2": r2,
                         "gamma_tilde": gamma_tilde, "n_heights": n,
                         "h_tilde_max": np.where(n > 0, top, np.nan), "rms_mN_per_m": rms,
                         "outside_emulator": outside & np.isfinite(nu),
                         "nu_beyond_isotropic": nu > NU_ISOTROPIC_MAX,
                         "excluded_reason": pd.Series(reasons, dtype=object)})


def _goodness(emulator: Emulator, bending: str, theta: Any, curves: CurveArrays) -> tuple[Any, Any]:
    """R² and the RMS residual (mN/m, n - 2 degrees of freedom) per cell."""
    h, k, use, tension, volume = curves
    with np.errstate(invalid="ignore", divide="ignore"):
        K, _, _ = model(emulator, bending, np.nan_to_num(theta), filled_heights(h, use), tension, volume)
        res = np.where(use, K - np.nan_to_num(k), 0.0)
        n = use.sum(axis=1)
        mean = np.sum(np.where(use, k, 0), axis=1) / n
        ss_tot = np.sum(np.where(use, (k - mean[:, None]) ** 2, 0), axis=1)
        ss_res = np.sum(res**2, axis=1)
        r2 = np.where(ss_tot > 0, 1.0 - ss_res / ss_tot, np.nan)
        rms = np.sqrt(ss_res / np.maximum(n - 2, 1))
    bad = ~np.isfinite(theta).all(axis=1)
    r2[bad], rms[bad] = np.nan, np.nan
    return r2, rms
