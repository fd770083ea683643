"""`cortex analysis calibrate STORE --out DIR`: the whole analysis of a
campaign store, and its report.

Reads the store (through `read_store`, the one place that touches it),
refuses an unfinished store unless `partial`, computes everything in memory
(calibration, reconstruction, Monte-Carlo), and only then writes into DIR:

    calibration.json          per bending variant: lambda, C, D, alpha table, goodness
    calibration_fits.csv      every fitted value of steps 1-2, one row per (K_S, gamma_a) curve
    calibration_log_law.csv   steps 3-4, one row per gamma_a/K_B
    reconstruction.csv        nu recovered from every simulated curve vs the true nu
    montecarlo.json           per (bending, true nu, height-error mode): median, IQR and spreads
    montecarlo_studies.csv    per study: median and IQR of the recovered nu
    montecarlo_cells.csv      per trial: the inversion of its curve
    *.png, *.pdf              figures
    report.md                 numbers, tables, figures
    .cortex-outputs           the manifest of these files (`outputs.ownership`): a rerun
                              replaces only them; someone else's folder is refused
"""

import json
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

from outputs.ownership import OutputDir, json_document
from solver.errors import InputError


def read_store(path):
    """(results, trials) DataFrames of a campaign store, via `campaign.reader`."""
    try:
        from campaign import reader
    except ModuleNotFoundError as err:
        raise InputError(f"cannot read {path}: the campaign package is not installed ({err.name})") from None
    try:
        results = reader.read_results(path)
        trials = reader.read_trials(path)
    except InputError:
        raise
    except (OSError, KeyError, ValueError) as err:
        raise InputError(f"{path}: not a readable campaign store ({type(err).__name__}: {err})") from None
    return results, trials


def _progress(start):
    def say(message):
        print(f"[analysis {time.perf_counter() - start:6.1f} s] {message}", file=sys.stderr, flush=True)
    return say


def _missing(frame, unit, id_column):
    """(how many not done, how many in all, 'a pending, b failed' text)."""
    if frame is None or not len(frame):
        return 0, 0, ""
    states = frame.drop_duplicates(id_column)["state"]
    counts = states[states != "done"].value_counts()
    text = ", ".join(f"{n} {state}" for state, n in counts.items())
    return int(counts.sum()), int(len(states)), f"{int(counts.sum())} of {len(states)} {unit} not done ({text})"


def run(store, out, partial=False, progress=None):
    """The whole analysis; returns a dict of the headline numbers."""
    from analysis import calibration as cal_mod
    from analysis import montecarlo as mc_mod
    from analysis import reconstruction as rec_mod

    start = time.perf_counter()
    say = progress or _progress(start)
    store, out = Path(store), Path(out)
    if not store.exists():
        raise InputError(f"{store}: no such store")
    out = OutputDir(out, written_before_manifests=lambda d: json_document(d / "calibration.json").get("format")
                    == cal_mod.FORMAT)    # refused now if not ours (a file, someone else's folder)
    marks = [("start", time.perf_counter())]
    results, trials = read_store(store)      # no output before the input is checked
    marks.append(("read_s", time.perf_counter()))
    missing_cols = [c for c in cal_mod.NEEDED + ("state",) if c not in results.columns]
    if missing_cols:
        raise InputError(f"{store}: results lack column(s) {', '.join(missing_cols)}")
    n_res, total_res, text_res = _missing(results, "compression tasks", "task_id")
    has_trials = trials is not None and len(trials) > 0
    n_tri, total_tri, text_tri = _missing(trials, "Monte-Carlo trials", "trial_id") if has_trials else (0, 0, "")
    left_out = [t for n, t in ((n_res, text_res), (n_tri, text_tri)) if n]
    if left_out and not partial:
        raise InputError(f"{store} is unfinished: {'; '.join(left_out)}; finish the campaign "
                         "or pass --partial")
    done = results[(results["state"] == "done")]
    unusable = done[done[["h_tilde", "modulus_mN_per_m"]].isna().any(axis=1) |
                    ~np.isfinite(done["modulus_mN_per_m"])]
    if len(unusable):
        left_out.append(f"{len(unusable)} done compression task(s) without a finite modulus")
    done = done.drop(unusable.index)
    if not len(done):
        raise InputError(f"{store}: no finished compression with a finite modulus to calibrate")

    calibration, fits, loglaw = cal_mod.calibrate(done)   # bad data is refused before any output
    marks.append(("calibrate_s", time.perf_counter()))
    say(f"read {store}: {len(done)} finished compressions"
        + (f", {trials['trial_id'].nunique()} Monte-Carlo trials" if has_trials else "")
        + f"; calibrated bending variant(s) {', '.join(calibration.laws)}")
    for bending, group in done.groupby("bending"):
        used = fits.loc[fits["bending"] == bending, "n_heights"].sum()
        if used < len(group):
            left_out.append(f"{bending}: {len(group) - used} simulation(s) in curves with fewer than "
                            f"{cal_mod.MIN_HEIGHTS} heights")
    say("reconstruction check: inverting every simulated curve")
    recon = rec_mod.reconstruct(done, calibration, fits)
    recon_summary = rec_mod.summarise(recon)
    mc_records = studies = cells = None
    if has_trials:
        usable = trials[trials["bending"].isin(calibration.laws)]
        if len(usable) < len(trials):
            left_out.append(f"{trials.loc[~trials['bending'].isin(calibration.laws), 'trial_id'].nunique()} "
                            "Monte-Carlo trial(s) of a bending variant without calibration")
        if len(usable):
            say(f"Monte-Carlo study: inverting {usable['trial_id'].nunique()} trial curves")
            mc_records, studies, cells = mc_mod.montecarlo(usable, calibration)

    marks.append(("reconstruction_montecarlo_s", time.perf_counter()))
    say(f"writing {out.path}/")
    tables = {"calibration_fits.csv": fits, "calibration_log_law.csv": loglaw, "reconstruction.csv": recon}
    if mc_records is not None:
        tables.update({"montecarlo_studies.csv": studies, "montecarlo_cells.csv": cells})
    out.check(["calibration.json", "montecarlo.json", "report.md", *tables])
    with out.writing("calibration.json") as path:
        calibration.save(path)
    for name, table in tables.items():
        with out.writing(name) as path:
            table.to_csv(path, index=False)
    if mc_records is not None:
        with out.writing("montecarlo.json") as path:
            path.write_text(json.dumps(mc_records, indent=1) + "\n")
    say("figures")
    from analysis import figures
    figs = [figures.modulus_curves(done, calibration, fits, out)[0],
            figures.alpha_law(calibration, fits, out)[0],
            figures.reconstruction(recon, out)[0]]
    if "equator_shear_ratio" in done and done["equator_shear_ratio"].notna().any():
        figs.append(figures.equator_shear(done, out)[0])
    if mc_records is not None:
        figs.append(figures.montecarlo_boxes(cells, studies, out)[0])
    checks = _checks(done)
    notes = []
    unconverged = int((done["converged"].astype(str).str.lower() == "false").sum()) if "converged" in done else 0
    if unconverged:
        notes.append(f"{unconverged} finished simulation(s) report converged = False; they were used")
    text = render(store, calibration, recon_summary, mc_records, checks, left_out, figs, len(done), notes)
    with out.writing("report.md") as path:
        path.write_text(text)
    marks.append(("figures_report_s", time.perf_counter()))
    wall = time.perf_counter() - start
    timings = {name: round(t - t0, 3) for (_, t0), (name, t) in zip(marks, marks[1:])}
    say(f"done: {path}" + (f" (partial: {'; '.join(left_out)})" if left_out else ""))
    return {"calibration": calibration, "reconstruction": recon_summary, "montecarlo": mc_records,
            "left_out": left_out, "wall_s": wall, "timings_s": timings, "report": path}


def _checks(done):
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


def _fmt(x, digits=4):
    if x is None or (isinstance(x, float) and not np.isfinite(x)):
        return "-"
    return f"{x:.{digits}g}"


def _table(header, rows):
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def render(store, calibration, recon_summary, mc_records, checks, left_out, figs, n_done, notes=()):
    """report.md as text."""
    from cortex import __version__
    from analysis.figures import ORDER
    L = [f"# Calibration and Monte-Carlo analysis of `{store}`", "",
         f"cortex {__version__}, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; "
         f"{n_done} finished compressions used.", ""]
    if left_out:
        L += ["**Partial analysis.** Left out: " + "; ".join(left_out) + ".", ""]
    if notes:
        L += ["Notes: " + "; ".join(notes) + ".", ""]
    variants = [v for v in ORDER if v in calibration.laws] + [v for v in calibration.laws if v not in ORDER]
    L += ["## Calibration (SPEC 4)", "",
          "K(h~) = K_B (1 + alpha exp(h~/lambda)); alpha = C(g) ln(K_S/K_B) + D(g), g = gamma_a/K_B; "
          "C, D cubic in g (coefficients lowest order first).", ""]
    rows = []
    for v in variants:
        law = calibration.laws[v]
        g = law.goodness
        rows.append([v, _fmt(law.lam, 6), _fmt(g["step1_free_c"]["c_sd_over_grid"], 3),
                     ", ".join(_fmt(c, 5) for c in law.C), ", ".join(_fmt(c, 5) for c in law.D)])
    L += [_table(["bending", "lambda", "SD of free c over grid", "C coefficients", "D coefficients"], rows), ""]
    for v in variants:
        g = calibration.laws[v].goodness["step1_free_c"]
        lam = calibration.laws[v].lam
        if not abs(g["c_sd_over_grid"]) <= 0.2 * abs(lam):
            L += [f"**Warning ({v}):** the free fits' c vary by more than 20 % of lambda over the grid "
                  f"(SD {_fmt(g['c_sd_over_grid'], 3)}, range {_fmt(g['c_min'], 4)} to {_fmt(g['c_max'], 4)}): "
                  "a single lambda describes these curves poorly.", ""]
    L += ["Goodness of fit at every stage (lowest R², largest residual):", ""]
    rows = []
    for v in variants:
        g = calibration.laws[v].goodness
        rows.append([v,
                     f"{_fmt(g['step1_free_c']['r2_min'], 6)}, {_fmt(g['step1_free_c']['max_residual_mN_per_m'], 3)} mN/m",
                     f"{_fmt(g['step2_alpha']['r2_min'], 6)}, {_fmt(g['step2_alpha']['max_residual_mN_per_m'], 3)} mN/m",
                     f"{_fmt(g['step3_log_law']['r2_min'], 6)}, {_fmt(g['step3_log_law']['max_residual'], 3)}",
                     f"{_fmt(g['step4_C']['r2'], 6)} / {_fmt(g['step4_D']['r2'], 6)}",
                     f"{_fmt(g['law_K']['r2'], 6)}, {_fmt(g['law_K']['max_residual_mN_per_m'], 3)} mN/m",
                     _fmt(g["law_nu"]["max_abs_error"], 3)])
    L += [_table(["bending", "1: alpha, c free", "2: alpha (c = lambda)", "3: log law (alpha)",
                  "4: C / D cubic R²", "whole law vs K", "whole law: max nu error"], rows), ""]
    for v in variants:
        law = calibration.laws[v]
        L += [f"alpha table, {v} bending (rows gamma_a/K_B, columns K_S/K_B):", ""]
        L += [_table(["gamma_a/K_B"] + [_fmt(k, 4) for k in law.ks_tilde],
                     [[_fmt(g, 4)] + [_fmt(a, 5) for a in row] for g, row in zip(law.gamma_tilde, law.alpha)]), ""]
    if checks:
        L += ["Solver checks: largest relative volume error; largest deviation of the droplet area "
              "increase from the simulated shell's (the published check: within 6 %).", ""]
        L += [_table(["bending", "max volume error", "max abs(eps_A droplet / eps_A shell - 1)"],
                     [[c["bending"], _fmt(c.get("max_volume_error"), 3), _fmt(c.get("max_area_deviation"), 3)]
                      for c in checks]), ""]
    L += ["## Reconstruction check", "",
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
    if mc_records:
        L += ["## Monte-Carlo error study (SPEC 5)", "",
              "Each trial curve fitted and inverted exactly as a measured cell, gamma_a = mean tension seen. "
              "median, IQR: the median over studies (repetitions of N cells) of each study's median and IQR "
              "of the recovered nu; [p05, p95]: their 5th-95th percentiles over studies; pooled: all cells of "
              "all studies together.", ""]
        L += [_table(["bending", "true nu", "height error", "N cells", "studies", "excluded",
                      "median [p05, p95]", "IQR [p05, p95]", "pooled median / IQR"],
                     [[r["bending"], _fmt(r["nu_true"], 3), r["height_error_mode"], r["n_cells"], r["n_studies"],
                       f"{100 * r['excluded_fraction']:.1f} %",
                       f"{_fmt(r['median'], 3)} [{_fmt(r['median_p05'], 3)}, {_fmt(r['median_p95'], 3)}]",
                       f"{_fmt(r['iqr'], 3)} [{_fmt(r['iqr_p05'], 3)}, {_fmt(r['iqr_p95'], 3)}]",
                       f"{_fmt(r['pooled_median'], 3)} / {_fmt(r['pooled_iqr'], 3)}"] for r in mc_records]), ""]
    L += ["## Figures", ""] + [f"![{p.stem}]({p.name})" for p in figs] + [""]
    return "\n".join(L)
