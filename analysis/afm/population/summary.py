"""Population statistics per frequency (SPEC 6).

ML lognormal fit of K̃_S (scipy.stats.lognorm.fit with loc = 0: μ = ln scale,
σ = shape); the induced ν density p_ν(ν) = p_K(K̃) |dK̃/dν| with
K̃ = (1 - ν)/(1 + ν), |dK̃/dν| = 2/(1 + ν)² (`solver.elasticity`); median and IQR of ν of the
included cells; two-sided Mann-Whitney U between every pair of frequencies.
"""

import itertools
from typing import Any

import numpy as np
import numpy.typing as npt
import pandas as pd
from scipy import stats

from solver.elasticity import shear_ratio, shear_ratio_slope


def lognormal_fit(ks: npt.NDArray[np.float64]) -> tuple[float, float]:
    ks = np.asarray(ks, float)
    ks = ks[np.isfinite(ks) & (ks > 0)]
    if ks.size < 2:
        return float("nan"), float("nan")
    sigma, _, scale = stats.lognorm.fit(ks, floc=0)
    return float(np.log(scale)), float(sigma)


def nu_density(nu: npt.ArrayLike, mu: float, sigma: float) -> np.ndarray:
    """Density of ν = (1 - K̃)/(1 + K̃) for K̃ ~ lognormal(μ, σ)."""
    nu = np.asarray(nu, float)
    return stats.lognorm.pdf(shear_ratio(nu), sigma, scale=np.exp(mu)) * shear_ratio_slope(nu)


def summary(table: pd.DataFrame) -> dict[str, Any]:
    """`table`: rows of `analyze`. Returns the summary dict of summary.json."""
    out: dict[str, Any] = {"frequencies": [], "mann_whitney_p": {}}
    ok = table[table["excluded_reason"].isna()]
    for f, g in table.groupby("frequency_hz", sort=True):
        good = ok[ok["frequency_hz"] == f]
        mu, sigma = lognormal_fit(good["ks_tilde"])
        nu = good["nu"].to_numpy(float)
        q1, q3 = np.percentile(nu, [25, 75]) if nu.size else (np.nan, np.nan)
        out["frequencies"].append({"frequency_hz": float(f), "n_cells": int(len(good)),
                                   "n_excluded": int(len(g) - len(good)),
                                   "median_nu": float(np.median(nu)) if nu.size else None,
                                   "iqr_nu": float(q3 - q1) if nu.size else None,
                                   "lognormal_mu": mu, "lognormal_sigma": sigma})
    for a, b in itertools.combinations(sorted(ok["frequency_hz"].unique()), 2):
        x, y = ok.loc[ok["frequency_hz"] == a, "nu"], ok.loc[ok["frequency_hz"] == b, "nu"]
        if len(x) and len(y):
            out["mann_whitney_p"][f"{a:g}Hz_vs_{b:g}Hz"] = float(stats.mannwhitneyu(x, y, alternative="two-sided").pvalue)
    return out
