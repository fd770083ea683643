"""Off-grid noise-free curves from the solver inverted through `cortex analysis
invert` with the shipped calibration, by both methods (issue 13: |ν - ν_true| ≤
0.02 for every curve with the emulator). Prints one JSON object.

Curves (seeded): K̃_S 0.05-5 and γ_a/K_B 0.01-0.25 uniform in their logarithms,
V 3200-6300 µm³, K_B 15-35 mN/m, standard bending; heights h̃ from 0.745 down
to 0.5 in 8 steps (a 0.5 µm compression centred on each, as `cortex afm synth`
does). The table is written to a temporary folder and the command run on it.

    python bench/offgrid_invert.py [N_CURVES]       (default 24)
"""

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

from analysis.afm.synth.cells import solver_forward
from solver.elasticity import poisson_of_ratio
from solver.geometry import cell_radius

H_TILDES = np.linspace(0.745, 0.5, 8)


def curves(n, rng):
    forward = solver_forward("standard")
    rows, truth = [], {}
    for i in range(n):
        ks = float(np.exp(rng.uniform(np.log(0.05), np.log(5.0))))
        gt = float(np.exp(rng.uniform(np.log(0.01), np.log(0.25))))
        V, bulk = rng.uniform(3200.0, 6300.0), rng.uniform(15.0, 35.0)
        heights = H_TILDES * 2.0 * float(cell_radius(V))
        K = forward(V, heights, bulk, ks * bulk, gt * bulk)
        cid = f"c{i:02d}"
        truth[cid] = {"nu": float(poisson_of_ratio(ks)), "ks_tilde": ks, "gamma_tilde": gt, "volume_um3": V,
                      "bulk_mN_per_m": bulk}
        rows += [{"cell_id": cid, "h_tilde": h, "modulus_mN_per_m": k, "tension_mN_per_m": gt * bulk,
                  "volume_um3": V} for h, k in zip(H_TILDES, K)]
    return pd.DataFrame(rows), truth


def invert(table_path, out_dir, method):
    exe = Path(sys.executable).with_name("cortex")
    run = subprocess.run([str(exe), "analysis", "invert", str(table_path), "--out", str(out_dir), "--method",
                          method, "--json"], capture_output=True, text=True, env=dict(os.environ))
    if run.returncode != 0:
        raise SystemExit(f"cortex analysis invert failed ({run.returncode}): {run.stderr.strip()}")
    return {r["cell_id"]: r for r in json.loads(run.stdout)}


def main():
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 24
    table, truth = curves(n, np.random.default_rng(2024))
    out = {"benchmark": "offgrid_invert", "n_curves": n, "curves": []}
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "table.csv"
        table.to_csv(path, index=False)
        res = {m: invert(path, Path(tmp) / m, m) for m in ("emulator", "law")}
    for cid, t in truth.items():
        e, law = res["emulator"][cid], res["law"][cid]
        out["curves"].append({"cell_id": cid, **t, "nu_emulator": e["nu"], "nu_lo95": e["nu_lo95"],
                              "nu_hi95": e["nu_hi95"], "excluded_emulator": e["excluded_reason"],
                              "nu_law": law["nu"], "excluded_law": law["excluded_reason"]})
    err_e = np.array([abs(c["nu_emulator"] - c["nu"]) for c in out["curves"]])
    err_l = np.array([abs(c["nu_law"] - c["nu"]) if c["nu_law"] is not None else np.nan for c in out["curves"]])
    out["emulator_max_abs_err"] = float(np.max(err_e))
    out["law_max_abs_err"] = float(np.nanmax(err_l))
    out["law_median_abs_err"] = float(np.nanmedian(err_l))
    out["target_max_abs_err"] = 0.02
    print(json.dumps(out))


if __name__ == "__main__":
    main()
