"""Whether a cell's standard error of ln K̃_S (`ln_ks_se` in cells.csv, from the bootstrap
draws the protocol admits) is the size of its actual error, per error source and before /
after the published filters. Prints one JSON object.

Synthetic experiments (`cortex afm synth`'s cells, 85 per seed) with the shipped
emulator as the forward model (the intervals' own model is the truth's) and one
error source on at a time (height offset, volume, force noise and drift) or all,
analysed by the emulator method with the same error sizes. Per run and per set of
curves (the included ones, every curve with a finite fit, the excluded ones): the
count, the RMS of the error e = ln K̃_S − ln K̃_S,true, its mean, the RMS of
`ln_ks_se`, their ratio, and how often [ks_lo95, ks_hi95] holds the truth.

    python bench/bootstrap_se.py [SEED ...] [--sources all height volume noise]   (default seeds 6 7)
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

SOURCES = {"all": None, "height": ("height_offset_sd_um",), "volume": ("volume_rel_sd",),
           "noise": ("force_noise_nN", "drift_nN_per_s")}


def curves(seeds, emu, source):
    """One row per curve with a finite fit: error, ln_ks_se, ln lo, ln hi, true l, excluded (0/1)."""
    from error_sources import emulator_forward      # bench/ is first on the path
    keep, on = dict(synth.ERRORS), SOURCES[source]
    synth.ERRORS.update({k: (v if on is None or k in on else 0.0) for k, v in keep.items()})
    err = MeasurementErrors(volume_rel_sd=synth.ERRORS["volume_rel_sd"],
                            height_sd_um=synth.ERRORS["height_offset_sd_um"])
    rows = []
    try:
        for seed in seeds:
            cells, truth = synth.generate(85, seed, errors=True, forward=emulator_forward(emu))
            table, _ = analyze_cells(cells, choose("emulator", None, emu), "standard", err)
            for r in table[np.isfinite(table["ks_tilde"].astype(float))].itertuples():
                lt = np.log(truth["frequencies"][str(float(r.frequency_hz))]["cells"][r.cell_id]["ks_tilde"])
                rows.append((np.log(r.ks_tilde) - lt, r.ln_ks_se, np.log(r.ks_lo95), np.log(r.ks_hi95), lt,
                             float(isinstance(r.excluded_reason, str))))
    finally:
        synth.ERRORS.update(keep)
    return np.array(rows, float)


def summary(a):
    e, se, lo, hi, lt, ex = a.T
    out = {}
    for name, sel in (("included", ex == 0), ("all_finite", ex >= 0), ("excluded", ex == 1)):
        rms_e, rms_se = np.sqrt(np.mean(e[sel] ** 2)), np.sqrt(np.nanmean(se[sel] ** 2))
        out[name] = {"curves": int(sel.sum()), "rms_error_ln_ks": float(rms_e), "mean_error_ln_ks": float(e[sel].mean()),
                     "rms_ln_ks_se": float(rms_se), "se_over_error": float(rms_se / rms_e),
                     "coverage": float(np.mean((lo[sel] <= lt[sel]) & (lt[sel] <= hi[sel])))}
    return out


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("seeds", nargs="*", type=int, default=[6, 7])
    p.add_argument("--sources", nargs="+", choices=list(SOURCES), default=list(SOURCES))
    a = p.parse_args()
    emu = load_calibration().emulator
    out = {"benchmark": "bootstrap_se", "seeds": a.seeds, "cells": 85, "runs": []}
    for source in a.sources:
        out["runs"].append({"errors": source, **summary(curves(a.seeds, emu, source))})
        print(json.dumps(out["runs"][-1]), file=sys.stderr, flush=True)
    print(json.dumps(out))


if __name__ == "__main__":
    main()
