"""Mesh convergence of a shell solver (Richardson extrapolation); prints one JSON object.

For each point, K is computed at resolutions r_1 < r_2 < ... (each the last
times q, default 1, 2, 4: every element halved per step). With the error
K(r) - K∞ ≈ C r^-p, the last three resolutions give

    p  = ln((K_a - K_b) / (K_b - K_c)) / ln q,
    K∞ = K_c + (K_c - K_b) / (q^p - 1),

(a, b, c the last three), the relative error of K at the default resolution
r_d, err_d = |K(r_d) / K∞ - 1|, and the resolution that brings the error to
0.1 %: r_d (err_d / 1e-3)^(1/p). If the differences change sign or do not shrink
(p undefined: not yet in the asymptotic range, or converged down to the
solver's noise), K∞ is the finest value, flagged `"asymptotic": false`;
`finest_change` = |K_c / K_b - 1| then bounds how far that is from K∞.

Default points: the issue's set (ν = 0 and 0.5, h0 = 10 and 15 µm, γ_a = 0.5
and 3 mN/m, K_B = 25 mN/m, bending `standard`) plus the point where the two
solvers disagreed most (h0 = 15, K_S = 25, γ_a = 3, bending `none`).
`--cache FILE` keeps every finished solve (one JSON line each) and reuses
it, so a long run can be stopped and resumed, or extended by resolutions.

The explicit scheme's cost grows as r³ (r⁵ where bending sets the time
step), 5-200 s per solve at r = 1: run it as
`nice python bench/convergence.py --solver explicit --resolutions 0.25 0.5 1
--cache /tmp/explicit.jsonl` (about 20 min for the default points).
"""

import argparse
import itertools
import json
import pathlib
import sys
import time

import numpy as np

from solver.compression import compress
from solver.elasticity import poisson_ratio
from common.errors import InputError, SolverError
from solver.model import Shell

BULK = 25.0
ISSUE_POINTS = [(h0, ks, g, "standard") for ks, h0, g in
                itertools.product((25.0, 8.33), (10.0, 15.0), (0.5, 3.0))]
DISAGREEING = [(15.0, 25.0, 3.0, "none")]
TARGET = 1e-3


def shell(point, resolution):
    h0, ks, g, bending = point
    return Shell(volume_um3=4300.0, h0_um=h0, bulk_mN_per_m=BULK, shear_mN_per_m=ks,
                 tension_mN_per_m=g, bending=bending, resolution=resolution)


def richardson(K, q, K_default=None):
    """Observed order p, K∞ and whether the last three values are in the
    asymptotic range (differences of one sign, shrinking)."""
    a, b, c = K[-3:]
    d1, d2 = a - b, b - c
    if d1 * d2 > 0 and abs(d2) < abs(d1):
        p = float(np.log(d1 / d2) / np.log(q))
        return p, float(c + (c - b) / (q**p - 1.0)), True
    return None, float(c), False


def solve(point, resolution, method, cache):
    key = json.dumps([method, list(point), resolution])
    if key in cache:
        return cache[key]
    start = time.perf_counter()
    try:
        c = compress(shell(point, resolution), method)
        d = c.to_dict()
        row = dict(modulus_mN_per_m=d["modulus_mN_per_m"], force_nN=d["force_nN"],
                   volume_error=d["volume_error"], iterations=d["iterations"],
                   nodes=int(c.solution.r_um.size), error=None)
    except SolverError as err:
        row = dict(modulus_mN_per_m=float("nan"), error=str(err))
    row["wall_s"] = time.perf_counter() - start
    cache[key] = row
    return row


def study(point, resolutions, default, method, cache, log):
    rows = [solve(point, r, method, cache) for r in resolutions]
    for r, row in zip(resolutions, rows):
        log(dict(point=point, resolution=r, **row))
    K = np.array([row["modulus_mN_per_m"] for row in rows])
    q = resolutions[-1] / resolutions[-2]
    out = dict(h0_um=point[0], bulk_mN_per_m=BULK, shear_mN_per_m=point[1],
               tension_mN_per_m=point[2], bending=point[3],
               poisson_ratio=round(poisson_ratio(BULK, point[1]), 3),
               resolution=list(resolutions), modulus_mN_per_m=[float(k) for k in K],
               wall_s=[row["wall_s"] for row in rows], nodes=[row.get("nodes") for row in rows],
               errors=[row["error"] for row in rows if row["error"]])
    if len(K) < 3 or not np.all(np.isfinite(K)):
        return out
    p, K_inf, asymptotic = richardson(K, q)
    K_d = solve(point, default, method, cache)["modulus_mN_per_m"]
    err = abs(K_d / K_inf - 1.0)
    out.update(order_p=p, asymptotic=asymptotic, modulus_extrapolated_mN_per_m=K_inf,
               modulus_default_mN_per_m=K_d, rel_error_default=err,
               rel_error_finest=abs(K[-1] / K_inf - 1.0) if asymptotic else None,
               finest_change=abs(K[-1] / K[-2] - 1.0))
    out["resolution_for_1e-3"] = (default * (err / TARGET) ** (1.0 / p)
                                  if asymptotic and p > 0 else None)
    return out


def parse_point(text):
    try:
        h0, ks, g, bending = text.split(",")
        point = float(h0), float(ks), float(g), bending
        shell(point, 1.0)
    except (ValueError, InputError) as err:
        raise argparse.ArgumentTypeError(f"{text!r}: {err}") from None
    return point


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--solver", choices=("fast", "explicit"), default="fast")
    ap.add_argument("--resolutions", type=float, nargs="+", default=[1.0, 2.0, 4.0],
                    help="increasing, in a constant ratio (at least 3)")
    ap.add_argument("--default", type=float, default=1.0, help="the solver's default resolution")
    ap.add_argument("--point", type=parse_point, action="append",
                    help="h0_um,shear_mN_per_m,tension_mN_per_m,bending (repeatable); "
                         "default: the issue's 8 points and the disagreeing one")
    ap.add_argument("--cache", type=pathlib.Path, help="JSON-lines file of finished solves (reused)")
    ap.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    args = ap.parse_args()
    res = sorted(args.resolutions)
    if len(res) < 3 or not np.allclose(np.diff(np.log(res)), np.log(res[1] / res[0])):
        ap.error("--resolutions: at least 3, in a constant ratio")
    cache = {}
    if args.cache and args.cache.exists():
        for line in args.cache.read_text().splitlines():
            if line.strip():
                entry = json.loads(line)
                cache[entry.pop("key")] = entry

    def log(entry):
        if not args.quiet:
            print(json.dumps(entry), file=sys.stderr, flush=True)

    class Store(dict):     # append each new solve to the cache file as it finishes
        def __setitem__(self, key, row):
            super().__setitem__(key, row)
            if args.cache:
                with args.cache.open("a") as f:
                    f.write(json.dumps(dict(key=key, **row)) + "\n")

    store = Store(cache)
    start = time.perf_counter()
    points = [study(p, res, args.default, args.solver, store, log)
              for p in (args.point or ISSUE_POINTS + DISAGREEING)]
    errs = [p["rel_error_default"] for p in points if "rel_error_default" in p]
    print(json.dumps(dict(solver=args.solver, default_resolution=args.default, points=points,
                          max_rel_error_default=max(errs) if errs else None,
                          **{"all_within_1e-3": bool(errs) and len(errs) == len(points)
                             and max(errs) <= TARGET},
                          wall_s=time.perf_counter() - start)))


if __name__ == "__main__":
    main()
