"""One frequency's population of ln K̃_S with each cell's measurement error taken out.

Cell i has the fitted y_i = ln K̃_S,i and its standard error s_i, `ln_ks_se` of the
cells table: the RMS deviation from y_i of the ln K̃_S refits of its bootstrap draws,
among the drawn truths the protocol admits (`analysis.invert.intervals`; on the
included cells of synthetic experiments its RMS is about the RMS of their actual
errors, docs/population.md).

The normal-normal random-effects model (the one of meta-analysis):

    y_i = θ_i + e_i,   θ_i ~ N(μ, τ²) (the cells),   e_i ~ N(0, s_i²) (the measurement),
    so  y_i ~ N(μ, τ² + s_i²),  w_i(τ) = 1 / (τ² + s_i²),
    ℓ(μ, τ)  = -1/2 Σ [ln(τ² + s_i²) + w_i (y_i - μ)²],
    μ̂(τ)    = Σ w_i y_i / Σ w_i,
    ℓ_R(τ)   = ℓ(μ̂(τ), τ) - 1/2 ln Σ w_i            (restricted likelihood, REML).

τ̂ maximises ℓ_R (REML: with s_i = 0 it gives the sample SD with n - 1, where plain
maximum likelihood is biased low by a factor sqrt((n-1)/n)); its 95 % interval is
the likelihood-ratio (profile) one, the τ with 2 (ℓ_R(τ̂) - ℓ_R(τ)) ≤ χ²_1,0.95
(Hardy & Thompson 1996; scipy's `minimize_scalar` and `brentq`): unlike a Wald
interval (τ̂ ± 1.96 SE) it stays inside τ ≥ 0 and follows the likelihood's skew
with 20-60 cells.

μ is estimated by the plain mean ȳ with the t interval ȳ ± t_{n-1} sd(y)/√n, not by
the precision-weighted μ̂(τ̂): the var(ȳ) = (τ² + mean s_i²)/n the sample variance
estimates holds for any pattern of s_i, while the weighted mean is biased when s_i
depends on θ_i. It does with these standard errors: cells of high K̃_S (flatter
K(h̃)) have larger ones (1.4 times larger above ln K̃_S = 0 than below; correlation
0.28 with the true ln K̃_S over 30 synthetic experiments, docs/population.md), and
the weighted mean differed from the plain one by -0.09 to +0.14 there.

The measurement part: s_m² = mean_i s_i², the variance measurement error alone
adds to the observed spread; its share of the observed variance
s_m² / (τ² + s_m²), whose interval is the image of τ's (the share falls as τ grows).

Assumptions: θ_i normal (K̃_S lognormal, SPEC 6), errors independent between
cells and normal on the ln K̃_S scale with SD s_i, the cells a
random sample of the population (the quality filters do not select on K̃_S).
"""

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
from scipy import optimize, stats

LEVEL = 0.95
CHI2 = float(stats.chi2.ppf(LEVEL, 1))          # 3.84: the likelihood-ratio cut of a 95 % interval
TAU_MAX_FACTOR = 10.0                           # τ searched in [0, 10 × (SD of y + max s)]


@dataclass(frozen=True)
class Population:
    """The fit of one frequency: μ and τ (ln K̃_S) with 95 % intervals, s_m and its share."""

    n_cells: int
    mean: float
    mean_lo: float
    mean_hi: float
    sd: float
    sd_lo: float
    sd_hi: float
    measurement_sd: float
    share: float
    share_lo: float
    share_hi: float

    def to_dict(self) -> dict:
        return {"n_cells": self.n_cells, "mean_ln_ks": self.mean, "mean_ln_ks_lo95": self.mean_lo,
                "mean_ln_ks_hi95": self.mean_hi, "between_cell_sd_ln_ks": self.sd,
                "between_cell_sd_ln_ks_lo95": self.sd_lo, "between_cell_sd_ln_ks_hi95": self.sd_hi,
                "measurement_sd_ln_ks": self.measurement_sd, "measurement_share": self.share,
                "measurement_share_lo95": self.share_lo, "measurement_share_hi95": self.share_hi}


def _variance(s2: Any, tau: Any) -> Any:
    return np.maximum(tau**2 + s2, 1e-12)       # τ = s = 0 would divide by zero


def _weighted_mean(y: Any, s2: Any, tau: Any) -> tuple[float, Any]:
    w = 1.0 / _variance(s2, tau)
    return float(np.sum(w * y) / np.sum(w)), w


def loglik(y: np.ndarray, s2: np.ndarray, mu: float, tau: float) -> float:
    """ℓ(μ, τ) of the module doc."""
    v = _variance(s2, tau)
    return float(-0.5 * np.sum(np.log(v) + (y - mu) ** 2 / v))


def restricted_loglik(y: np.ndarray, s2: np.ndarray, tau: float) -> float:
    """ℓ_R(τ) = ℓ(μ̂(τ), τ) - 1/2 ln Σ w_i."""
    mu, w = _weighted_mean(y, s2, tau)
    return loglik(y, s2, mu, tau) - 0.5 * float(np.log(np.sum(w)))


def _argmax(f: Callable[[float], float], hi: float) -> tuple[float, float]:
    """The τ in [0, hi] that maximises f, and f there."""
    r = optimize.minimize_scalar(lambda t: -f(t), bounds=(0.0, hi), method="bounded",
                                 options={"xatol": 1e-6 * hi})
    x = float(r.x) if -r.fun >= f(0.0) else 0.0
    return x, f(x)


def _ends(dev: Callable[[float], float], centre: float, lo_bound: float, hi_bound: float) -> tuple[float, float]:
    """The roots of dev(x) = χ² left and right of `centre` in [lo_bound, hi_bound]
    (the bound itself where dev stays below the cut)."""
    g = lambda x: dev(x) - CHI2                                                  # noqa: E731
    lo = lo_bound if g(lo_bound) <= 0 else optimize.brentq(g, lo_bound, centre, xtol=1e-8)
    hi = hi_bound if g(hi_bound) <= 0 else optimize.brentq(g, centre, hi_bound, xtol=1e-8)
    return float(lo), float(hi)


def fit(y: npt.NDArray[np.float64], s: npt.NDArray[np.float64]) -> Population:
    """The random-effects fit of ln K̃_S values `y` with measurement SDs `s` (same length;
    non-finite pairs are left out). NaN fields with fewer than 3 cells."""
    y, s = np.asarray(y, float), np.asarray(s, float)
    keep = np.isfinite(y) & np.isfinite(s)
    y, s2 = y[keep], s[keep] ** 2
    n = int(y.size)
    s_m = float(np.sqrt(np.mean(s2))) if n else float("nan")
    if n < 3:
        nan = float("nan")
        return Population(n, nan, nan, nan, nan, nan, nan, s_m, nan, nan, nan)
    top = TAU_MAX_FACTOR * (float(np.std(y)) + float(np.sqrt(s2.max())) + 1e-12)
    tau, best_r = _argmax(lambda t: restricted_loglik(y, s2, t), top)
    tau_lo, tau_hi = _ends(lambda t: 2.0 * (best_r - restricted_loglik(y, s2, t)), tau, 0.0, top)
    mu = float(np.mean(y))
    half = float(stats.t.ppf(0.5 + LEVEL / 2, n - 1) * np.std(y, ddof=1) / np.sqrt(n))
    mu_lo, mu_hi = mu - half, mu + half
    share = lambda t: s_m**2 / (t**2 + s_m**2) if s_m > 0 else 0.0              # noqa: E731
    return Population(n, mu, mu_lo, mu_hi, tau, tau_lo, tau_hi, s_m, share(tau), share(tau_hi), share(tau_lo))
