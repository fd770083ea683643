"""The measured-cell round trip (issue 13, "what it must show"): synthetic
experiments of 85 cells with the fast solver as the forward model
(`analysis.afm.synth.cells`), analysed with the shipped calibration by both methods.
Prints one JSON object.

Per seed and errors off/on, per method: the medians of ν per frequency
(recovered and true, over the included non-blebbing cells), the fraction of
included cells with |Δν| ≤ 0.03, and (emulator) the fraction whose 95 %
interval holds the true ν.

With `--cache FILE` the solver's answers are memoised in FILE (the pickle
`bench/error_sources.py --cache` writes: its `all` configuration asks the same
questions as errors on here), so a rerun of the analysis alone takes minutes,
not the solver's ~11 min per seed and errors setting; `--errors on` (or off)
runs one setting only.

    python bench/roundtrip.py [SEED ...] [--errors off on] [--cache FILE]   (default: 6 7 8 9, both)
"""

import argparse
import json
import pickle
import sys
import time
from pathlib import Path

import numpy as np


from analysis.afm.analyze import analyze_cells
from analysis.invert.method import choose
from analysis.afm.synth.cells import generate, solver_forward
from analysis.calibration.file import load_calibration


def memoised(forward, cache):
    """`forward` answering repeated questions from the dict `cache`."""
    def ask(volume, heights, bulk, shear, tension):
        key = (float(volume), tuple(np.asarray(heights, float)), float(bulk), float(shear), float(tension))
        if key not in cache:
            cache[key] = np.asarray(forward(volume, heights, bulk, shear, tension))
        return cache[key]
    return ask


def score(table, truth):
    rows = []
    for r in table.itertuples():
        t = truth["frequencies"][str(float(r.frequency_hz))]["cells"][r.cell_id]
        rows.append((r.frequency_hz, t["nu"], r.nu, getattr(r, "nu_lo95", np.nan), getattr(r, "nu_hi95", np.nan),
                     isinstance(r.excluded_reason, str), t["blebbing"]))
    a = np.array([x[:5] for x in rows], float)
    excluded = np.array([x[5] for x in rows])
    ok = ~excluded
    err = np.abs(a[:, 2] - a[:, 1])
    out = {"n_curves": len(rows), "n_included": int(ok.sum()),
           "frac_abs_err_le_0.03": float(np.mean(err[ok] <= 0.03)),
           "max_abs_err": float(np.max(err[ok])), "per_frequency": {}}
    if np.isfinite(a[ok, 3]).any():
        out["coverage_95"] = float(np.mean((a[ok, 3] <= a[ok, 1]) & (a[ok, 1] <= a[ok, 4])))
    for f in sorted(set(a[:, 0])):
        sel = ok & (a[:, 0] == f)
        out["per_frequency"][f"{f:g}"] = {"median_nu": float(np.median(a[sel, 2])),
                                          "median_nu_true": float(np.median(a[sel, 1])),
                                          "n": int(sel.sum())}
    return out


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("seeds", nargs="*", type=int, default=[6, 7, 8, 9])
    p.add_argument("--errors", nargs="+", choices=("off", "on"), default=["off", "on"])
    p.add_argument("--cache", type=Path, help="pickle of the solver's answers (read if present, written)")
    a = p.parse_args()
    file = load_calibration()
    cal, emu = file.calibration, file.emulator
    cache = pickle.loads(a.cache.read_bytes()) if a.cache and a.cache.is_file() else {}
    forward = memoised(solver_forward("standard"), cache)
    out = {"benchmark": "roundtrip", "cells": 85, "runs": []}
    for seed in a.seeds:
        for errors in (e == "on" for e in a.errors):
            start = time.perf_counter()
            cells, truth = generate(85, seed, errors=errors, forward=forward)
            synth_s = time.perf_counter() - start
            run = {"seed": seed, "errors": errors, "synth_s": round(synth_s, 1)}
            for method in ("emulator", "law"):
                start = time.perf_counter()
                table, _ = analyze_cells(cells, choose(method, cal, emu), "standard", None)
                run[method] = {**score(table, truth), "analyze_s": round(time.perf_counter() - start, 2)}
            out["runs"].append(run)
            print(json.dumps(run), file=sys.stderr, flush=True)
        if a.cache:
            a.cache.write_bytes(pickle.dumps(cache))
    print(json.dumps(out))


if __name__ == "__main__":
    main()
