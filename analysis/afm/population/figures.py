"""Figures of the measured cells: ν histograms with the fitted lognormal's
induced density, box plots of ν per frequency and variant, normalised K(h̃)
curves K/K_B of every included cell."""

from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from analysis.afm.population.summary import nu_density

if TYPE_CHECKING:
    import pandas as pd

    from outputs.ownership import OutputDir


FIGURES = ("nu_histograms.png", "nu_boxplots.png", "k_curves.png")


def _save(fig: Any, out: "OutputDir", name: str) -> Path:
    """Lay out, write (PNG, 80 dpi) as file `name` of the output folder `out`
    (an `outputs.ownership.OutputDir`) and close a figure; returns its path."""
    import matplotlib.pyplot as plt
    fig.tight_layout()
    with out.writing(name) as path:
        fig.savefig(path, dpi=80)
    plt.close(fig)
    return path


def figures(tables: dict[str, "pd.DataFrame"], sums: dict[str, dict[str, Any]], segs: "pd.DataFrame",
            out: "OutputDir") -> list[Path]:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    paths = []
    variants = list(tables)
    freqs = sorted(tables[variants[0]]["frequency_hz"].unique())
    fig, axes = plt.subplots(len(variants), len(freqs), figsize=(3 * len(freqs), 2.5 * len(variants)),
                             squeeze=False)
    grid = np.linspace(-0.99, 0.99, 400)
    for i, v in enumerate(variants):
        ok = tables[v][tables[v]["excluded_reason"].isna()]
        for j, f in enumerate(freqs):
            ax = axes[i, j]
            nu = ok.loc[ok["frequency_hz"] == f, "nu"]
            ax.hist(nu, bins=np.linspace(-1, 1, 21), density=True, alpha=0.6)
            r = next(r for r in sums[v]["frequencies"] if r["frequency_hz"] == f)
            if np.isfinite(r["lognormal_mu"]):
                ax.plot(grid, nu_density(grid, r["lognormal_mu"], r["lognormal_sigma"]))
            ax.set_title(f"{v}, {f:g} Hz", fontsize=8)
            ax.set_xlabel("Poisson ratio nu (1)")
            ax.set_ylabel("density (1)")
    paths.append(_save(fig, out, "nu_histograms.png"))

    fig, ax = plt.subplots(figsize=(6, 3.5))
    data, labels = [], []
    for v in variants:
        ok = tables[v][tables[v]["excluded_reason"].isna()]
        for f in freqs:
            data.append(ok.loc[ok["frequency_hz"] == f, "nu"].to_numpy())
            labels.append(f"{v}\n{f:g} Hz")
    ax.boxplot(data, tick_labels=labels)
    ax.tick_params(labelsize=6)
    ax.set_ylabel("Poisson ratio nu (1)")
    paths.append(_save(fig, out, "nu_boxplots.png"))

    v = variants[0]
    ok = tables[v][tables[v]["excluded_reason"].isna()][["cell_id", "frequency_hz", "bulk_mN_per_m"]]
    curves = segs.merge(ok, on=["cell_id", "frequency_hz"])
    fig, ax = plt.subplots(figsize=(5, 3.5))
    for (c, f), g in curves.groupby(["cell_id", "frequency_hz"]):
        ax.plot(g["h_tilde"], g["modulus_mN_per_m"] / g["bulk_mN_per_m"], lw=0.5,
                color=f"C{freqs.index(f)}")
    ax.set_xlabel("normalised height h~ (1)")
    ax.set_ylabel("K / K_B (1)")
    paths.append(_save(fig, out, "k_curves.png"))
    return paths


def nu_intervals(table: "pd.DataFrame", out: "OutputDir") -> Path:
    """ν of every included cell with its 95 % interval, one panel per frequency,
    cells sorted by ν."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    ok = table[table["excluded_reason"].isna()]
    freqs = sorted(ok["frequency_hz"].unique())
    fig, axes = plt.subplots(1, max(len(freqs), 1), figsize=(3.2 * max(len(freqs), 1), 3.2), squeeze=False,
                             sharey=True)
    for ax, f in zip(axes[0], freqs):
        g = ok[ok["frequency_hz"] == f].sort_values("nu")
        x = np.arange(len(g))
        ax.vlines(x, g["nu_lo95"], g["nu_hi95"], lw=0.6)    # an interval need not hold its fit (emulator.md)
        ax.plot(x, g["nu"], "o", ms=2)
        ax.axhline(0.5, color="grey", lw=0.5, ls="--")
        ax.set_title(f"{f:g} Hz", fontsize=8)
        ax.set_xlabel("cell, sorted by nu (1)")
    axes[0, 0].set_ylabel("Poisson ratio nu with 95 % interval (1)")
    return _save(fig, out, "nu_intervals.png")
