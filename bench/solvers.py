"""Speed and agreement of the two shell solvers; prints one JSON object.

fast_median_s: median wall time of the fast solver per compression over the
paper grid (SPEC 4; all 540 compressions, or a random sample of --sample),
one core, default resolution (K within 0.1 % of its mesh limit);
fast_median_cpu_s the same in CPU time of the process (user + system), which
other jobs on a shared machine inflate far less than the wall time.
explicit_median_s (and _cpu_s): the same for the explicit scheme at its
default resolution on --explicit common points (corners of the grid, the
bending variants in turn). speedup = explicit_median_s / fast_median_s,
speedup_cpu the same in CPU time.
max_rel_diff_K: largest |K_fast / K_explicit - 1| on the common points.
fast_failed counts solves that raised (each says why).
"""

import argparse
import itertools
import json
import time

import numpy as np

from solver.compression import compress
from common.errors import SolverError
from solver.model import Shell

GRID = dict(shear=(8.33, 10.0, 15.0, 20.0, 25.0), h0=(15.0, 14.0, 13.0, 12.0, 11.0, 10.0),
            tension=(0.5, 1.0, 1.5, 2.0, 2.5, 3.0), bending=("standard", "double", "none"))
# the grid's corners, all bending variants, ordered so that any first few span the variants
CORNERS = [(8.33, 15.0, 0.5, "standard"), (25.0, 10.0, 3.0, "double"), (8.33, 10.0, 3.0, "none"),
           (25.0, 15.0, 0.5, "standard"), (8.33, 15.0, 0.5, "double"), (25.0, 10.0, 3.0, "none"),
           (8.33, 10.0, 3.0, "standard"), (25.0, 15.0, 0.5, "double"), (8.33, 15.0, 0.5, "none"),
           (25.0, 10.0, 3.0, "standard"), (8.33, 10.0, 3.0, "double"), (25.0, 15.0, 0.5, "none")]


def shell(ks, h0, g, b):
    return Shell(volume_um3=4300.0, h0_um=h0, bulk_mN_per_m=25.0, shear_mN_per_m=ks,
                 tension_mN_per_m=g, bending=b)


def timed(point, method):
    """K, wall and CPU seconds of one compression."""
    start, cpu = time.perf_counter(), time.process_time()
    try:
        K = compress(shell(*point), method).to_dict()["modulus_mN_per_m"]
    except SolverError:
        K = float("nan")
    return K, time.perf_counter() - start, time.process_time() - cpu


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sample", type=int, default=0, help="fast solves on this many random grid points (0: all 540)")
    ap.add_argument("--explicit", type=int, default=3, help="common points for the explicit solver (0: none; 1-3 min each)")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    points = list(itertools.product(*GRID.values()))
    if args.sample:
        rng = np.random.default_rng(args.seed)
        points = [points[i] for i in rng.choice(len(points), args.sample, replace=False)]
    timed(points[0], "fast")                      # imports and first-call set-up
    fast = [timed(p, "fast") for p in points]
    K, wall, cpu = (np.array(x) for x in zip(*fast))
    out = {"fast_points": len(points), "fast_failed": int(np.sum(~np.isfinite(K))),
           "fast_median_s": float(np.median(wall)), "fast_median_cpu_s": float(np.median(cpu)),
           "fast_p90_s": float(np.percentile(wall, 90)), "fast_total_s": float(wall.sum()),
           "K_min_mN_per_m": float(np.nanmin(K)), "K_max_mN_per_m": float(np.nanmax(K))}
    common = CORNERS[: args.explicit]
    if common:
        pairs = [(timed(p, "fast")[0], *timed(p, "explicit")) for p in common]
        kf, ke, te, ce = (np.array(x) for x in zip(*pairs))
        out["explicit_points"] = [list(p) for p in common]
        out["explicit_median_s"] = float(np.median(te))
        out["explicit_median_cpu_s"] = float(np.median(ce))
        out["speedup"] = out["explicit_median_s"] / out["fast_median_s"]
        out["speedup_cpu"] = out["explicit_median_cpu_s"] / out["fast_median_cpu_s"]
        out["max_rel_diff_K"] = float(np.nanmax(np.abs(kf / ke - 1.0)))
        out["K_fast_mN_per_m"] = [round(float(k), 4) for k in kf]
        out["K_explicit_mN_per_m"] = [round(float(k), 4) for k in ke]
    else:
        out.update(explicit_median_s=None, explicit_median_cpu_s=None, speedup=None, speedup_cpu=None,
                   max_rel_diff_K=None)
    print(json.dumps(out))


if __name__ == "__main__":
    main()
