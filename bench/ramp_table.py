"""Accuracy of the shell ramp table (`analysis.calibration.ramp_table`), two parts:

`table`: the model `shell_ramp.force_nN` with the shipped table against the solver
it was built from (`shell_table.unit_forces`, the table's resolution) off the grid:
30 seeded random cells (γ̃_a 0.004-0.4, K̃_S 0.1-2, R 5-10 µm, log-uniform but R),
14 depths each, δ/R 0.0015-0.3 log-spaced: median, 95th percentile and worst
relative error of F, the worst per band of δ/R.

`solver`: the solver's own mesh error at the table's depths below δ/R = 0.025: the
force at the table's resolution (2) against 4× that (8), at the corners of the
table's grid (γ̃_a 0.003, 0.019, 0.124, 0.5; K̃_S 0.08, 0.45, 2.5; R 4, 7.3, 13.5 µm;
a corner whose fine continuation stalls is counted, not judged), and the
tension-only shell (K_B = K_S = 0.003 γ_a, no bending, R = 6.8 µm) against the
exact droplet at resolution 2 and 8: the worst relative change per depth.
Prints one JSON object.

    .venv/bin/python bench/ramp_table.py [table|solver]   (default: both)
"""

import itertools
import json
import sys

import numpy as np

from analysis.afm.tension import shell_ramp
from analysis.afm.tension.shell_table import DEPTHS, GAMMAS, RADII_UM, SHEARS, unit_forces
from common.errors import SolverError
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


def solver() -> dict:
    """The solver's mesh error at small depths (module doc)."""
    changes, stalled = [], 0
    for g, s, r in itertools.product(GAMMAS[[0, 4, 8, -1]], SHEARS[[0, 4, -1]], RADII_UM[[0, 2, -1]]):
        coarse = unit_forces(g, s, LOW, radius_um=r)
        volume = 4.0 * np.pi * r ** 3 / 3.0
        try:
            fine = ramp_forces_nN(volume, LOW * r, 10.0, 10.0 * s, 10.0 * g, resolution=FINE) / (10.0 * r)
        except SolverError:
            stalled += 1
            continue
        changes.append(fine / coarse - 1.0)
    r, k = 6.8, 0.003
    volume = 4.0 * np.pi * r ** 3 / 3.0
    exact = force_per_tension_um(volume, 2.0 * r - LOW * r)
    droplet = {f"resolution_{res:g}": _change([ramp_forces_nN(volume, LOW * r, k, k, 1.0, "none", resolution=res)
                                               / exact - 1.0]) for res in (2.0, FINE)}
    return {"corners": len(changes) + stalled, "fine_stalled": stalled, "fine_resolution": FINE,
            "worst_rel_change_by_depth_over_R": _change(changes),
            "tension_only_vs_droplet_by_depth_over_R": droplet}


def main() -> None:
    parts = sys.argv[1:] or ["table", "solver"]
    out = {p: {"table": table, "solver": solver}[p]() for p in parts}
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
