"""report.md of `cortex analysis calibrate` (`analysis.calibration.command.pipeline`), as text.

One function per section: the header (what was used and left out), the
calibration laws (SPEC 4) with the goodness of every fitting stage and the α
tables, the solver checks (volume error; droplet vs shell area increase, the
published check: within 6 %), the reconstruction check and the Monte-Carlo
study (SPEC 5), then the figures. Tables are Markdown; numbers go through
`_fmt` (4 significant digits unless told, '-' for missing or non-finite).
"""

from __future__ import annotations

import time
from importlib.metadata import version
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from analysis.calibration.command.figures import ORDER


def solver_checks(done: pd.DataFrame) -> list[dict[str, Any]]:
    """Per variant: the largest volume error and the droplet-vs-shell area-increase deviation."""
    rows = []
    for bending, g in done.groupby("bending", sort=False):
        row = {"bending": bending}
        if "volume_error" in g:
            row["max_volume_error"] = float(g["volume_error"].max())
        if "area_strain_shell" in g:
            with np.errstate(divide="ignore", invalid="ignore"):
                dev = (g["area_strain"] / g["area_strain_shell"] - 1.0).abs()
            row["max_area_deviation"] = float(dev.max())
        rows.append(row)
    return rows


def _fmt(x: Any, digits: int = 4) -> str:
    if x is None or (isinstance(x, float) and not np.isfinite(x)):
        return "-"
    return f"{x:.{digits}g}"


def _table(header: list[str], rows: Any) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


FAILED_SHOWN = 20      # failed compressions listed by name in the report; the rest counted


def _failed_tasks(failed: pd.DataFrame | None) -> list[str]:
    """The failed compressions, each with its parameters and message (`cortex campaign status` lists all)."""
    if failed is None or not len(failed):
        return []
    rows = [(t.task_id, f"{t.h0_um:g}", f"{t.shear_mN_per_m:g}", f"{t.tension_mN_per_m:g}", t.bending,
             str(t.error).replace("|", "/")) for t in failed.head(FAILED_SHOWN).itertuples()]
    more = len(failed) - len(rows)
    return [f"Failed compression tasks ({len(failed)}):", "",
            _table(["task_id", "h0_um", "shear_mN_per_m", "tension_mN_per_m", "bending", "error"], rows), ""] + \
        ([f"... and {more} more: `cortex campaign status STORE` lists them all.", ""] if more else [])


def _header(inputs: Any) -> list[str]:
    done = inputs.done
    L = [f"# Calibration and Monte-Carlo analysis of `{inputs.store}`", "",
         f"cortex {version('cortex-poisson')}, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; "
         f"{len(done)} finished compressions used.", ""]
    if inputs.left_out:
        L += ["**Partial analysis.** Left out: " + "; ".join(inputs.left_out) + ".", ""]
    L += _failed_tasks(inputs.failed)
    unconverged = int((done["converged"].astype(str).str.lower() == "false").sum()) if "converged" in done else 0
    if unconverged:
        L += ["Notes: " + f"{unconverged} finished simulation(s) report converged = False; they were used"
              + ".", ""]
    return L


def _laws(calibration: Any, variants: list[str]) -> list[str]:
    L = ["## Calibration (SPEC 4)", "",
         "K(h~) = K_B (1 + alpha exp(h~/lambda)); alpha = C(g) ln(K_S/K_B) + D(g), g = gamma_a/K_B; "
         "C, D cubic in g (coefficients lowest order first).", ""]
    rows = []
    for v in variants:
        law = calibration.laws[v]
        rows.append([v, _fmt(law.lam, 6), _fmt(law.goodness["step1_free_c"]["c_sd_over_grid"], 3),
                     ", ".join(_fmt(c, 5) for c in law.C), ", ".join(_fmt(c, 5) for c in law.D)])
    L += [_table(["bending", "lambda", "SD of free c over grid", "C coefficients", "D coefficients"], rows), ""]
    for v in variants:
        g = calibration.laws[v].goodness["step1_free_c"]
        lam = calibration.laws[v].lam
        if not abs(g["c_sd_over_grid"]) <= 0.2 * abs(lam):
            L += [f"**Warning ({v}):** the free fits' c vary by more than 20 % of lambda over the grid "
                  f"(SD {_fmt(g['c_sd_over_grid'], 3)}, range {_fmt(g['c_min'], 4)} to {_fmt(g['c_max'], 4)}): "
                  "a single lambda describes these curves poorly.", ""]
    return L


def _goodness_row(v: str, g: dict[str, Any]) -> list[str]:
    return [v,
            f"{_fmt(g['step1_free_c']['r2_min'], 6)}, {_fmt(g['step1_free_c']['max_residual_mN_per_m'], 3)} mN/m",
            f"{_fmt(g['step2_alpha']['r2_min'], 6)}, {_fmt(g['step2_alpha']['max_residual_mN_per_m'], 3)} mN/m",
            f"{_fmt(g['step3_log_law']['r2_min'], 6)}, {_fmt(g['step3_log_law']['max_residual'], 3)}",
            f"{_fmt(g['step4_C']['r2'], 6)} / {_fmt(g['step4_D']['r2'], 6)}",
            f"{_fmt(g['law_K']['r2'], 6)}, {_fmt(g['law_K']['max_residual_mN_per_m'], 3)} mN/m",
            _fmt(g["law_nu"]["max_abs_error"], 3)]


def _goodness(calibration: Any, variants: list[str]) -> list[str]:
    L = ["Goodness of fit at every stage (lowest R², largest residual):", ""]
    rows = [_goodness_row(v, calibration.laws[v].goodness) for v in variants]
    L += [_table(["bending", "1: alpha, c free", "2: alpha (c = lambda)", "3: log law (alpha)",
                  "4: C / D cubic R²", "whole law vs K", "whole law: max nu error"], rows), ""]
    for v in variants:
        law = calibration.laws[v]
        L += [f"alpha table, {v} bending (rows gamma_a/K_B, columns K_S/K_B):", ""]
        L += [_table(["gamma_a/K_B"] + [_fmt(k, 4) for k in law.ks_tilde],
                     [[_fmt(g, 4)] + [_fmt(a, 5) for a in row] for g, row in zip(law.gamma_tilde, law.alpha)]), ""]
    return L


def _checks(checks: Any) -> list[str]:
    if not checks:
        return []
    return ["Solver checks: largest relative volume error; largest deviation of the droplet area "
            "increase from the simulated shell's (the published check: within 6 %).", "",
            _table(["bending", "max volume error", "max abs(eps_A droplet / eps_A shell - 1)"],
                   [[c["bending"], _fmt(c.get("max_volume_error"), 3), _fmt(c.get("max_area_deviation"), 3)]
                    for c in checks]), ""]


def _reconstruction(recon_summary: Any, variants: list[str]) -> list[str]:
    L = ["## Reconstruction check", "",
         "Every simulated K(h~) curve inverted as a measured cell (heights 0.5 <= h~ <= 0.75, K_B and alpha "
         "fitted with lambda fixed, the published filters) with gamma_a known (the simulation's). "
         "'law only': the step-2 alpha (K_B known, all heights) inverted.", ""]
    recon_summary = sorted(recon_summary, key=lambda r: variants.index(r["bending"])
                           if r["bending"] in variants else len(variants))
    L += [_table(["bending", "curves", "excluded", "max abs nu error", "RMS nu error", "worst at K_S, gamma_a (mN/m)",
                  "law only: max abs nu error"],
                 [[r["bending"], r["n_curves"], r["n_excluded"], _fmt(r["max_abs_nu_error"], 3),
                   _fmt(r["rms_nu_error"], 3),
                   (f"{r['worst_at']['shear_mN_per_m']:g}, {r['worst_at']['tension_mN_per_m']:g}"
                    if r["worst_at"] else "-"), _fmt(r["max_abs_nu_law_error"], 3)] for r in recon_summary]), ""]
    reasons = sorted({x for r in recon_summary for x in r["excluded_reasons"]})
    if reasons:
        L += ["Exclusion reasons: " + "; ".join(reasons), ""]
    return L


def _montecarlo(mc_records: Any) -> list[str]:
    if not mc_records:
        return []
    return ["## Monte-Carlo error study (SPEC 5)", "",
            "Each trial curve fitted and inverted exactly as a measured cell, gamma_a = mean tension seen. "
            "median, IQR: the median over studies (repetitions of N cells) of each study's median and IQR "
            "of the recovered nu; [p05, p95]: their 5th-95th percentiles over studies; pooled: all cells of "
            "all studies together.", "",
            _table(["bending", "true nu", "height error", "N cells", "studies", "excluded",
                    "median [p05, p95]", "IQR [p05, p95]", "pooled median / IQR"],
                   [[r["bending"], _fmt(r["nu_true"], 3), r["height_error_mode"], r["n_cells"], r["n_studies"],
                     f"{100 * r['excluded_fraction']:.1f} %",
                     f"{_fmt(r['median'], 3)} [{_fmt(r['median_p05'], 3)}, {_fmt(r['median_p95'], 3)}]",
                     f"{_fmt(r['iqr'], 3)} [{_fmt(r['iqr_p05'], 3)}, {_fmt(r['iqr_p95'], 3)}]",
                     f"{_fmt(r['pooled_median'], 3)} / {_fmt(r['pooled_iqr'], 3)}"] for r in mc_records]), ""]


def render(inputs: Any, result: Any, checks: list[dict[str, Any]], figs: list[Path]) -> str:
    """report.md as text: `inputs` and `result` of `analysis.calibration.command.pipeline`
    (`Inputs`, `Fitted`), `checks` of `solver_checks`, `figs` the figures' paths."""
    cal = result.calibration
    variants = [v for v in ORDER if v in cal.laws] + [v for v in cal.laws if v not in ORDER]
    L = (_header(inputs) + _laws(cal, variants) + _goodness(cal, variants) + _checks(checks)
         + _reconstruction(result.recon_summary, variants) + _montecarlo(result.mc_records))
    L += ["## Figures", ""] + [f"![{p.stem}]({p.name})" for p in figs] + [""]
    return "\n".join(L)
