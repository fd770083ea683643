"""Figures of the population answer (`analysis.afm.population.answer`):

- `nu_paired.png`: every cell included at two or more frequencies, its ν with the
  95 % interval per frequency, joined across frequencies (a spaghetti plot);
- `nu_deconvolved.png`: per frequency the histogram of ν, the ν density induced by
  the raw lognormal fit of K̃_S and by the deconvolved population N(μ, τ²) of ln K̃_S;
- `nu_trend.png`: the trend's ν(f) of the population's median cell with its 95 %
  band, beside the deconvolved medians per frequency with their intervals.
"""

from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from analysis.afm.population.figures import _save
from analysis.afm.population.summary import lognormal_fit, nu_density
from solver.elasticity import poisson_of_ratio

if TYPE_CHECKING:
    import pandas as pd

    from outputs.ownership import OutputDir

POPULATION_FIGURES = ("nu_paired.png", "nu_deconvolved.png", "nu_trend.png")


def _pyplot() -> Any:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def paired(table: "pd.DataFrame", out: "OutputDir") -> Path:
    plt = _pyplot()
    ok = table[table["excluded_reason"].isna()]
    fig, ax = plt.subplots(figsize=(5, 3.8))
    for _, g in ok.groupby("cell_id"):
        if len(g) < 2:
            continue
        g = g.sort_values("frequency_hz")
        line, = ax.plot(g["frequency_hz"], g["nu"], lw=0.6, alpha=0.6, marker="o", ms=2)
        if "nu_lo95" in g:
            ax.vlines(g["frequency_hz"], g["nu_lo95"], g["nu_hi95"], color=line.get_color(), lw=0.4, alpha=0.4)
    ax.set_xscale("log")
    ax.set_xlabel("frequency f (Hz)")
    ax.set_ylabel("Poisson ratio nu with 95 % interval (1)")
    ax.set_title("cells measured at two or more frequencies", fontsize=8)
    return _save(fig, out, "nu_paired.png")


def deconvolved(table: "pd.DataFrame", doc: dict, out: "OutputDir") -> Path:
    plt = _pyplot()
    ok = table[table["excluded_reason"].isna()]
    rows = doc["frequencies"]
    fig, axes = plt.subplots(1, max(len(rows), 1), figsize=(3 * max(len(rows), 1), 2.8), squeeze=False)
    grid = np.linspace(-0.99, 0.99, 400)
    for ax, r in zip(axes[0], rows):
        g = ok[ok["frequency_hz"] == r["frequency_hz"]]
        ax.hist(g["nu"], bins=np.linspace(-1, 1, 21), density=True, alpha=0.5, color="grey")
        mu, sigma = lognormal_fit(g["ks_tilde"])
        if np.isfinite(mu):
            ax.plot(grid, nu_density(grid, mu, sigma), label="raw lognormal fit")
        if r["mean_ln_ks"] is not None and np.isfinite(r["mean_ln_ks"]) and r["between_cell_sd_ln_ks"] > 0:
            ax.plot(grid, nu_density(grid, r["mean_ln_ks"], r["between_cell_sd_ln_ks"]), label="deconvolved")
        ax.set_title(f"{r['frequency_hz']:g} Hz, {r['n_cells']} cells", fontsize=8)
        ax.set_xlabel("Poisson ratio nu (1)")
        ax.set_ylabel("density (1)")
    labelled = [ax for ax in axes[0] if ax.get_legend_handles_labels()[0]]
    if labelled:
        labelled[0].legend(fontsize=6)
    return _save(fig, out, "nu_deconvolved.png")


def trend_band(doc: dict, out: "OutputDir") -> Path:
    plt = _pyplot()
    t = doc["trend"]
    fig, ax = plt.subplots(figsize=(5, 3.5))
    band = t["band"]
    f = np.array([b["frequency_hz"] for b in band])
    ax.fill_between(f, [b["nu_lo95"] for b in band], [b["nu_hi95"] for b in band], alpha=0.3,
                    label="trend, 95 % band")
    ax.plot(f, [b["nu"] for b in band], label=f"trend: {t['slope_ln_ks_per_decade']:+.2f} ln K_S~ per decade")
    rows = [r for r in doc["frequencies"] if r["mean_ln_ks"] is not None and np.isfinite(r["mean_ln_ks"])]
    fr = np.array([r["frequency_hz"] for r in rows])
    med = poisson_of_ratio(np.exp([r["mean_ln_ks"] for r in rows]))
    lo = poisson_of_ratio(np.exp([r["mean_ln_ks_hi95"] for r in rows]))
    hi = poisson_of_ratio(np.exp([r["mean_ln_ks_lo95"] for r in rows]))
    ax.errorbar(fr, med, yerr=[med - lo, hi - med], fmt="o", ms=3, capsize=2, label="per frequency (deconvolved)")
    ax.set_xscale("log")
    ax.set_xlabel("frequency f (Hz)")
    ax.set_ylabel("nu of the median cell (1)")
    ax.legend(fontsize=6)
    return _save(fig, out, "nu_trend.png")


def population_figures(table: "pd.DataFrame", doc: dict, out: "OutputDir") -> list[Path]:
    """The three figures into the `OutputDir` out (the trend's only with a trend); their paths."""
    paths = [paired(table, out), deconvolved(table, doc, out)]
    if doc.get("trend"):
        paths.append(trend_band(doc, out))
    return paths
