"""Monte-Carlo error study (SPEC section 5): how much spread do volume and
height errors put into the recovered Poisson ratios?

Each trial is one simulated cell of true ν whose K(h̃) curve was computed
with an erroneous volume and erroneous heights. It is inverted exactly as a
measured cell (`analysis.invert.inversion.invert_curves`) with its bending variant's
calibration and γ_a = the mean over its heights of `tension_seen` (the active
tension an experimenter would infer at rest with the erroneous geometry).
Excluded cells (the filters of SPEC 6) are left out of the statistics and
counted.

Per (bending, true ν, height-error mode) and per study (one repetition of
N cells): the median and the interquartile range IQR = q75 - q25 of the
recovered ν of its included cells. Over the repetitions:

- `median`, `iqr`: the MEDIAN OVER STUDIES of the per-study median and IQR
  (what one experiment of N cells typically shows);
- `median_p05`, `median_p95`, `iqr_p05`, `iqr_p95`: the 5th and 95th
  percentiles of the per-study median and IQR over the studies (the sampling
  distribution of one experiment's numbers);
- `pooled_median`, `pooled_iqr`: over all included cells of all studies.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from analysis.calibration.law import Calibration
from analysis.invert.inversion import invert_curves, to_curves

KEYS = ["bending", "nu_true", "height_error_mode", "study", "cell", "trial_id"]
GROUP = ["bending", "nu_true", "height_error_mode"]


def invert_trials(trials: pd.DataFrame, calibration: Calibration) -> pd.DataFrame:
    """One row per trial: its keys, γ_a used, and the inversion's fields."""
    done = trials[trials["state"] == "done"] if "state" in trials else trials
    keys, arr = to_curves(done, KEYS, ("h_tilde", "modulus_mN_per_m", "tension_seen_mN_per_m"))
    with np.errstate(invalid="ignore"):
        tension = np.nanmean(arr["tension_seen_mN_per_m"], axis=1)
    parts = []
    for bending, idx in keys.groupby("bending").groups.items():
        idx = np.asarray(idx)
        inv = invert_curves(arr["h_tilde"][idx], arr["modulus_mN_per_m"][idx], tension[idx],
                            calibration, bending)
        part = keys.loc[idx].reset_index(drop=True).drop(columns="n_rows")
        part["tension_used_mN_per_m"] = tension[idx]
        parts.append(pd.concat([part, inv.rename(columns={"bulk_mN_per_m": "bulk_fit_mN_per_m"})], axis=1))
    return pd.concat(parts, ignore_index=True)


def _iqr(x: Any) -> float:
    q25, q75 = np.percentile(x, [25, 75])
    return q75 - q25


def per_study(cells: pd.DataFrame) -> pd.DataFrame:
    """Median, IQR and counts of recovered ν per study."""
    cells = cells.assign(included=cells["excluded_reason"].isna())
    rows = []
    for key, g in cells.groupby(GROUP + ["study"], sort=True):
        nu = g.loc[g["included"], "nu"].to_numpy()
        rows.append(dict(zip(GROUP + ["study"], key), n_cells=len(g), n_included=len(nu),
                         median=np.median(nu) if len(nu) else np.nan,
                         iqr=_iqr(nu) if len(nu) else np.nan))
    return pd.DataFrame(rows)


def summarise(cells: pd.DataFrame) -> tuple[list[dict[str, Any]], pd.DataFrame]:
    """The `montecarlo.json` records (see the module docstring), one per
    (bending, true ν, height-error mode), and the per-study table."""
    studies = per_study(cells)
    pooled = dict(list(cells.groupby(GROUP, sort=True)))
    nan = float("nan")
    out = []
    for key, g0 in studies.groupby(GROUP, sort=True):
        g = g0.dropna(subset=["median"])
        allcells = pooled[key]
        nu = allcells.loc[allcells["excluded_reason"].isna(), "nu"].to_numpy()
        pct = lambda col, q: float(np.percentile(g[col], q)) if len(g) else nan  # noqa: E731
        out.append({"bending": key[0], "nu_true": float(key[1]), "height_error_mode": key[2],
                    "n_cells": int(g0["n_cells"].max()), "n_studies": int(len(g0)),
                    "excluded_fraction": float(1.0 - len(nu) / len(allcells)),
                    "median": float(np.median(g["median"])) if len(g) else nan,
                    "iqr": float(np.median(g["iqr"])) if len(g) else nan,
                    "median_p05": pct("median", 5), "median_p95": pct("median", 95),
                    "iqr_p05": pct("iqr", 5), "iqr_p95": pct("iqr", 95),
                    "pooled_median": float(np.median(nu)) if len(nu) else nan,
                    "pooled_iqr": float(_iqr(nu)) if len(nu) else nan})
    return out, studies


def montecarlo(trials: pd.DataFrame, calibration: Calibration
               ) -> tuple[list[dict[str, Any]], pd.DataFrame, pd.DataFrame]:
    """Invert every trial and summarise: (records, per-study DataFrame, per-cell DataFrame)."""
    cells = invert_trials(trials, calibration)
    records, studies = summarise(cells)
    return records, studies, cells
