"""Where the remaining error comes from (issue 13, item 6): the synthetic
experiment's measurement errors switched on one at a time. Prints one JSON
object.

Configurations: none; volume (SD 7.5 %); height offset (SD 0.5 µm, one per
cell); force noise (0.2 nN); drift (±0.001 nN/s); blebbing (8 % of cells,
with the others off; the tension filter should exclude them); all. Per seed,
configuration and method: recovered minus true median ν per frequency (true
median over the included cells), the included count, (emulator) how often
the 95 % interval (`analysis.invert.intervals`) holds the true ν, and what the
filters' exclusions alone do
(`exclusion_shift`: the true median over the included cells minus the true
median over all non-blebbing cells); then the mean over the seeds.

The forward model is the fast solver (`--forward solver`, the default) or the
shipped emulator (`--forward emulator`, within 0.05 % of the solver and
instant). A seed's cells draw the same random numbers whatever errors are on
(an error switched off is multiplied by 0), so the seven configurations of a
seed ask the forward model the same questions: the answers are memoised, and
with `--cache FILE` kept in FILE (a pickle this script writes) for reruns.

    python bench/error_sources.py [SEED ...] [--forward solver|emulator] [--cache FILE]
        (default seeds 6 7 8 9)
"""

import argparse
import json
import pickle
import sys
from pathlib import Path

import numpy as np


from analysis.afm.synth import cells as synth
from analysis.afm.analyze import analyze_cells
from analysis.invert.method import choose
from analysis.calibration.file import load_calibration

ALL = dict(synth.ERRORS)
ONLY = {"none": {}, "volume": {"volume_rel_sd"}, "height": {"height_offset_sd_um"},
        "force_noise": {"force_noise_nN"}, "drift": {"drift_nN_per_s"}, "blebbing": {"bleb_fraction"},
        "all": set(ALL)}


def emulator_forward(emu, bending="standard"):
    from solver.geometry import cell_radius

    def forward(volume, heights, bulk, shear, tension):
        h = heights / (2.0 * float(cell_radius(volume)))
        return emu.modulus(h, bulk, shear / bulk, tension, volume, bending)
    return forward


def run_seed(seed, cal, emu, forward):
    from roundtrip import score      # bench/roundtrip.py (bench/ is first on the path)
    rows = []
    for name, keep in ONLY.items():
        synth.ERRORS.update({k: (v if k in keep else 0.0) for k, v in ALL.items()})
        try:
            cells, truth = synth.generate(85, seed, errors=True, forward=forward)
        finally:
            synth.ERRORS.update(ALL)
        row = {"seed": seed, "errors_on": name}
        for method in ("emulator", "law"):
            table, _ = analyze_cells(cells, choose(method, cal, emu), "standard", None)
            s = score(table, truth)
            row[method] = {"n_included": s["n_included"], "n_curves": s["n_curves"],
                           "coverage_95": s.get("coverage_95"),
                           "median_error": {f: round(v["median_nu"] - v["median_nu_true"], 4)
                                            for f, v in s["per_frequency"].items()},
                           "exclusion_shift": {f: round(v["median_nu_true"] - truth["frequencies"][str(float(f))]
                                                        ["median_nu_true"], 4) for f, v in s["per_frequency"].items()}}
        rows.append(row)
        print(json.dumps(row), file=sys.stderr, flush=True)
    return rows


def mean_over_seeds(rows):
    out = []
    for name in ONLY:
        sel = [r for r in rows if r["errors_on"] == name]
        row = {"errors_on": name, "seeds": len(sel)}
        for method in ("emulator", "law"):
            m = [r[method] for r in sel]
            freqs = m[0]["median_error"]
            cov = [x["coverage_95"] for x in m if x["coverage_95"] is not None]
            row[method] = {"n_included": sum(x["n_included"] for x in m), "n_curves": sum(x["n_curves"] for x in m),
                           "coverage_95": (float(np.sum([c * x["n_included"] for c, x in zip(cov, m)])
                                                 / sum(x["n_included"] for x in m)) if cov else None),
                           "median_error_mean": {f: round(float(np.mean([x["median_error"][f] for x in m])), 4)
                                                 for f in freqs},
                           "median_error_max_abs": {f: round(float(np.max([abs(x["median_error"][f]) for x in m])), 4)
                                                    for f in freqs},
                           "exclusion_shift_mean": {f: round(float(np.mean([x["exclusion_shift"][f] for x in m])), 4)
                                                    for f in freqs}}
        out.append(row)
    return out


def main():
    from roundtrip import memoised
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("seeds", nargs="*", type=int, default=[6, 7, 8, 9])
    p.add_argument("--forward", choices=("solver", "emulator"), default="solver")
    p.add_argument("--cache", type=Path, help="pickle of the forward model's answers (read if present, written)")
    a = p.parse_args()
    file = load_calibration()
    cal, emu = file.calibration, file.emulator
    base = synth.solver_forward("standard") if a.forward == "solver" else emulator_forward(emu)
    cache = pickle.loads(a.cache.read_bytes()) if a.cache and a.cache.is_file() else {}
    forward = memoised(base, cache)
    rows = []
    for seed in a.seeds:
        rows += run_seed(seed, cal, emu, forward)
        if a.cache:
            a.cache.write_bytes(pickle.dumps(cache))
    print(json.dumps({"benchmark": "error_sources", "forward": a.forward, "seeds": a.seeds, "cells": 85,
                      "rows": rows, "mean_over_seeds": mean_over_seeds(rows)}))


if __name__ == "__main__":
    main()
