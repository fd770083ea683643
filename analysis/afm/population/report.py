"""The population answer's part of report.md (`analysis.afm.analyze_report`): the trend's
sentence first, then the deconvolved populations, the paired and Friedman tests."""

from typing import Any

import numpy as np


def _f(x: float | None, fmt: str = ".3f") -> str:
    return "–" if x is None or not np.isfinite(x) else format(x, fmt)


def _ci(lo: float | None, hi: float | None, fmt: str = ".3f") -> str:
    return f"[{_f(lo, fmt)}, {_f(hi, fmt)}]"


def trend_sentence(t: dict, design_weighted: dict | None = None) -> str:
    """"ln K̃_S changes by b [lo, hi] per decade ...; ν of the median cell ..." from population.json's
    trend, with the design-weighted slope beside it when given."""
    at = ", ".join(f"{r['nu']:.2f} {_ci(r['nu_lo95'], r['nu_hi95'], '.2f')} at {r['frequency_hz']:g} Hz"
                   for r in t["frequencies"])
    beside = "" if not design_weighted else (
        f" Design-weighted slope (mixed model over {design_weighted['n_cells']} cells, "
        f"{design_weighted['n_observations']} cell-frequency results; its weights follow how many cells were "
        f"measured at each frequency): {design_weighted['slope_ln_ks_per_decade']:+.3f} "
        f"{_ci(design_weighted['slope_lo95'], design_weighted['slope_hi95'])}.")
    return (f"**Trend:** ln K̃_S changes by {t['slope_ln_ks_per_decade']:+.3f} "
            f"{_ci(t['slope_lo95'], t['slope_hi95'])} per decade of frequency (95 % interval; least-squares line "
            f"through the population means of ln K̃_S at {t['n_frequencies']} frequencies, each weighted alike; "
            f"{t['n_cells']} cells); ν of the population's median cell: {at}.{beside}")


def _populations(rows: list[dict[str, Any]], from_intervals: bool) -> list[str]:
    lines = ["| f (Hz) | cells | mean ln K̃_S [95 %] | between-cell SD [95 %] | raw SD | measurement SD | "
             "measurement share [95 %] | raw median ν (IQR) | population median ν (IQR) |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        share = (f"{_f(r['measurement_share'])} {_ci(r['measurement_share_lo95'], r['measurement_share_hi95'])}"
                 if from_intervals else "–")
        lines.append(f"| {r['frequency_hz']:g} | {r['n_cells']} | {_f(r['mean_ln_ks'])} "
                     f"{_ci(r['mean_ln_ks_lo95'], r['mean_ln_ks_hi95'])} | {_f(r['between_cell_sd_ln_ks'])} "
                     f"{_ci(r['between_cell_sd_ln_ks_lo95'], r['between_cell_sd_ln_ks_hi95'])} | "
                     f"{_f(r['raw_sd_ln_ks'])} | {_f(r['measurement_sd_ln_ks'])} | {share} | "
                     f"{_f(r['raw_median_nu'])} ({_f(r['raw_iqr_nu'])}) | "
                     f"{_f(r['population_median_nu'])} ({_f(r['population_iqr_nu'])}) |")
    return lines


def _tests(doc: dict[str, Any], mann_whitney: Any) -> list[str]:
    lines = ["| pair | paired cells | Wilcoxon p (ν) | Wilcoxon p (ln K̃_S) | median Δν | Mann-Whitney p (unpaired) |",
             "|---|---|---|---|---|---|"]
    for k, r in doc["paired"].items():
        lines.append(f"| {k} | {r['n_cells']} | {_f(r['wilcoxon_p'], '.3g')} | {_f(r['wilcoxon_p_ln_ks'], '.3g')} | "
                     f"{_f(r['median_diff_nu'])} | {_f(mann_whitney.get(k), '.3g')} |")
    if not doc["friedman_frequencies_hz"]:
        return lines + ["", "No Friedman test: fewer than three frequencies."]
    freqs = ", ".join(f"{f:g}" for f in doc["friedman_frequencies_hz"])
    return lines + ["", f"Friedman test over the cells included at all of {freqs} Hz "
                        f"({doc['friedman_n_cells']} cells): p = {_f(doc['friedman_p'], '.3g')}."]


def markdown_population(doc: dict, mann_whitney: dict) -> list:
    """Lines of report.md: the trend sentence, then the population tables (population.json)."""
    lines = [trend_sentence(doc["trend"], doc.get("trend_design_weighted")), ""] if doc.get("trend") else []
    lines += ["## Population per frequency, measurement error taken out", "",
              "Random-effects model of ln K̃_S per frequency with each cell's own measurement SD (from its "
              "95 % interval): the mean with its t interval, the between-cell SD by REML with its profile-likelihood "
              "interval (docs/population.md). "
              "The measurement share is the part of the observed variance of ln K̃_S that measurement "
              "error alone explains.", ""]
    lines += _populations(doc["frequencies"], doc["measurement_from_intervals"])
    lines += ["", "## Paired comparisons", "", "Cells included at both frequencies of a pair (two-sided "
              "Wilcoxon signed-rank), beside the unpaired Mann-Whitney test on all included cells:", ""]
    return lines + _tests(doc, mann_whitney) + [""]
