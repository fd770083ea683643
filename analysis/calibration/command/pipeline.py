"""`cortex analysis calibrate STORE --out DIR`: read -> fit -> write.

The three stages are one function each, and the data passes through them once:

    read(store, partial)        the store's finished compressions and trials (through
                                `read_store`, the one place that touches the store),
                                refusing an unfinished store unless `partial`;
    fit(inputs, say)            calibration (SPEC 4), reconstruction check, Monte-Carlo
                                study (SPEC 5), all in memory;
    write(out, inputs, result)  the tables, the figures and report.md
                                (`analysis.calibration.command.report`) into DIR.

Nothing is written before the input is checked and fitted. DIR gets:

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

from __future__ import annotations

import json
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from os import PathLike
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from analysis.calibration import law as cal_mod
from outputs.ownership import OutputDir
from common.errors import InputError


@dataclass
class Inputs:
    """What `read` found: the usable finished compressions, the trials (or
    None), what was left out (one text per reason) and the failed
    compressions (their rows of the store's results)."""

    store: Path
    done: pd.DataFrame
    trials: pd.DataFrame | None
    left_out: list[str] = field(default_factory=list)
    failed: pd.DataFrame | None = None


@dataclass
class Fitted:
    """What `fit` computed; the Monte-Carlo parts are None without trials."""

    calibration: cal_mod.Calibration
    fits: pd.DataFrame
    loglaw: pd.DataFrame
    recon: pd.DataFrame
    recon_summary: list[dict[str, Any]]
    mc_records: list[dict[str, Any]] | None = None
    studies: pd.DataFrame | None = None
    cells: pd.DataFrame | None = None


def read_store(path: str | PathLike[str]) -> tuple[pd.DataFrame, pd.DataFrame | None]:
    """(results, trials) DataFrames of a campaign store, via `campaign.store.reader`."""
    try:
        from campaign.store import reader
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


def _progress(start: float) -> Callable[[str], None]:
    def say(message: str) -> None:
        print(f"[analysis {time.perf_counter() - start:6.1f} s] {message}", file=sys.stderr, flush=True)
    return say


def _missing(frame: pd.DataFrame | None, unit: str, id_column: str) -> tuple[int, int, str]:
    """(how many not done, how many in all, 'a pending, b failed' text)."""
    if frame is None or not len(frame):
        return 0, 0, ""
    states = frame.drop_duplicates(id_column)["state"]
    counts = states[states != "done"].value_counts()
    text = ", ".join(f"{n} {state}" for state, n in counts.items())
    return int(counts.sum()), int(len(states)), f"{int(counts.sum())} of {len(states)} {unit} not done ({text})"


def read(store: Path, partial: bool = False) -> Inputs:
    """The store's usable compressions and trials as `Inputs`; InputError for
    a missing, unreadable or (unless `partial`) unfinished store."""
    results, trials = read_store(store)      # no output before the input is checked
    missing_cols = [c for c in cal_mod.NEEDED + ("state",) if c not in results.columns]
    if missing_cols:
        raise InputError(f"{store}: results lack column(s) {', '.join(missing_cols)}")
    has_trials = trials is not None and len(trials) > 0
    n_res, _, text_res = _missing(results, "compression tasks", "task_id")
    n_tri, _, text_tri = _missing(trials, "Monte-Carlo trials", "trial_id") if has_trials else (0, 0, "")
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
    return Inputs(store=store, done=done, trials=trials if has_trials else None, left_out=left_out,
                  failed=results[results["state"] == "failed"])


def fit(inputs: Inputs, say: Callable[[str], None], marks: list[tuple[str, float]]) -> Fitted:
    """Calibration, reconstruction check and Monte-Carlo study of `inputs` as
    `Fitted` (bad data is refused here, before any output); adds to
    inputs.left_out what could not be used and to `marks` the stage times."""
    from analysis.calibration.command import montecarlo as mc_mod
    from analysis.calibration.command import reconstruction as rec_mod

    done, trials, left_out = inputs.done, inputs.trials, inputs.left_out
    calibration, fits, loglaw = cal_mod.calibrate(done)
    marks.append(("calibrate_s", time.perf_counter()))
    say(f"read {inputs.store}: {len(done)} finished compressions"
        + (f", {trials['trial_id'].nunique()} Monte-Carlo trials" if trials is not None else "")
        + f"; calibrated bending variant(s) {', '.join(calibration.laws)}")
    for bending, group in done.groupby("bending"):
        used = fits.loc[fits["bending"] == bending, "n_heights"].sum()
        if used < len(group):
            left_out.append(f"{bending}: {len(group) - used} simulation(s) in curves with fewer than "
                            f"{cal_mod.MIN_HEIGHTS} heights")
    say("reconstruction check: inverting every simulated curve")
    recon = rec_mod.reconstruct(done, calibration, fits)
    result = Fitted(calibration, fits, loglaw, recon, rec_mod.summarise(recon))
    if trials is not None:
        usable = trials[trials["bending"].isin(calibration.laws)]
        if len(usable) < len(trials):
            left_out.append(f"{trials.loc[~trials['bending'].isin(calibration.laws), 'trial_id'].nunique()} "
                            "Monte-Carlo trial(s) of a bending variant without calibration")
        if len(usable):
            say(f"Monte-Carlo study: inverting {usable['trial_id'].nunique()} trial curves")
            result.mc_records, result.studies, result.cells = mc_mod.montecarlo(usable, calibration)
    marks.append(("reconstruction_montecarlo_s", time.perf_counter()))
    return result


def _tables(result: Fitted) -> dict[str, pd.DataFrame]:
    """{file name: DataFrame} of the CSV tables."""
    tables = {"calibration_fits.csv": result.fits, "calibration_log_law.csv": result.loglaw,
              "reconstruction.csv": result.recon}
    if result.mc_records is not None:
        tables.update({"montecarlo_studies.csv": result.studies, "montecarlo_cells.csv": result.cells})
    return tables


def _figures(done: pd.DataFrame, result: Fitted, out: OutputDir) -> list[Path]:
    """The figures' paths (PNG; a PDF beside each)."""
    from analysis.calibration.command import figures
    cal = result.calibration
    figs = [figures.modulus_curves(done, cal, result.fits, out)[0],
            figures.alpha_law(cal, result.fits, out)[0],
            figures.reconstruction(result.recon, out)[0]]
    if "equator_shear_ratio" in done and done["equator_shear_ratio"].notna().any():
        figs.append(figures.equator_shear(done, out)[0])
    if result.mc_records is not None:
        figs.append(figures.montecarlo_boxes(result.cells, result.studies, out)[0])
    return figs


def write(out: OutputDir, inputs: Inputs, result: Fitted, say: Callable[[str], None]) -> Path:
    """Write every output of the module docstring into the `OutputDir` out;
    returns the report's path."""
    from analysis.calibration.command.report import render, solver_checks

    say(f"writing {out.path}/")
    tables = _tables(result)
    out.check(["calibration.json", "montecarlo.json", "report.md", *tables])
    with out.writing("calibration.json") as path:
        result.calibration.save(path)
    for name, table in tables.items():
        with out.writing(name) as path:
            table.to_csv(path, index=False)
    if result.mc_records is not None:
        with out.writing("montecarlo.json") as path:
            path.write_text(json.dumps(result.mc_records, indent=1) + "\n")
    say("figures")
    figs = _figures(inputs.done, result, out)
    text = render(inputs, result, solver_checks(inputs.done), figs)
    with out.writing("report.md") as path:
        path.write_text(text)
    return path


def run(store: str | PathLike[str], out: str | PathLike[str], partial: bool = False,
        progress: Callable[[str], None] | None = None) -> dict[str, Any]:
    """The whole analysis (read -> fit -> write); returns a dict of the headline numbers."""
    start = time.perf_counter()
    say = progress or _progress(start)
    store = Path(store)
    if not store.exists():
        raise InputError(f"{store}: no such store")
    folder = OutputDir(Path(out))     # refused now if not ours (a file, someone else's folder)
    marks = [("start", time.perf_counter())]
    inputs = read(store, partial)
    marks.append(("read_s", time.perf_counter()))
    result = fit(inputs, say, marks)
    path = write(folder, inputs, result, say)
    marks.append(("figures_report_s", time.perf_counter()))
    timings = {name: round(t - t0, 3) for (_, t0), (name, t) in zip(marks, marks[1:])}
    left_out = inputs.left_out
    say(f"done: {path}" + (f" (partial: {'; '.join(left_out)})" if left_out else ""))
    return {"calibration": result.calibration, "reconstruction": result.recon_summary,
            "montecarlo": result.mc_records, "left_out": left_out,
            "wall_s": time.perf_counter() - start, "timings_s": timings, "report": path}
