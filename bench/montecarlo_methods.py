"""The paper campaign's Monte-Carlo study (SPEC 5) by both methods (issue 13,
item 6): the trial cells of the store (volume and heights seen with errors)
inverted with the shipped calibration by the emulator and by the law. Prints
one JSON object: per (true ν, height-error mode) and method, the median over
studies of the per-study median and IQR of ν, and the excluded fraction.

    python bench/montecarlo_methods.py [STORE] [STUDIES]   (default results/paper.h5, 20 studies)
"""

import json
import sys
from pathlib import Path


from analysis.invert.measurement_errors import MeasurementErrors
from analysis.invert.method import invert_rows
from analysis.calibration.command.pipeline import read_store
from analysis.calibration.file import load_calibration


def main():
    store = Path(sys.argv[1] if len(sys.argv) > 1 else "results/paper.h5")
    n_studies = int(sys.argv[2]) if len(sys.argv) > 2 else 20
    if not store.is_file():
        raise SystemExit(f"bench: {store}: no such store (run campaigns/paper.toml into it first, "
                         "README's tour)")
    _, trials = read_store(store)
    trials = trials[(trials["state"] == "done") & (trials["study"] < n_studies)]
    file = load_calibration()
    cal, emu = file.calibration, file.emulator
    rows = trials.rename(columns={"trial_id": "cell_id", "volume_used_um3": "volume_um3"})
    rows = rows.assign(tension_mN_per_m=rows["tension_seen_mN_per_m"])
    meta = trials.groupby("trial_id")[["nu_true", "height_error_mode", "study"]].first()
    out = {"benchmark": "montecarlo_methods", "store": str(store), "studies": n_studies, "rows": []}
    for method in ("emulator", "law"):
        t = invert_rows(rows[["cell_id", "h_tilde", "modulus_mN_per_m", "tension_mN_per_m", "volume_um3"]],
                        method, cal, emu, "standard", MeasurementErrors(draws=10))
        t = t.join(meta, on="cell_id")
        for (nu, mode), g in t.groupby(["nu_true", "height_error_mode"]):
            ok = g[g["excluded_reason"].isna()]
            per = ok.groupby("study")["nu"]
            q = per.quantile([0.25, 0.75]).unstack()
            out["rows"].append({"method": method, "nu_true": float(nu), "height_error_mode": mode,
                                "median": float(per.median().median()),
                                "iqr": float((q[0.75] - q[0.25]).median()),
                                "excluded_fraction": float(1 - len(ok) / len(g)), "cells": int(len(g))})
    print(json.dumps(out))


if __name__ == "__main__":
    main()
