"""Figures of the calibration and the Monte-Carlo study (matplotlib, Agg),
each written as PNG and PDF, the bending variants side by side (one column
each), units on every axis.

- `modulus_curves`: K vs h̃ per K_S at one γ_a, with the fitted laws
  K_B (1 + α exp(h̃/λ)) (step 2 α) drawn through them;
- `alpha_law`: α vs K̃_S per γ̃_a, with the lines C(γ̃_a) ln K̃_S + D(γ̃_a)
  of the cubic polynomials;
- `reconstruction`: ν recovered from each simulated curve vs the true ν;
- `equator_shear`: |e1 - e2| / (e1 + e2) at the equator vs h̃;
- `montecarlo_boxes`: recovered ν of one study per (true ν, height-error
  mode), and the per-study medians over all repetitions.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

if TYPE_CHECKING:
    from analysis.calibration.law import Calibration
    from outputs.ownership import OutputDir

ORDER = ("standard", "double", "none")
H_LABEL = "h~ = h / (2 R_cell)  [dimensionless]"


def _variants(names: Any) -> list[str]:
    names = list(dict.fromkeys(names))
    return [v for v in ORDER if v in names] + [v for v in names if v not in ORDER]


def _panels(n: int, width: float = 4.2, height: float = 3.4) -> tuple[Any, Any]:
    fig, axes = plt.subplots(1, n, figsize=(width * n, height), squeeze=False, constrained_layout=True)
    return fig, axes[0]


def _save(fig: Any, out: OutputDir, name: str) -> list[Path]:
    for ax in fig.axes:
        ax.title.set_fontsize(9)
        ax.xaxis.label.set_fontsize(8)
        ax.yaxis.label.set_fontsize(8)
    fig.canvas.draw()                 # lay out once (constrained), then freeze the layout
    fig.set_layout_engine("none")
    paths = []
    for ext in ("png", "pdf"):
        with out.writing(f"{name}.{ext}") as path:     # out: an outputs.ownership.OutputDir
            fig.savefig(path, dpi=110)
        paths.append(path)
    plt.close(fig)
    return paths


def _middle(values: Any) -> Any:
    values = sorted(set(values))
    return values[(len(values) - 1) // 2]


def modulus_curves(results: pd.DataFrame, calibration: Calibration, fits: pd.DataFrame, out: OutputDir) -> list[Path]:
    variants = _variants(results["bending"])
    fig, axes = _panels(len(variants))
    for ax, bending in zip(axes, variants):
        law = calibration[bending]
        df = results[results["bending"] == bending]
        tension = _middle(df["tension_mN_per_m"])
        df = df[df["tension_mN_per_m"] == tension]
        shears = sorted(df["shear_mN_per_m"].unique())
        colors = plt.cm.viridis(np.linspace(0, 0.9, len(shears)))
        grid = np.linspace(df["h_tilde"].min(), df["h_tilde"].max(), 100)
        for shear, color in zip(shears, colors):
            pts = df[df["shear_mN_per_m"] == shear]
            ax.plot(pts["h_tilde"], pts["modulus_mN_per_m"], "o", color=color, ms=4,
                    label=f"K_S = {shear:g}")
            row = fits[(fits["bending"] == bending) & (fits["shear_mN_per_m"] == shear)
                       & (fits["tension_mN_per_m"] == tension)]
            if len(row):
                r = row.iloc[0]
                ax.plot(grid, r["bulk_mN_per_m"] * (1 + r["alpha"] * np.exp(grid / law.lam)), "-", color=color)
        ax.set(title=f"{bending} bending, gamma_a = {tension:g} mN/m\nlines: fitted law, lambda = {law.lam:.4g}",
               xlabel=H_LABEL, ylabel="K  [mN/m]")
        ax.legend(fontsize=7, title="mN/m", title_fontsize=7)
    return _save(fig, out, "modulus_vs_height")


def alpha_law(calibration: Calibration, fits: pd.DataFrame, out: OutputDir) -> list[Path]:
    variants = _variants(fits["bending"])
    fig, axes = _panels(len(variants))
    for ax, bending in zip(axes, variants):
        law = calibration[bending]
        f = fits[fits["bending"] == bending]
        gammas = sorted(f["gamma_tilde"].unique())
        colors = plt.cm.plasma(np.linspace(0, 0.85, len(gammas)))
        ks = np.geomspace(f["ks_tilde"].min(), f["ks_tilde"].max(), 50)
        for g, color in zip(gammas, colors):
            pts = f[f["gamma_tilde"] == g]
            ax.plot(pts["ks_tilde"], pts["alpha"], "o", color=color, ms=4, label=f"{g:.3g}")
            ax.plot(ks, law.alpha_of(ks, g), "-", color=color, lw=1)
        ax.set_xscale("log")
        ax.set(title=f"{bending} bending\nlines: alpha = C(g) ln(K_S/K_B) + D(g), cubic C, D",
               xlabel="K_S / K_B  [dimensionless]", ylabel="alpha  [dimensionless]")
        ax.legend(fontsize=7, title="gamma_a / K_B", title_fontsize=7)
    return _save(fig, out, "alpha_vs_shear")


def reconstruction(recon: pd.DataFrame, out: OutputDir) -> list[Path]:
    variants = _variants(recon["bending"])
    fig, axes = _panels(len(variants), height=3.8)
    for ax, bending in zip(axes, variants):
        r = recon[recon["bending"] == bending]
        ok = r["excluded_reason"].isna()
        lim = [min(-0.05, r["nu_true"].min() - 0.05), max(0.6, r["nu_true"].max() + 0.05)]
        ax.plot(lim, lim, "k-", lw=0.8)
        sc = ax.scatter(r.loc[ok, "nu_true"], r.loc[ok, "nu"], c=r.loc[ok, "tension_mN_per_m"], s=14,
                        cmap="plasma")
        if (~ok).any():
            ax.plot(r.loc[~ok, "nu_true"], r.loc[~ok, "nu"], "x", color="grey", label="excluded")
            ax.legend(fontsize=7)
        fig.colorbar(sc, ax=ax, label="gamma_a  [mN/m]")
        err = r.loc[ok, "nu_error"].abs().max() if ok.any() else float("nan")
        ax.set(title=f"{bending} bending\nmax |nu error| = {err:.3g} (gamma_a known)", xlabel="true nu  [dimensionless]",
               ylabel="recovered nu  [dimensionless]")
    return _save(fig, out, "reconstruction")


def equator_shear(results: pd.DataFrame, out: OutputDir) -> list[Path]:
    variants = _variants(results["bending"])
    fig, axes = _panels(len(variants))
    for ax, bending in zip(axes, variants):
        df = results[results["bending"] == bending]
        tension = _middle(df["tension_mN_per_m"])
        df = df[df["tension_mN_per_m"] == tension].sort_values("h_tilde")
        shears = sorted(df["shear_mN_per_m"].unique())
        for shear, color in zip(shears, plt.cm.viridis(np.linspace(0, 0.9, len(shears)))):
            pts = df[df["shear_mN_per_m"] == shear]
            ax.plot(pts["h_tilde"], pts["equator_shear_ratio"], "o-", color=color, ms=3,
                    label=f"K_S = {shear:g}")
        ax.set(title=f"{bending} bending, gamma_a = {tension:g} mN/m\nequator shear-to-dilation ratio",
               xlabel=H_LABEL, ylabel="|e1 - e2| / (e1 + e2) at equator  [dimensionless]")
        ax.legend(fontsize=7, title="mN/m", title_fontsize=7)
    return _save(fig, out, "equator_shear_ratio")


def montecarlo_boxes(cells: pd.DataFrame, studies: pd.DataFrame, out: OutputDir) -> list[Path]:
    variants = _variants(cells["bending"])
    fig, axes = plt.subplots(2, len(variants), figsize=(6.0 * len(variants), 7.0), squeeze=False,
                             constrained_layout=True)
    for col, bending in enumerate(variants):
        c = cells[(cells["bending"] == bending) & cells["excluded_reason"].isna()]
        s = studies[studies["bending"] == bending].dropna(subset=["median"])
        keys = sorted(set(zip(c["nu_true"], c["height_error_mode"])))
        labels = [f"{nu:g}\n{mode}" for nu, mode in keys]
        first = c["study"].min()
        one = [c[(c["nu_true"] == nu) & (c["height_error_mode"] == m) & (c["study"] == first)]["nu"]
               for nu, m in keys]
        med = [s[(s["nu_true"] == nu) & (s["height_error_mode"] == m)]["median"] for nu, m in keys]
        for ax, data, what in ((axes[0, col], one, f"cells of study {first}"),
                               (axes[1, col], med, "per-study medians over repetitions")):
            ax.boxplot([np.asarray(d) for d in data], tick_labels=labels, showfliers=True)
            ax.plot(range(1, len(keys) + 1), [nu for nu, _ in keys], "r_", ms=20, mew=2, label="true nu")
            ax.set(title=f"{bending} bending: recovered nu\n{what}", xlabel="true nu  [dimensionless], height-error mode",
                   ylabel="recovered nu  [dimensionless]")
            ax.tick_params(axis="x", labelsize=7)
            ax.legend(fontsize=7)
    return _save(fig, out, "montecarlo")
