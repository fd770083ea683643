"""`cortex afm analyze`: load recordings, analyse with every bending variant,
write DIR/cells.csv, DIR/segments.csv, DIR/summary.json (selected variant),
DIR/summary_<variant>.json, figures and DIR/report.md.

With the emulator (the default method) every cell and frequency has a 95 %
interval of ν and K̃_S (`nu_lo95`, `nu_hi95`, `ks_lo95`, `ks_hi95` in cells.csv),
and every frequency's median ν a bootstrap 95 % interval (`median_nu_lo95`,
`median_nu_hi95` in the summaries); figure `nu_intervals.png`."""

import json
from pathlib import Path

import numpy as np

from analysis.afm.analyze import analyze
from analysis.afm.population import summary
from solver.errors import InputError


def load(path):
    """Cells from an experiment (.h5/.hdf5) or a single-cell CSV (.csv)."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix in (".h5", ".hdf5"):
        from analysis.afm.h5format import read_experiment
        return read_experiment(path)
    if suffix == ".csv":
        from analysis.afm.csvformat import read_csv_cell
        return [read_csv_cell(path)]
    raise InputError(f"{path}: unknown recording format '{suffix}' (expected .h5, .hdf5 or .csv)")


def run(data, calibration_path, out, bending="standard", method="law", errors=None):
    """Analyse DATA into DIR `out`. `calibration_path` None: the shipped calibration."""
    from analysis.shipped import load as load_calibration
    cells = load(data)
    cal, emu, _ = load_calibration(calibration_path)
    where = calibration_path or "the shipped calibration"
    variants = list(emu.tables) if method == "emulator" and emu is not None else list(cal.laws) if cal else []
    if method == "emulator" and emu is None:
        raise InputError(f"{where}: holds no emulator tables; use --method law")
    if method == "law" and cal is None:
        raise InputError(f"{where}: holds no paper law; use --method emulator")
    if bending not in variants:
        raise InputError(f"{where}: no bending variant '{bending}' (has {', '.join(variants)})")
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise InputError(f"{out}: exists and is not a directory")
    out.mkdir(parents=True, exist_ok=True)
    tables, sums = {}, {}
    for variant in [bending] + [v for v in variants if v != bending]:
        tab, segs = analyze(cells, cal, variant, method=method, emulator=emu, errors=errors)
        tables[variant], sums[variant] = tab, _with_medians(summary(tab), tab, method)
        tab.to_csv(out / f"cells_{variant}.csv", index=False)
        (out / f"summary_{variant}.json").write_text(json.dumps(sums[variant], indent=1) + "\n")
        if variant == bending:
            segs.to_csv(out / "segments.csv", index=False)
            tab.to_csv(out / "cells.csv", index=False)
    (out / "summary.json").write_text(json.dumps({"bending": bending, "method": method, **sums[bending]},
                                                 indent=1) + "\n")
    from analysis.afm.figures import figures, nu_intervals
    figs = figures(tables, sums, segs, out)
    if method == "emulator":
        figs.append(nu_intervals(tables[bending], out))
    report = out / "report.md"
    report.write_text(_markdown(data, bending, tables, sums, figs))
    return {"report": report, "summary": sums[bending], "table": tables[bending]}


def _with_medians(summ, table, method):
    """The summary with each frequency's bootstrap 95 % interval of the median ν (emulator)."""
    if method != "emulator":
        return summ
    from analysis.invert_table import median_table
    meds = {r["frequency_hz"]: r for r in median_table(table)}
    for r in summ["frequencies"]:
        m = meds.get(r["frequency_hz"], {})
        r["median_nu_lo95"], r["median_nu_hi95"] = m.get("median_nu_lo95"), m.get("median_nu_hi95")
        r["n_nu_beyond_isotropic"] = int(((table["frequency_hz"] == r["frequency_hz"])
                                          & table["excluded_reason"].isna() & table["nu_beyond_isotropic"]).sum())
    return summ


def _markdown(data, bending, tables, sums, figs):
    method = tables[bending]["method"].iloc[0] if "method" in tables[bending] else "law"
    lines = [f"# Measured cells: {Path(data).name}", "",
             f"Method: `{method}`. Calibration variant: `{bending}`. "
             f"{tables[bending]['cell_id'].nunique()} cells.", ""]
    if method == "emulator":
        lines += [f"Median ν per frequency with its bootstrap 95 % interval (variant `{bending}`):", "",
                  "| f (Hz) | cells | median ν | 95 % interval | cells with ν > 0.5 |", "|---|---|---|---|---|"]
        for r in sums[bending]["frequencies"]:
            lo, hi = r.get("median_nu_lo95"), r.get("median_nu_hi95")
            ci = f"[{lo:.3f}, {hi:.3f}]" if lo is not None and np.isfinite(lo) else "–"
            med = f"{r['median_nu']:.3f}" if r["median_nu"] is not None else "–"
            lines.append(f"| {r['frequency_hz']:g} | {r['n_cells']} | {med} | {ci} | "
                         f"{r.get('n_nu_beyond_isotropic', 0)} |")
        lines += ["", "Each cell's 95 % interval (`nu_lo95`, `nu_hi95` in cells.csv) includes the volume "
                  "and height errors and the fit's residuals (parametric bootstrap through the emulator).", ""]
    lines += [
             "| variant | f (Hz) | cells | excluded | median ν | IQR ν | lognormal μ | lognormal σ |",
             "|---|---|---|---|---|---|---|---|"]
    for v, s in sums.items():
        for r in s["frequencies"]:
            fmt = lambda x: "–" if x is None or not np.isfinite(x) else f"{x:.3f}"  # noqa: E731
            lines.append(f"| {v} | {r['frequency_hz']:g} | {r['n_cells']} | {r['n_excluded']} | "
                         f"{fmt(r['median_nu'])} | {fmt(r['iqr_nu'])} | {fmt(r['lognormal_mu'])} | "
                         f"{fmt(r['lognormal_sigma'])} |")
    lines += ["", "Two-sided Mann-Whitney p-values (variant `%s`):" % bending, ""]
    lines += [f"- {k}: {p:.3g}" for k, p in sums[bending]["mann_whitney_p"].items()]
    tab = tables[bending]
    ok = tab[tab["excluded_reason"].isna()]
    if ok["outside_calibration"].notna().any():
        lines += ["", f"{int((ok['outside_calibration'] == True).sum())} of {len(ok)} included results "  # noqa: E712
                  "have K̃_S or γ̃_a outside the calibration grid (ν from the log law's extrapolation; "
                  "`outside_calibration` in cells.csv)."]
    lines += ["", "## Excluded cells", "", "| cell | f (Hz) | reason |", "|---|---|---|"]
    ex = tables[bending][tables[bending]["excluded_reason"].notna()]
    lines += [f"| {r.cell_id} | {r.frequency_hz:g} | {r.excluded_reason} |" for r in ex.itertuples()]
    lines += ["", "## Figures", ""] + [f"![{p.stem}]({p.name})" for p in figs]
    return "\n".join(lines) + "\n"
