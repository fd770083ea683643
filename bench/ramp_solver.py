"""Benchmark of `solver.ramp.ramp_forces_nN` over the corners of the
physiological range: R 5 and 10 µm, γ_a 0.2 and 2 mN/m, K_B 5 and 50 mN/m,
K_S/K_B 0.1 and 2, bending standard, double and none (48 ramps of 50 depths,
δ/R from 0.005 to 1, log-spaced). Each corner is also run at twice the
resolution; the worst relative change of F over δ/R 0.01-1 is reported,
and the worst in the bands 0.01-0.03, 0.03-0.1 and 0.1-1.
Prints one JSON object: converged count, failures, worst refinement change
(and where), seconds per ramp at the default resolution.

    .venv/bin/python bench/ramp_solver.py [--quick]   (--quick: R 5 only)
"""

import itertools
import json
import sys
import time

import numpy as np

from common.errors import SolverError
from solver.ramp import RESOLUTION, ramp_forces_nN

DEPTHS = np.geomspace(0.005, 1.0, 50)     # δ/R
CHECKED = DEPTHS >= 0.01                   # where refinement is judged
BANDS = ((0.01, 0.03), (0.03, 0.1), (0.1, 1.01))   # δ/R bands of the worst change


def corner(radius, gamma, bulk, ks, bending):
    """(seconds, forces at RESOLUTION, forces at twice that) of one corner."""
    volume = 4.0 * np.pi / 3.0 * radius**3
    args = (volume, DEPTHS * radius, bulk, ks * bulk, gamma, bending)
    start = time.perf_counter()
    coarse = ramp_forces_nN(*args)
    seconds = time.perf_counter() - start
    return seconds, coarse, ramp_forces_nN(*args, resolution=2.0 * RESOLUTION)


def main():
    radii = (5.0,) if "--quick" in sys.argv else (5.0, 10.0)
    ramp_forces_nN(4.0 * np.pi / 3.0 * 125.0, [0.5], 5.0, 5.0, 1.0)     # load the compiled code
    seconds, failures, worst = [], [], (0.0, None)
    bands = dict.fromkeys((f"{lo:g}-{min(hi, 1.0):g}" for lo, hi in BANDS), 0.0)
    for c in itertools.product(radii, (0.2, 2.0), (5.0, 50.0), (0.1, 2.0), ("standard", "double", "none")):
        try:
            s, coarse, fine = corner(*c)
        except SolverError as err:
            failures.append({"corner": c, "error": str(err)})
            continue
        seconds.append(s)
        for (lo, hi), key in zip(BANDS, bands):
            inside = (DEPTHS >= lo) & (DEPTHS < hi)
            bands[key] = max(bands[key], float(np.abs(fine / coarse - 1.0)[inside].max()))
        change = np.abs(fine / coarse - 1.0)[CHECKED]
        if change.max() > worst[0]:
            worst = (float(change.max()), {"corner": c, "depth_over_R": float(DEPTHS[CHECKED][change.argmax()])})
    print(json.dumps({"ramps": len(seconds) + len(failures), "converged": len(seconds),
                      "failures": failures, "depths": DEPTHS.size, "resolution": RESOLUTION,
                      "worst_refinement_change": worst[0], "worst_at": worst[1],
                      "worst_refinement_change_by_depth_over_R": bands,
                      "seconds_per_ramp_mean": float(np.mean(seconds)) if seconds else None,
                      "seconds_per_ramp_max": float(np.max(seconds)) if seconds else None}, indent=1))


if __name__ == "__main__":
    main()
