"""Paired comparisons between frequencies, on the cells measured at both.

Per pair of frequencies (f1 < f2), the cells included at both: the two-sided
Wilcoxon signed-rank test (`scipy.stats.wilcoxon`) of the differences ν(f2) - ν(f1)
and, separately, of ln K̃_S(f2) - ln K̃_S(f1) (ν is a decreasing function of K̃_S,
so the signs agree but the ranks of the differences need not), with the median
difference of ν. A cell is its own control: what makes one cell stiffer than
another at every frequency (and a measurement error a cell carries to all its
frequencies, its height offset, its volume) cancels in the difference, which the
unpaired Mann-Whitney test (`analysis.afm.population.summary.summary`) cannot do.

Cells at three or more frequencies: the Friedman test (`scipy.stats.friedmanchisquare`,
ranks within each cell; the same for ν and ln K̃_S) on the set of ≥ 3 frequencies
with the most cells included at all of them (on a tie, the larger set).
"""

import itertools
from typing import Any

import numpy as np
import pandas as pd
from scipy import stats


def _wide(table: pd.DataFrame, column: str) -> pd.DataFrame:
    """Included rows as one row per cell, one column per frequency (NaN: not measured or excluded)."""
    ok = table[table["excluded_reason"].isna()]
    return ok.pivot_table(index="cell_id", columns="frequency_hz", values=column, aggfunc="first")


def _wilcoxon(d: np.ndarray) -> float | None:
    d = d[np.isfinite(d)]
    if d.size < 2 or not np.any(d != 0):
        return None
    return float(stats.wilcoxon(d, alternative="two-sided").pvalue)


def pair_key(a: float, b: float) -> str:
    return f"{a:g}Hz_vs_{b:g}Hz"


def paired_tests(table: pd.DataFrame) -> dict:
    """{"paired": {pair: {n_cells, wilcoxon_p, wilcoxon_p_ln_ks, median_diff_nu}}, "friedman_p",
    "friedman_n_cells", "friedman_frequencies_hz"} of a cells table (`analysis.afm.analyze`)."""
    nu, lks = _wide(table, "nu"), np.log(_wide(table, "ks_tilde"))
    out: dict[str, Any] = {"paired": {}}
    for a, b in itertools.combinations(sorted(nu.columns), 2):
        both = nu[[a, b]].dropna().index.intersection(lks[[a, b]].dropna().index)
        d_nu = (nu.loc[both, b] - nu.loc[both, a]).to_numpy(float)
        d_lks = (lks.loc[both, b] - lks.loc[both, a]).to_numpy(float)
        out["paired"][pair_key(a, b)] = {
            "n_cells": int(both.size), "wilcoxon_p": _wilcoxon(d_nu), "wilcoxon_p_ln_ks": _wilcoxon(d_lks),
            "median_diff_nu": float(np.median(d_nu)) if d_nu.size else None}
    out.update(friedman(nu))
    return out


def friedman(wide: pd.DataFrame) -> dict:
    """The Friedman test of `wide` (cells x frequencies) on the best set of ≥ 3 frequencies."""
    best: tuple[int, tuple[float, ...]] = (0, ())
    for k in range(3, wide.shape[1] + 1):
        for cols in itertools.combinations(sorted(wide.columns), k):
            n = int(wide[list(cols)].dropna().shape[0])
            if (n, len(cols)) > (best[0], len(best[1])):
                best = (n, cols)
    n, cols = best
    p = None
    if n >= 2:
        complete = wide[list(cols)].dropna()
        p = float(stats.friedmanchisquare(*[complete[c].to_numpy(float) for c in cols]).pvalue)
    return {"friedman_p": p, "friedman_n_cells": n, "friedman_frequencies_hz": [float(c) for c in cols]}
