"""report.md of `cortex afm analyze` (`analysis.afm.analyze_pipeline`), as text.

Sections: the method and variant, the population answer (the trend's sentence
first, the deconvolved populations, the paired tests: `analysis.afm.population.report`),
for a table with intervals (the emulator's) the median ν per frequency with its
bootstrap 95 % interval, the population table of every
variant (median and IQR of ν, the lognormal fit of K̃_S), the Mann-Whitney
p-values, the count of results outside the calibration grid, the excluded
cells, the figures; and the recordings not analysed (`markdown_skipped`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from analysis.afm.analyze import has_intervals

def markdown_skipped(name: str | None, skipped: dict[str, str]) -> str:
    lines = [f"# Measured cells: {name}", "", "No recording could be analysed."] if name else []
    if skipped:
        lines += ["", "## Recordings not analysed", "", "| cell | reason |", "|---|---|"]
        lines += [f"| {c} | {r} |" for c, r in skipped.items()]
    return "\n".join(lines) + "\n" if lines else ""


def _fmt3(x: float | None) -> str:
    return "–" if x is None or not np.isfinite(x) else f"{x:.3f}"


def _populations(sums: dict[str, dict[str, Any]]) -> list[str]:
    lines = ["| variant | f (Hz) | cells | excluded | median ν | IQR ν | lognormal μ | lognormal σ |",
             "|---|---|---|---|---|---|---|---|"]
    for v, s in sums.items():
        for r in s["frequencies"]:
            lines.append(f"| {v} | {r['frequency_hz']:g} | {r['n_cells']} | {r['n_excluded']} | "
                         f"{_fmt3(r['median_nu'])} | {_fmt3(r['iqr_nu'])} | {_fmt3(r['lognormal_mu'])} | "
                         f"{_fmt3(r['lognormal_sigma'])} |")
    return lines


def _outside(tab: pd.DataFrame) -> list[str]:
    ok = tab[tab["excluded_reason"].isna()]
    if not ok["outside_calibration"].notna().any():
        return []
    return ["", f"{int((ok['outside_calibration'] == True).sum())} of {len(ok)} included results "  # noqa: E712
            "have K̃_S or γ̃_a outside the calibration grid (ν from the log law's extrapolation; "
            "`outside_calibration` in cells.csv)."]


def _intervals(bending: str, summary: dict[str, Any]) -> list[str]:
    """The median ν per frequency with its interval, and what a cell's interval includes."""
    lines = [f"Median ν per frequency with its bootstrap 95 % interval (variant `{bending}`):", "",
             "| f (Hz) | cells | median ν | 95 % interval | cells with ν > 0.5 |", "|---|---|---|---|---|"]
    for r in summary["frequencies"]:
        lo, hi = r.get("median_nu_lo95"), r.get("median_nu_hi95")
        ci = f"[{lo:.3f}, {hi:.3f}]" if lo is not None and np.isfinite(lo) else "–"
        med = f"{r['median_nu']:.3f}" if r["median_nu"] is not None else "–"
        lines.append(f"| {r['frequency_hz']:g} | {r['n_cells']} | {med} | {ci} | "
                     f"{r.get('n_nu_beyond_isotropic', 0)} |")
    return lines + ["", "Each cell's 95 % interval (`nu_lo95`, `nu_hi95` in cells.csv) includes the volume "
                    "and height errors and the fit's residuals (parametric bootstrap through the emulator).", ""]


def markdown(name: str, bending: str, method: str, tables: dict[str, pd.DataFrame],
             sums: dict[str, dict[str, Any]], figs: list[Path], population: dict[str, Any] | None = None) -> str:
    """The report of the cells analysed by the inversion `method` names: `tables` and `sums` per variant, `figs` the
    figures' paths, `population` the selected variant's population.json."""
    tab = tables[bending]
    lines = [f"# Measured cells: {name}", "",
             f"Method: `{method}`. Calibration variant: `{bending}`. "
             f"{tab['cell_id'].nunique()} cells.", ""]
    if population is not None:
        from analysis.afm.population.report import markdown_population
        lines += markdown_population(population, sums[bending]["mann_whitney_p"])
    if has_intervals(tab):
        lines += _intervals(bending, sums[bending])
    lines += _populations(sums)
    lines += ["", "Two-sided Mann-Whitney p-values (variant `%s`):" % bending, ""]
    lines += [f"- {k}: {p:.3g}" for k, p in sums[bending]["mann_whitney_p"].items()]
    lines += _outside(tab)
    lines += ["", "## Excluded cells", "", "| cell | f (Hz) | reason |", "|---|---|---|"]
    ex = tab[tab["excluded_reason"].notna()]
    lines += [f"| {r.cell_id} | {r.frequency_hz:g} | {r.excluded_reason} |" for r in ex.itertuples()]
    lines += ["", "## Figures", ""] + [f"![{p.stem}]({p.name})" for p in figs]
    return "\n".join(lines) + "\n"
