"""The viscoelastic reading (SPEC 10): the complex table against the solver, round trips,
the speed of the analysis. Prints one JSON object.

`table`: ln C = ln(K*/K) from the shipped table (`analysis.calibration.viscoelastic_table`) against
`solver.viscoelastic` at random points between its nodes (seeded; h̃ 0.45-0.82, K̃_S
0.05-5 and γ̃_a 0.01-0.25 uniform in their logarithms, δ_B and δ_S 0-0.9 rad, V 3000-6500
µm³): the largest and RMS error of the phase (rad) and of ln |C| (the relative error of
|K*|).
`round_trips`: synthetic experiments of 85 cells made with the complex emulator forward
model (`cortex afm synth --solver emulator`), analysed like measured ones: errors off
(β_B 0.1, β_S 0.3), errors on (0.1 vs 0.3 and 0.2 vs 0.2, seeds 1-3): the largest error
of each cell's β and loss angles, population medians against the truth's, the share of
cells whose 95 % intervals hold their true β (and pooled over the errors-on trips), and
the paired test.
`speed`: 100 cells × 4 frequencies, the viscoelastic part (fits with intervals) timed alone.

    python bench/viscoelastic.py [N_TABLE_POINTS]     (default 30)
"""

import json
import sys
import time

import numpy as np


from analysis.afm.synth import cells as sy
from analysis.afm.analyze import analyze_cells
from analysis.invert.method import choose
from analysis.afm.rheology import analyze as rheology
from analysis.afm.synth.rheology import ViscoelasticForward, emulator_complex
from analysis.invert.measurement_errors import MeasurementErrors
from analysis.calibration.file import load_calibration
from solver.geometry import cell_radius
from solver.model import Shell
from solver.viscoelastic import correction, hessian_parts


def table_error(n, seed=3):
    rng = np.random.default_rng(seed)
    table, errs = load_calibration().viscoelastic.table, []
    while len(errs) < n:
        ht, v = rng.uniform(0.45, 0.82), rng.uniform(3000, 6500)
        ks, g = np.exp(rng.uniform(np.log(0.05), np.log(5))), np.exp(rng.uniform(np.log(0.01), np.log(0.25)))
        db, ds = rng.uniform(0, 0.9, 2)
        shell = Shell(volume_um3=v, h0_um=ht * 2 * float(cell_radius(v)) + 0.25, bulk_mN_per_m=25.0,
                      shear_mN_per_m=25.0 * ks, tension_mN_per_m=25.0 * g)
        try:
            exact = np.log(correction(hessian_parts(shell), db, ds, 1.0))
        except Exception:        # noqa: BLE001 (a point without a smooth linear response: skipped)
            continue
        errs.append(table.log_factor(ht, ks, g, db, ds, v) - exact)
    e = np.array(errs)
    return {"points": n, "phase_max_abs_rad": float(np.abs(e.imag).max()),
            "phase_rms_rad": float(np.sqrt(np.mean(e.imag**2))),
            "modulus_max_rel": float(np.abs(e.real).max()), "modulus_rms_rel": float(np.sqrt(np.mean(e.real**2)))}


def experiment(bulk, shear, errors, n_cells=85, seed=1):
    cells, truth = sy.generate(n_cells, seed, errors=errors,
                               forward=ViscoelasticForward(bulk, shear, emulator_complex(load_calibration().viscoelastic),
                                                           seed=seed))
    return cells, truth


def analyse(cells):
    model = load_calibration().viscoelastic
    table, segs = analyze_cells(cells, choose("emulator", None, model.emulator), "standard", MeasurementErrors())
    start = time.perf_counter()
    table, rheo, summ = rheology(table, segs, model, "standard", MeasurementErrors())
    return table, rheo, summ, time.perf_counter() - start


def compare(truth, table, rheo, summ):
    cells = {c["cell_id"]: c for c in truth["cells"]}
    out = {"n_cells": int(len(rheo))}
    for name in ("bulk", "shear"):
        t = rheo["cell_id"].map(lambda c: cells[c][f"{name}_exponent"]).to_numpy()
        est = rheo[f"{name}_exponent"].to_numpy()
        inside = (rheo[f"{name}_exponent_lo95"] <= t) & (t <= rheo[f"{name}_exponent_hi95"])
        out[name] = {"max_abs_error": float(np.max(np.abs(est - t))), "median": float(np.median(est)),
                     "median_true": float(np.median(t)), "interval_coverage": float(np.mean(inside))}
        ok = table["bulk_loss_angle_rad"].notna()
        tl = [cells[c]["frequencies"][f][f"{name}_loss_angle_rad"] for c, f in
              zip(table.loc[ok, "cell_id"], table.loc[ok, "frequency_hz"])]
        el = table.loc[ok, f"{name}_loss_angle_rad"].to_numpy()
        lo, hi = table.loc[ok, f"{name}_loss_angle_lo95_rad"], table.loc[ok, f"{name}_loss_angle_hi95_rad"]
        out[name]["loss_angle_max_abs_error_rad"] = float(np.max(np.abs(el - tl)))
        out[name]["loss_angle_interval_coverage"] = float(np.mean((lo <= tl) & (np.asarray(tl) <= hi)))
    out["paired_test"] = {k: summ["paired_test"][k] for k in ("median_difference", "p_value_greater",
                                                               "p_value_two_sided", "shear_exponent_greater")}
    return out


SEEDS = (1, 2, 3)


def pooled(trips):
    """The share of cells (over every errors-on round trip) whose 95 % intervals hold the true β."""
    out = {}
    for name in ("bulk", "shear"):
        n = sum(t["n_cells"] for k, t in trips.items() if k.startswith("errors_on"))
        hit = sum(t["n_cells"] * t[name]["interval_coverage"] for k, t in trips.items() if k.startswith("errors_on"))
        out[f"{name}_exponent"] = hit / n
    return out


def main():
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 30
    result = {"table": table_error(n), "round_trips": {}}
    cases = {"errors_off_0.1_0.3": (0.1, 0.3, False, 1)}
    for seed in SEEDS:
        cases[f"errors_on_0.1_0.3_seed{seed}"] = (0.1, 0.3, True, seed)
        cases[f"errors_on_0.2_0.2_seed{seed}"] = (0.2, 0.2, True, seed)
    for label, (b, s, err, seed) in cases.items():
        cells, truth = experiment(b, s, err, seed=seed)
        table, rheo, summ, _ = analyse(cells)
        result["round_trips"][label] = compare(truth, table, rheo, summ)
    result["pooled_interval_coverage_errors_on"] = pooled(result["round_trips"])
    sy.SUBSETS = (((0.02, 0.1, 1.0, 10.0), 100),)          # every cell at four frequencies
    cells, _ = experiment(0.1, 0.3, True, n_cells=100, seed=7)
    table, rheo, summ, wall = analyse(cells)
    result["speed"] = {"cells": 100, "frequencies": 4, "curves": int(table["bulk_loss_angle_rad"].notna().sum()),
                       "draws": MeasurementErrors().draws, "viscoelastic_wall_s": wall}
    print(json.dumps(result))


if __name__ == "__main__":
    main()
