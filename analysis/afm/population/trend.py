"""The design-weighted frequency trend of ln K̃_S: a linear mixed model over all cells and frequencies
(the answer's trend is `mean_trend`; this one stays beside it in population.json).

Observation j of cell c at frequency f_j: y_j = ln K̃_S, x_j = log10(f_j / 1 Hz), s_j its
measurement SD (`random_effects.measurement_sd`):

    y_j = a + b x_j + u_c + e_j,   u_c ~ N(0, τ²) (one per cell),   e_j ~ N(0, σ_e² + s_j²),

σ_e the scatter of a cell about its own line beyond the measurement (and any
curvature of the trend). A cell's observations are jointly normal with
Σ_c = D_c + τ² 1 1ᵀ, D_c = diag(d_j), d_j = σ_e² + s_j², so with
S_c(u, v) = Σ_j u_j v_j / d_j (Sherman-Morrison, determinant lemma):

    uᵀ Σ_c⁻¹ v   = S_c(u, v) - τ² S_c(u, 1) S_c(v, 1) / (1 + τ² S_c(1, 1)),
    ln det Σ_c   = Σ_j ln d_j + ln(1 + τ² S_c(1, 1)),
    ℓ            = -1/2 Σ_c [ln det Σ_c + rᵀ Σ_c⁻¹ r],   r = y - a - b x.

Given (τ, σ_e) the coefficients (a, b) are the generalised least squares ones,
(Xᵀ Σ⁻¹ X)⁻¹ Xᵀ Σ⁻¹ y, so the likelihood is maximised over (ln τ, ln σ_e) only
(`scipy.optimize.minimize`, Nelder-Mead: two parameters, no gradient needed). Cells measured at one frequency count:
they inform a and τ. The slope's 95 % interval is the profile-likelihood one:
the b with 2 (ℓ̂ - max_{a, τ, σ_e} ℓ(b)) ≤ χ²_1,0.95 (`scipy.optimize.brentq`).
The line at frequency f, η(f) = a + b log10 f, is the ln K̃_S of the population's
median cell, so ν(f) = (1 - e^η)/(1 + e^η) is its Poisson ratio; η's interval is
again the profile one (the intercept of the model with x centred at f), ν's its
image (ν falls as η rises: the ends swap).

Assumptions: ln K̃_S linear in log10 f on average, a cell's offset u_c the same at
every frequency, errors normal and independent between observations. A measurement
error shared by a cell's frequencies (its height offset, its volume) is part of
u_c for the slope; it makes the slope's interval conservative, not biased.
"""

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
from scipy import optimize

from analysis.afm.population.random_effects import CHI2
from solver.elasticity import poisson_of_ratio

LOG_SD_BOUNDS = (np.log(1e-4), np.log(20.0))       # ln τ and ln σ_e searched in this range


@dataclass(frozen=True)
class Observations:
    """One row per cell and frequency: cell index (0..n-1), x = log10 f, y = ln K̃_S, s² (measurement)."""

    cell: np.ndarray
    x: np.ndarray
    y: np.ndarray
    s2: np.ndarray

    @classmethod
    def of(cls, cell_ids: npt.ArrayLike, freq_hz: npt.ArrayLike, ln_ks: npt.ArrayLike, s: npt.ArrayLike
           ) -> "Observations":
        """From columns; rows with a non-finite value are left out."""
        x, y, s = np.log10(np.asarray(freq_hz, float)), np.asarray(ln_ks, float), np.asarray(s, float)
        keep = np.isfinite(x) & np.isfinite(y) & np.isfinite(s)
        cells = np.unique(np.asarray(cell_ids)[keep], return_inverse=True)[1]
        return cls(cells.astype(int), x[keep], y[keep], s[keep] ** 2)

    def shifted(self, x0: float) -> "Observations":
        return Observations(self.cell, self.x - x0, self.y, self.s2)


def _gls(obs: Any, theta: Any, fixed: Any = None) -> tuple[Any, Any, Any]:
    """(ℓ, β, cov β) at θ = (ln τ, ln σ_e); `fixed` = (k, value) holds β_k at value.
    With z = (1, x, y) per observation, M_c = Σ_j z zᵀ / d_j and m_c its first column,
    Σ_c (zᵀ Σ_c⁻¹ z) = Σ_c [M_c - τ² m_c m_cᵀ / (1 + τ² M_c,11)]: six bincounts give it all."""
    tau2, d = np.exp(2 * theta[0]), np.exp(2 * theta[1]) + obs.s2
    y = obs.y if fixed is None else obs.y - fixed[1] * (obs.x if fixed[0] == 1 else 1.0)
    z = np.stack([np.ones_like(obs.x), obs.x, y])
    n = int(obs.cell.max()) + 1
    M = np.empty((n, 3, 3))
    for i in range(3):
        for j in range(i, 3):
            M[:, i, j] = M[:, j, i] = np.bincount(obs.cell, weights=z[i] * z[j] / d, minlength=n)
    m = M[:, :, 0]
    Q = np.sum(M - tau2 * m[:, :, None] * m[:, None, :] / (1.0 + tau2 * M[:, 0, 0])[:, None, None], axis=0)
    cols = [0, 1] if fixed is None else [1 - fixed[0]]
    A, rhs = Q[np.ix_(cols, cols)], Q[cols, 2]
    beta = np.linalg.solve(A, rhs)
    logdet = float(np.sum(np.log(d)) + np.sum(np.log1p(tau2 * M[:, 0, 0])))
    ll = -0.5 * (logdet + float(Q[2, 2] - rhs @ beta))
    if fixed is not None:
        beta = np.insert(beta, fixed[0], fixed[1])
    return ll, beta, np.linalg.inv(A)


def _maximise(obs: Any, fixed: Any = None, start: Any = None) -> tuple[float, Any]:
    """max over θ of ℓ (with β_k held if `fixed`), from `start` or from two starts (σ_e may sit
    at its bound): (ℓ, θ)."""
    starts = [start] if start is not None else [(np.log(0.5), np.log(0.2)), (np.log(0.5), np.log(0.02))]
    best: Any = None
    for s in starts:
        r = optimize.minimize(lambda t: -_gls(obs, t, fixed)[0], np.asarray(s, float), method="Nelder-Mead",
                              bounds=[LOG_SD_BOUNDS] * 2, options={"xatol": 1e-4, "fatol": 1e-7})
        if best is None or r.fun < best.fun:
            best = r
    return -float(best.fun), best.x


def _profile_interval(obs: Any, k: int, ll_hat: float, theta: Any, centre: float, se: float
                      ) -> tuple[float, float]:
    """The β_k with 2 (ℓ̂ - max ℓ | β_k) ≤ χ²: brentq on each side, bracketed by steps of 2 Wald SEs."""
    dev = lambda v: 2.0 * (ll_hat - _maximise(obs, (k, v), theta)[0]) - CHI2   # noqa: E731
    ends = []
    for sign in (-1.0, 1.0):
        step, far = 2.0 * se, centre
        for _ in range(20):
            far = centre + sign * step
            if dev(far) > 0:
                break
            step *= 2.0
        ends.append(optimize.brentq(dev, *sorted((centre, far)), xtol=1e-6))
    return float(ends[0]), float(ends[1])


@dataclass(frozen=True)
class Trend:
    """The fit: a, b (per decade) with b's 95 % interval, τ, σ_e, and per frequency
    (Hz) η = ln K̃_S of the median cell with its interval and the ν it implies."""

    intercept: float
    slope: float
    slope_lo: float
    slope_hi: float
    cell_sd: float
    residual_sd: float
    n_cells: int
    n_observations: int
    at: dict

    def to_dict(self) -> dict:
        return {"slope_ln_ks_per_decade": self.slope, "slope_lo95": self.slope_lo, "slope_hi95": self.slope_hi,
                "intercept_ln_ks_at_1Hz": self.intercept, "cell_sd_ln_ks": self.cell_sd,
                "residual_sd_ln_ks": self.residual_sd, "n_cells": self.n_cells,
                "n_observations": self.n_observations,
                "frequencies": [{"frequency_hz": f, **v} for f, v in self.at.items()]}


def fit(obs: Observations, frequencies_hz: Iterable[float] = ()) -> Trend | None:
    """The mixed model of `obs`; the line's ln K̃_S and ν with 95 % intervals at `frequencies_hz`.
    None with fewer than two distinct frequencies or three observations."""
    if np.unique(obs.x).size < 2 or obs.y.size < 3:
        return None
    ll, theta = _maximise(obs)
    _, beta, cov = _gls(obs, theta)
    lo, hi = _profile_interval(obs, 1, ll, theta, beta[1], float(np.sqrt(cov[1, 1])))
    at = {}
    for f in frequencies_hz:
        o = obs.shifted(np.log10(f))
        _, b0, c0 = _gls(o, theta)
        e_lo, e_hi = _profile_interval(o, 0, ll, theta, b0[0], float(np.sqrt(c0[0, 0])))
        at[float(f)] = {"ln_ks": float(b0[0]), "ln_ks_lo95": e_lo, "ln_ks_hi95": e_hi,
                        "nu": float(poisson_of_ratio(np.exp(b0[0]))), "nu_lo95": float(poisson_of_ratio(np.exp(e_hi))),
                        "nu_hi95": float(poisson_of_ratio(np.exp(e_lo)))}
    return Trend(float(beta[0]), float(beta[1]), lo, hi, float(np.exp(theta[0])), float(np.exp(theta[1])),
                 int(obs.cell.max() + 1), int(obs.y.size), at)


def pseudo_true_slope(populations: dict[float, tuple[float, float]],
                      design: Iterable[tuple[tuple[float, ...], int]]) -> float:
    """The slope b the model converges to (maximum expected ℓ) for cells whose true
    ln K̃_S(f) = μ_f + σ_f z, z ~ N(0, 1) one per cell, measured without error:
    `populations` {f (Hz): (μ_f, σ_f)}, `design` [(frequencies, number of cells), ...].
    For a cell measured at x_F (mean μ_F, covariance σ_F σ_Fᵀ) and the model's
    Σ = σ_e² I + τ² 1 1ᵀ:  E ℓ_F = -1/2 [ln det Σ + tr(Σ⁻¹ σ_F σ_Fᵀ) + (μ_F - X β)ᵀ Σ⁻¹ (μ_F - X β)],
    summed over the design; β by generalised least squares, (τ, σ_e) by Nelder-Mead.
    When μ_f is not linear in log10 f this is the slope the fit estimates: the paired
    cells' within-cell slopes weigh most, so it depends on which frequencies the
    cells share (0.379 per decade for the published design and populations)."""
    groups = []
    for freqs, n in design:
        x = np.log10(np.asarray(freqs, float))
        mu = np.array([populations[f][0] for f in freqs])
        sd = np.array([populations[f][1] for f in freqs])
        groups.append((n, np.column_stack([np.ones_like(x), x]), mu, np.outer(sd, sd)))

    def expected(theta: Any, beta_only: bool = False) -> Any:
        tau2, e2 = np.exp(2 * theta[0]), np.exp(2 * theta[1])
        inv = [(n, X, mu, C, np.linalg.inv(e2 * np.eye(len(mu)) + tau2)) for n, X, mu, C in groups]
        beta = np.linalg.solve(sum(n * X.T @ S @ X for n, X, _, _, S in inv),
                               sum(n * X.T @ S @ mu for n, X, mu, _, S in inv))
        if beta_only:
            return beta
        return -0.5 * sum(n * (-np.linalg.slogdet(S)[1] + np.trace(S @ C) + (mu - X @ beta) @ S @ (mu - X @ beta))
                          for n, X, mu, C, S in inv)

    r = optimize.minimize(lambda t: -expected(t), np.array([np.log(0.8), np.log(0.1)]), method="Nelder-Mead",
                          bounds=[LOG_SD_BOUNDS] * 2, options={"xatol": 1e-8, "fatol": 1e-12})
    return float(expected(r.x, beta_only=True)[1])
