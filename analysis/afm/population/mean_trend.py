"""The frequency trend of ln K̃_S as the answer: the least-squares line through the
per-frequency population means, every frequency weighted alike.

Frequencies f_k, k = 1..K, x_k = log10(f_k / 1 Hz); at each the population mean
μ̂_k = ȳ_k, the plain mean of y = ln K̃_S over its n_k included cells (the μ of
`random_effects.fit`). The line's slope and its value at x are linear in μ̂,

    b = Σ_k w_k μ̂_k,   w_k = (x_k - x̄) / Σ_l (x_l - x̄)²,
    η(x) = Σ_k c_k(x) μ̂_k,   c_k(x) = 1/K + (x - x̄) w_k,

so their variances are wᵀ C w and cᵀ C c with C the covariance of the means. A cell
measured at f_k and f_l enters both means, so

    C_kl = n_kl σ̂_kl / (n_k n_l),

n_kl the cells measured at both, σ̂_kl the sample covariance (n_kl - 1) of their y
at f_k and f_l (pandas' pairwise `DataFrame.cov`; 0 with fewer than 2 shared
cells); C_kk = σ̂_k² / n_k, the t interval's variance of `random_effects`. The sample
covariances hold everything y varies by (cells, measurement, errors a cell shares
across its frequencies), so no error model enters. 95 % intervals b ± t_{n-1} √(wᵀ C w)
with n = min_k n_k (conservative for the frequencies with more cells), the same for
η(f), and ν's as η's image through ν = (1 - e^η)/(1 + e^η) (the ends swap).

Unlike the mixed model of `trend` (whose slope leans on the cells measured at
several frequencies, so depends on the design when μ_f is not linear in log10 f),
the estimand here is the least-squares line through the true μ_f, whatever the
number of cells at each frequency. Frequencies with fewer than 2 cells are left out.
"""

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import pandas as pd
from scipy import stats

from analysis.afm.population.random_effects import LEVEL
from solver.elasticity import poisson_of_ratio


@dataclass(frozen=True)
class MeanTrend:
    """Slope b (ln K̃_S per decade) with its 95 % interval, intercept at 1 Hz, and per
    frequency (Hz) the line's η = ln K̃_S of the median cell and ν with 95 % intervals."""

    intercept: float
    slope: float
    slope_lo: float
    slope_hi: float
    n_cells: int
    n_frequencies: int
    at: dict

    def to_dict(self) -> dict:
        return {"slope_ln_ks_per_decade": self.slope, "slope_lo95": self.slope_lo, "slope_hi95": self.slope_hi,
                "intercept_ln_ks_at_1Hz": self.intercept, "n_cells": self.n_cells,
                "n_frequencies": self.n_frequencies,
                "frequencies": [{"frequency_hz": f, **v} for f, v in self.at.items()]}


def means_and_covariance(cell_ids: npt.ArrayLike, freq_hz: npt.ArrayLike, ln_ks: npt.ArrayLike
                         ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64],
                                    npt.NDArray[np.int64], int]:
    """(frequencies (Hz), means μ̂_k, their covariance C, cells n_k, cells in all) of the module doc."""
    df = pd.DataFrame({"cell": np.asarray(cell_ids), "f": np.asarray(freq_hz, float), "y": np.asarray(ln_ks, float)})
    df = df[np.isfinite(df["f"]) & np.isfinite(df["y"])]
    wide = df.pivot_table(index="cell", columns="f", values="y", aggfunc="mean")
    wide = wide.loc[:, wide.count() >= 2]
    wide = wide[wide.notna().any(axis=1)]
    seen = wide.notna().to_numpy(float)
    n = seen.sum(axis=0)
    cov = np.nan_to_num(wide.cov(min_periods=2).to_numpy()) * (seen.T @ seen) / np.outer(n, n)
    return wide.columns.to_numpy(float), wide.mean().to_numpy(), cov, n.astype(int), int(len(wide))


def _interval(c: np.ndarray, means: np.ndarray, cov: np.ndarray, t: float) -> tuple[float, float, float]:
    """c·μ̂ and its t interval."""
    centre, sd = float(c @ means), float(np.sqrt(max(float(c @ cov @ c), 0.0)))
    return centre, centre - t * sd, centre + t * sd


def fit(cell_ids: npt.ArrayLike, freq_hz: npt.ArrayLike, ln_ks: npt.ArrayLike,
        frequencies_hz: Iterable[float] = ()) -> MeanTrend | None:
    """The line through the per-frequency means of ln K̃_S (one row per cell and frequency);
    its ln K̃_S and ν with 95 % intervals at `frequencies_hz`. None with fewer than two
    frequencies of at least 2 cells."""
    freqs, means, cov, n, n_cells = means_and_covariance(cell_ids, freq_hz, ln_ks)
    if freqs.size < 2:
        return None
    x = np.log10(freqs)
    w = (x - x.mean()) / np.sum((x - x.mean()) ** 2)
    t = float(stats.t.ppf(0.5 + LEVEL / 2, int(n.min()) - 1))
    slope, lo, hi = _interval(w, means, cov, t)
    at = {}
    for f in frequencies_hz:
        eta, e_lo, e_hi = _interval(1.0 / x.size + (np.log10(f) - x.mean()) * w, means, cov, t)
        at[float(f)] = {"ln_ks": eta, "ln_ks_lo95": e_lo, "ln_ks_hi95": e_hi,
                        "nu": float(poisson_of_ratio(np.exp(eta))), "nu_lo95": float(poisson_of_ratio(np.exp(e_hi))),
                        "nu_hi95": float(poisson_of_ratio(np.exp(e_lo)))}
    intercept = float((1.0 / x.size - x.mean() * w) @ means)
    return MeanTrend(intercept, slope, lo, hi, n_cells, int(freqs.size), at)
