"""The calibration law K(h̃) = K_B (1 + α exp(h̃/c)) and the fits built on it
(SPEC sections 4 and 6).

Four fits, each a least-squares problem with its goodness (R² and the largest
absolute residual, in the units of the fitted quantity):

- `fit_alpha_c`: K_B known, α and c free (calibration step 1). Write
  y = K/K_B - 1 = a exp(r (h̃ - h̃_m)) with r = 1/c and h̃_m the mean height
  (a decorrelates from r). For fixed r the best a is linear,
  a(r) = Σ y e / Σ e², so the residual is a function of r alone: a scan over r
  brackets the minimum, Levenberg-Marquardt on (a, r) polishes it, and the
  Jacobian gives the covariance (s² (JᵀJ)⁻¹, s² = SS_res/(n-2)); then
  α = a exp(-r h̃_m), c = 1/r, σ_c = σ_r / r².
- `fit_alpha`: K_B and c = λ known (step 2): α = Σ y e / Σ e², e = exp(h̃/λ).
- `fit_bulk_alpha`: λ known, K_B and α free (a measured cell, section 6):
  K = K_B + (K_B α) e is linear in (K_B, K_B α); solved in centred form,
  b = Σ (e-ē)(K-K̄) / Σ (e-ē)², K_B = K̄ - b ē, α = b / K_B, vectorised
  over many curves at once with a mask of the heights to use.
- `fit_log_law` (step 3): α = C ln K̃_S + D; `fit_polynomial` (step 4):
  C(γ̃_a), D(γ̃_a) as cubics, coefficients lowest order first.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt
from scipy.optimize import least_squares


def modulus_law(h_tilde: npt.ArrayLike, bulk: Any, alpha: Any, c: Any) -> Any:
    """K(h̃) = K_B (1 + α exp(h̃/c)), in the units of K_B (mN/m)."""
    return bulk * (1.0 + alpha * np.exp(np.asarray(h_tilde, float) / c))


def goodness(y: npt.ArrayLike, y_fit: npt.ArrayLike) -> tuple[float, float]:
    """(R², largest |y - y_fit|) with R² = 1 - SS_res / SS_tot (SS_tot about the mean).

    R² is 1 for a perfect fit, NaN when y is constant (SS_tot = 0)."""
    y, y_fit = np.asarray(y, float), np.asarray(y_fit, float)
    res = y - y_fit
    ss_tot = np.sum((y - y.mean()) ** 2)
    r2 = 1.0 - np.sum(res**2) / ss_tot if ss_tot > 0 else float("nan")
    return float(r2), float(np.max(np.abs(res))) if res.size else float("nan")


def fit_alpha_c(h_tilde: npt.ArrayLike, modulus: npt.ArrayLike, bulk: float) -> dict[str, float]:
    """Step 1: α and c of K(h̃) = K_B (1 + α exp(h̃/c)) with K_B known.

    Returns a dict: alpha, c, alpha_sd, c_sd (1-σ from the fit's covariance;
    NaN with fewer than three heights), r2, max_residual_mN_per_m."""
    h = np.asarray(h_tilde, float)
    y = np.asarray(modulus, float) / bulk - 1.0
    if h.size < 2 or np.ptp(h) == 0:
        raise ValueError("fitting alpha and c needs at least two distinct heights")
    hm = h.mean()
    x = h - hm

    def best_a(r: npt.ArrayLike) -> tuple[Any, Any]:
        e = np.exp(np.multiply.outer(r, x))
        return (e @ y) / np.sum(e * e, axis=-1), e

    span = np.ptp(h)
    rates = np.concatenate([-np.geomspace(200.0, 0.01, 400) / span, [0.0],
                            np.geomspace(0.01, 200.0, 400) / span])
    a, e = best_a(rates)
    sse = np.sum((y - a[:, None] * e) ** 2, axis=1)
    i = int(np.nanargmin(sse))
    start = np.array([a[i], rates[i] if rates[i] != 0 else 1e-6])
    scale = np.array([max(abs(start[0]), 1e-12), 1.0 / span])
    fit = least_squares(lambda p: p[0] * np.exp(p[1] * x) - y, start, method="lm",
                        x_scale=scale, xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=2000)
    a, r = fit.x
    dof = h.size - 2
    if dof > 0:
        s2 = np.sum(fit.fun**2) / dof
        cov = s2 * np.linalg.pinv(fit.jac.T @ fit.jac)
    else:
        cov = np.full((2, 2), np.nan)
    alpha, c = a * np.exp(-r * hm), 1.0 / r
    grad_alpha = np.array([np.exp(-r * hm), -hm * alpha])          # ∂α/∂(a, r)
    alpha_sd = float(np.sqrt(max(grad_alpha @ cov @ grad_alpha, 0.0))) if dof > 0 else float("nan")
    c_sd = float(np.sqrt(max(cov[1, 1], 0.0)) / r**2) if dof > 0 else float("nan")
    r2, worst = goodness(modulus, modulus_law(h, bulk, alpha, c))
    return {"alpha": float(alpha), "c": float(c), "alpha_sd": alpha_sd, "c_sd": c_sd,
            "r2": r2, "max_residual_mN_per_m": worst}


def fit_alpha(h_tilde: npt.ArrayLike, modulus: npt.ArrayLike, bulk: float, lam: float) -> dict[str, float]:
    """Step 2: α of K(h̃) = K_B (1 + α exp(h̃/λ)) with K_B and λ known (linear).

    Returns a dict: alpha, r2, max_residual_mN_per_m."""
    h = np.asarray(h_tilde, float)
    y = np.asarray(modulus, float) / bulk - 1.0
    e = np.exp(h / lam)
    alpha = float(e @ y / (e @ e))
    r2, worst = goodness(modulus, modulus_law(h, bulk, alpha, lam))
    return {"alpha": alpha, "r2": r2, "max_residual_mN_per_m": worst}


def fit_bulk_alpha(h_tilde: npt.ArrayLike, modulus: npt.ArrayLike, lam: float,
                   mask: npt.ArrayLike | None = None) -> Any:
    """A measured cell: K_B and α free, λ fixed, for one curve or many at once.

    `h_tilde`, `modulus`: arrays of shape (n,) or (curves, n); `mask` (same
    shape, default: finite entries) selects the heights to use. Returns
    (K_B, α, R²) as arrays of shape (curves,) (or scalars for one curve);
    NaN where fewer than two distinct heights are selected."""
    h = np.atleast_2d(np.asarray(h_tilde, float))
    k = np.atleast_2d(np.asarray(modulus, float))
    m = np.isfinite(h) & np.isfinite(k) if mask is None else np.atleast_2d(mask) & np.isfinite(h) & np.isfinite(k)
    w = m.astype(float)
    n = w.sum(axis=1)
    e = np.where(m, np.exp(np.where(m, h, 0.0) / lam), 0.0)
    kk = np.where(m, k, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        e_bar = e.sum(axis=1) / n
        k_bar = kk.sum(axis=1) / n
        de = w * (e - e_bar[:, None])
        dk = w * (kk - k_bar[:, None])
        see = np.sum(de * de, axis=1)
        b = np.sum(de * dk, axis=1) / see
        bulk = k_bar - b * e_bar
        alpha = b / bulk
        ss_res = np.sum((dk - b[:, None] * de) ** 2, axis=1)
        ss_tot = np.sum(dk * dk, axis=1)
        r2 = 1.0 - ss_res / ss_tot
    bad = (n < 2) | ~(see > 0)
    bulk, alpha, r2 = (np.where(bad, np.nan, v) for v in (bulk, alpha, r2))
    if np.ndim(h_tilde) == 1:
        return float(bulk[0]), float(alpha[0]), float(r2[0])
    return bulk, alpha, r2


def fit_log_law(ks_tilde: npt.ArrayLike, alpha: npt.ArrayLike) -> dict[str, float]:
    """Step 3: α = C ln K̃_S + D. Returns a dict: C, D, r2, max_residual (of α)."""
    x = np.log(np.asarray(ks_tilde, float))
    alpha = np.asarray(alpha, float)
    slope, intercept = np.polyfit(x, alpha, 1)
    r2, worst = goodness(alpha, slope * x + intercept)
    return {"C": float(slope), "D": float(intercept), "r2": r2, "max_residual": worst}


def fit_polynomial(x: npt.ArrayLike, y: npt.ArrayLike, degree: int = 3) -> dict[str, Any]:
    """Step 4: y(x) as a polynomial of the given degree (lowered to len(x) - 1
    if there are too few points). Returns a dict: coefficients (lowest order
    first), degree, r2, max_residual."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    degree = int(min(degree, x.size - 1))
    coef = np.polynomial.polynomial.polyfit(x, y, degree)
    r2, worst = goodness(y, np.polynomial.polynomial.polyval(x, coef))
    return {"coefficients": [float(v) for v in coef], "degree": degree, "r2": r2,
            "max_residual": worst}
