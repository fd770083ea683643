"""Reconstruction check by both methods (issue 13, item 6): every simulated
K(h̃) curve of the paper campaign's store inverted as a measured cell (γ_a
known, V = 4300 µm³, the published filters) with the shipped calibration, by
the emulator and by the law. Prints one JSON object: per bending variant and
method the largest and RMS |ν - ν_true| and the number of curves included.

    python bench/reconstruction.py [STORE]       (default results/paper.h5)
"""

import json
import sys
from pathlib import Path

import numpy as np


from analysis.invert.measurement_errors import MeasurementErrors
from analysis.invert.method import invert_rows
from analysis.calibration.command.pipeline import read_store
from analysis.calibration.file import load_calibration
from solver.elasticity import poisson_ratio


def main():
    store = Path(sys.argv[1] if len(sys.argv) > 1 else "results/paper.h5")
    if not store.is_file():
        raise SystemExit(f"bench: {store}: no such store (run campaigns/paper.toml into it first, "
                         "README's tour)")
    results, _ = read_store(store)
    results = results[results["state"] == "done"]
    file = load_calibration()
    cal, emu = file.calibration, file.emulator
    out = {"benchmark": "reconstruction", "store": str(store), "variants": {}}
    for bending, g in results.groupby("bending"):
        rows = g.assign(cell_id=[f"{s:g}/{t:g}" for s, t in zip(g["shear_mN_per_m"], g["tension_mN_per_m"])])
        truth = {c: poisson_ratio(b, s) for c, b, s in zip(rows["cell_id"], rows["bulk_mN_per_m"],
                                                         rows["shear_mN_per_m"])}
        rows = rows[["cell_id", "h_tilde", "modulus_mN_per_m", "tension_mN_per_m", "volume_um3"]]
        res = {}
        for method in ("emulator", "law"):
            t = invert_rows(rows, method, cal, emu, bending, MeasurementErrors(draws=20))
            ok = t[t["excluded_reason"].isna()]
            err = np.abs(ok["nu"].to_numpy() - ok["cell_id"].map(truth).to_numpy())
            res[method] = {"n_curves": len(t), "n_included": len(ok), "max_abs_err": float(err.max()),
                           "rms_err": float(np.sqrt(np.mean(err**2)))}
        out["variants"][bending] = res
    print(json.dumps(out))


if __name__ == "__main__":
    main()
