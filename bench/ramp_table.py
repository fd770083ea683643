"""Accuracy of the shell ramp table (`analysis.calibration.ramp_table`), two parts:

`table`: the model `shell_ramp.force_nN` with the shipped table against the solver
it was built from (`shell_table.unit_forces`, the table's resolution) off the grid:
30 seeded random cells (γ̃_a 0.004-0.4, K̃_S 0.1-2, R 5-10 µm, log-uniform but R),
14 depths each, δ/R 0.0015-0.3 log-spaced: median, 95th percentile and worst
relative error of F, the worst per band of δ/R.

`solver`: the mesh error near the sphere, at the table's depths below δ/R = 0.025
and the corners of its grid (γ̃_a 0.003, 0.019, 0.124, 0.5; K̃_S 0.08, 0.45, 2.5;
R 4, 7.3, 13.5 µm): the solver at the table's two meshes (resolution 2 and 4),
the table as shipped (their Richardson extrapolation, `shell_table.richardson`)
and the extrapolation of 4 and 8, each against resolution 8 (a corner whose
resolution-8 continuation stalls is counted, not judged): the worst relative
change per depth, and the table against the extrapolation of 4 and 8; the
observed order p = log2((f4 - f2)/(f8 - f4)) per depth where resolution 2 is
more than 0.1 % off (10th percentile, median, 90th, how many); and the tension-only shell (K_B = K_S =
0.003 γ_a, no bending, R = 6.8 µm) against the exact droplet at resolution 2, 4
and 8 and extrapolated from 2 and 4.
Prints one JSON object.

    .venv/bin/python bench/ramp_table.py [table|solver]   (default: both)
"""

import itertools
import json
import sys

import numpy as np

from analysis.afm.tension import shell_ramp
from analysis.afm.tension.shell_table import DEPTHS, GAMMAS, RADII_UM, SHEARS, forces, richardson, unit_forces
from solver.droplet_table import force_per_tension_um
from solver.ramp import ramp_forces_nN

BANDS = ((0.0013, 0.005), (0.005, 0.01), (0.01, 0.02), (0.02, 0.301))
LOW = DEPTHS[DEPTHS < 0.025]
FINE = 8.0


def table() -> dict:
    """The table against the solver off the grid (module doc)."""
    rng = np.random.default_rng(0)
    depths = np.geomspace(0.0015, 0.3, 14)
    errors = []
    for _ in range(30):
        g, s = np.exp(rng.uniform(np.log([0.004, 0.1]), np.log([0.4, 2.0])))
        r = float(rng.uniform(5.0, 10.0))
        truth = unit_forces(g, s, depths, radius_um=r)
        model = shell_ramp.force_nN(depths * r, r, 10.0 * g, 10.0, s) / (10.0 * r)
        errors.append(np.abs(model / truth - 1.0))
    err = np.array(errors)
    ok = np.isfinite(err)
    by_band = {f"{lo:g}-{min(hi, 0.3):g}": float(np.nanmax(err[:, (depths >= lo) & (depths < hi)]))
               for lo, hi in BANDS}
    return {"cells": len(err), "depths": depths.size, "unsolved": int((~ok).sum()),
            "median_rel_error": float(np.median(err[ok])), "p95_rel_error": float(np.percentile(err[ok], 95)),
            "max_rel_error": float(err[ok].max()), "max_rel_error_by_depth_over_R": by_band}


def _change(forces: list[np.ndarray]) -> dict:
    worst = np.nanmax(np.abs(np.array(forces)), axis=0)
    return {f"{d:.4f}": float(w) for d, w in zip(LOW, worst)}


def _corner(g: float, s: float, r: float) -> dict[str, np.ndarray]:
    """One corner's F/(K_B R) at LOW: resolutions 2, 4 and 8 and the shipped table."""
    volume = 4.0 * np.pi * r ** 3 / 3.0
    out = {f"{res:g}": forces(volume, r, LOW, 10.0, 10.0 * s, 10.0 * g, "standard", resolution=res)
           for res in (2.0, 4.0, FINE)}
    out["table"] = shell_ramp.force_nN(LOW * r, r, 10.0 * g, 10.0, s) / (10.0 * r)
    return out


def solver() -> dict:
    """The mesh error near the sphere, the table's against resolution 8 (module doc)."""
    runs = [_corner(g, s, r) for g, s, r in itertools.product(GAMMAS[[0, 4, 8, -1]], SHEARS[[0, 4, -1]],
                                                              RADII_UM[[0, 2, -1]])]
    done = [c for c in runs if np.isfinite(c["8"]).all()]
    fine = np.array([c["8"] for c in done])
    versus = {"resolution_2": [c["2"] for c in done], "resolution_4": [c["4"] for c in done],
              "table": [c["table"] for c in done],
              "richardson_4_8": [richardson(c["4"], c["8"]) for c in done]}
    change = {k: _change(list(np.array(v) / fine - 1.0)) for k, v in versus.items()}
    change["table_vs_richardson_4_8"] = _change(list(np.array(versus["table"]) / np.array(versus["richardson_4_8"])
                                                     - 1.0))
    f2, f4 = (np.array([c[k] for c in done]) for k in ("2", "4"))
    with np.errstate(invalid="ignore"):
        order = np.log2((f4 - f2) / (fine - f4))
    order[np.abs(f2 / fine - 1.0) < 1e-3] = np.nan        # judged where the mesh error is above 0.1 %
    r, k = 6.8, 0.003
    volume = 4.0 * np.pi * r ** 3 / 3.0
    exact = force_per_tension_um(volume, 2.0 * r - LOW * r) / (k * r)        # F/(K_B R) at γ_a = 1
    droplet = {f"{res:g}": forces(volume, r, LOW, k, k, 1.0, "none", resolution=res) for res in (2.0, 4.0, FINE)}
    droplet["richardson_2_4"] = richardson(droplet["2"], droplet["4"])
    return {"corners": len(runs), "fine_stalled": len(runs) - len(done), "fine_resolution": FINE,
            "worst_rel_change_vs_resolution_8_by_depth_over_R": change,
            "observed_order_p10_median_p90_count_by_depth_over_R": {
                f"{d:.4f}": [*(float(v) for v in np.nanpercentile(o, [10, 50, 90])), int(np.isfinite(o).sum())]
                for d, o in zip(LOW, order.T) if np.isfinite(o).any()},
            "tension_only_vs_droplet_by_depth_over_R": {k: _change([v / exact - 1.0]) for k, v in droplet.items()}}


def main() -> None:
    parts = sys.argv[1:] or ["table", "solver"]
    out = {p: {"table": table, "solver": solver}[p]() for p in parts}
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
