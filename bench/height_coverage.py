"""How often the 95 % intervals hold the true ν with only the height error on
(issue 13, item 6). Prints one JSON object.

Synthetic experiments (`cortex afm synth`'s cells, 85 per seed) with only the
recorded-height offset on (SD 0.5 µm, one per cell) and the shipped emulator
as the forward model (so the interval's own model is exactly the truth's),
analysed by the emulator method. All in l = ln K̃_S: l* the fit, l_true the
truth, [lo, hi] the interval `analysis.invert.intervals` reports (the percentiles of
the refits of the drawn truths). Reported per draw count: its coverage,
how often the truth falls below / above it, and, split by the sign of the
cell's offset δ (recorded minus true height, read off the recording's first
sample, 0.78 D), the coverage, the mean of (l* − l_true) and the mean of the
interval's midpoint (lo + hi)/2 − l*.

    python bench/height_coverage.py [SEED ...] [--draws N ...]   (default seeds 6 7 8 9, draws 100)
"""

import argparse
import json
import sys

import numpy as np


from analysis.afm.synth import cells as synth
from analysis.afm.analyze import analyze_cells
from analysis.invert.method import choose
from analysis.invert.measurement_errors import MeasurementErrors
from analysis.calibration.file import load_calibration


def curves(seeds, emu, draws):
    """One row per included curve: l*, l_true, lo, hi (ln K̃_S) and the cell's offset δ (µm)."""
    from error_sources import emulator_forward
    keep = dict(synth.ERRORS)
    synth.ERRORS.update({k: (v if k == "height_offset_sd_um" else 0.0) for k, v in keep.items()})
    rows = []
    try:
        for seed in seeds:
            cells, truth = synth.generate(85, seed, errors=True, forward=emulator_forward(emu))
            offset = {c.cell_id: float(c.height_um[0] - 0.78 * t["diameter_um"]) for c, t in zip(cells, truth["cells"])}
            table, _ = analyze_cells(cells, choose("emulator", None, emu), "standard", MeasurementErrors(draws=draws, seed=seed))
            for r in table[table["excluded_reason"].isna()].itertuples():
                t = truth["frequencies"][str(float(r.frequency_hz))]["cells"][r.cell_id]
                rows.append((np.log(r.ks_tilde), np.log(t["ks_tilde"]), np.log(r.ks_lo95), np.log(r.ks_hi95),
                             offset[r.cell_id]))
    finally:
        synth.ERRORS.update(keep)
    return np.array(rows)


def summary(a):
    l, lt, lo, hi, d = a.T
    inside = (lo <= lt) & (lt <= hi)
    out = {"curves": int(len(a)), "coverage": float(inside.mean()),
           "truth_below_interval": float(np.mean(lt < lo)), "truth_above_interval": float(np.mean(lt > hi)),
           "rms_error_ln_ks": float(np.sqrt(np.mean((l - lt) ** 2))),
           "median_half_width_ln_ks": float(np.median((hi - lo) / 2)), "by_offset_sign": {}}
    for name, sel in (("offset_up", d > 0), ("offset_down", d < 0)):
        out["by_offset_sign"][name] = {
            "curves": int(sel.sum()), "coverage": float(inside[sel].mean()),
            "mean_error_ln_ks": float(np.mean(l[sel] - lt[sel])),
            "mean_midpoint_shift_ln_ks": float(np.mean((lo[sel] + hi[sel]) / 2 - l[sel]))}
    return out


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("seeds", nargs="*", type=int, default=[6, 7, 8, 9])
    p.add_argument("--draws", nargs="+", type=int, default=[100])
    a = p.parse_args()
    emu = load_calibration().emulator
    out = {"benchmark": "height_coverage", "seeds": a.seeds, "cells": 85, "runs": []}
    for draws in a.draws:
        out["runs"].append({"draws": draws, **summary(curves(a.seeds, emu, draws))})
        print(json.dumps(out["runs"][-1]), file=sys.stderr, flush=True)
    print(json.dumps(out))


if __name__ == "__main__":
    main()
