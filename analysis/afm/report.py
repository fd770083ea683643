"""`cortex afm analyze`: load recordings, analyse with every bending variant,
write DIR/cells.csv, DIR/segments.csv, DIR/summary.json (selected variant),
DIR/summary_<variant>.json, figures and DIR/report.md.

Recordings: one experiment (.h5/.hdf5), one single-cell CSV, or JPK files and
folders of them (`jpk_import.import_cells`, with the volume and dish options
of `cortex afm import`). A recording without any oscillation segment is not
analysed: report.md lists it with that reason (`skipped` in the result).

With the emulator (the default method) every cell and frequency has a 95 %
interval of ν and K̃_S (`nu_lo95`, `nu_hi95`, `ks_lo95`, `ks_hi95` in cells.csv),
and every frequency's median ν a bootstrap 95 % interval (`median_nu_lo95`,
`median_nu_hi95` in the summaries); figure `nu_intervals.png`."""

import json
from pathlib import Path

import numpy as np

from analysis.afm.analyze import analyze
from analysis.afm.figures import FIGURES
from analysis.afm.population import summary
from outputs.ownership import OutputDir, json_document
from solver.errors import InputError


NO_OSCILLATION = "no modulation (oscillation) segment"


def load(paths, jpk_options=None):
    """Cells from an experiment (.h5/.hdf5), a single-cell CSV (.csv), or JPK
    files and folders (`jpk_options`: keyword arguments of `import_cells`)."""
    from analysis.afm.jpk_import import import_cells, is_jpk
    paths = [paths] if isinstance(paths, (str, Path)) else list(paths)
    if all(is_jpk(p) for p in paths):
        return import_cells(paths, **(jpk_options or {}))[1]
    if len(paths) != 1:
        raise InputError("give one experiment (.h5) or CSV file, or JPK files and folders (not a mixture)")
    given = [k for k, v in (jpk_options or {}).items() if v is not None]
    if given:
        raise InputError(f"{paths[0]}: --volume(s) and --dish-* apply to JPK files only; the experiment "
                         "and CSV formats carry their own volumes and heights")
    path = Path(paths[0])
    suffix = path.suffix.lower()
    if suffix in (".h5", ".hdf5"):
        from analysis.afm.h5format import read_experiment
        return read_experiment(path)
    if suffix == ".csv":
        from analysis.afm.csvformat import read_csv_cell
        return [read_csv_cell(path)]
    raise InputError(f"{path}: unknown recording format '{suffix}' (expected .h5, .hdf5, .csv, "
                     "a JPK file or a folder of them)")


def run(data, calibration_path, out, bending="standard", jpk_options=None, method="law", errors=None):
    """Analyse `data` (a path or a list of paths) into DIR `out`; the result has
    the report's path, the summary, the table and the skipped recordings.
    `calibration_path` None: the shipped calibration."""
    cells = load(data, jpk_options)
    cal, emu, variants = _calibration(calibration_path, method, bending)
    skipped = {c.cell_id: NO_OSCILLATION for c in cells if not c.oscillations()}
    cells = [c for c in cells if c.oscillations()]
    name = Path(data).name if isinstance(data, (str, Path)) else ", ".join(Path(d).name for d in data)
    out = OutputDir(out, written_before_manifests=lambda d: {"bending", "frequencies"}
                    <= set(json_document(d / "summary.json")))   # refused now if not ours
    variants = [bending] + [v for v in variants if v != bending]
    out.check(["segments.csv", "cells.csv", "summary.json", "report.md", "nu_intervals.png", *FIGURES]
              + [f"{kind}_{v}.{ext}" for v in variants for kind, ext in (("cells", "csv"), ("summary", "json"))])
    if not cells:
        report = _write(out, "report.md", lambda p: p.write_text(_markdown_skipped(name, skipped)))
        return {"report": report, "summary": None, "table": None, "skipped": skipped}
    tables, sums = {}, {}
    for variant in variants:
        tab, segs = analyze(cells, cal, variant, method=method, emulator=emu, errors=errors)
        tables[variant], sums[variant] = tab, _with_medians(summary(tab), tab, method)
        _write(out, f"cells_{variant}.csv", lambda p: tab.to_csv(p, index=False))
        _write(out, f"summary_{variant}.json", lambda p: p.write_text(json.dumps(sums[variant], indent=1) + "\n"))
        if variant == bending:
            _write(out, "segments.csv", lambda p: segs.to_csv(p, index=False))
            _write(out, "cells.csv", lambda p: tab.to_csv(p, index=False))
    head = {"bending": bending, "method": method}
    _write(out, "summary.json", lambda p: p.write_text(json.dumps({**head, **sums[bending]}, indent=1) + "\n"))
    from analysis.afm.figures import figures, nu_intervals      # matplotlib: only now
    figs = figures(tables, sums, segs, out)
    if method == "emulator":
        figs.append(nu_intervals(tables[bending], out))
    report = _write(out, "report.md", lambda p: p.write_text(_markdown(name, bending, tables, sums, figs)
                                                            + _markdown_skipped(None, skipped)))
    return {"report": report, "summary": sums[bending], "table": tables[bending], "skipped": skipped}


def _calibration(path, method, bending):
    """(Calibration or None, Emulator or None, bending variants) for `method`;
    InputError if the file cannot serve it. `path` None: the shipped one."""
    from analysis.shipped import load as load_calibration
    cal, emu, _ = load_calibration(path)
    where = path or "the shipped calibration"
    if method == "emulator" and emu is None:
        raise InputError(f"{where}: holds no emulator tables; use --method law")
    if method == "law" and cal is None:
        raise InputError(f"{where}: holds no paper law; use --method emulator")
    variants = list(emu.tables) if method == "emulator" else list(cal.laws)
    if bending not in variants:
        raise InputError(f"{where}: no bending variant '{bending}' (has {', '.join(variants)})")
    return cal, emu, variants


def _write(out, name, write):
    """`write(path)` for file `name` of the output folder `out` (`OutputDir`); its path."""
    with out.writing(name) as path:
        write(path)
    return path


def _markdown_skipped(name, skipped):
    lines = [f"# Measured cells: {name}", "", "No recording could be analysed."] if name else []
    if skipped:
        lines += ["", "## Recordings not analysed", "", "| cell | reason |", "|---|---|"]
        lines += [f"| {c} | {r} |" for c, r in skipped.items()]
    return "\n".join(lines) + "\n" if lines else ""


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


def _markdown(name, bending, tables, sums, figs):
    method = tables[bending]["method"].iloc[0] if "method" in tables[bending] else "law"
    lines = [f"# Measured cells: {name}", "",
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
