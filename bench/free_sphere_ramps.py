"""Ramps of the time-domain shell from its free sphere over the physiological range (issue 42).

Each case is a cell of radius R (V = 4/3 π R³) with active tension γ_a and a power-law cortex
K_B(t) = K_B (t/1 s)^-β, K_S(t) = K̃_S K_B (t/1 s)^-β (both moduli one β; Prony series,
`solver.time_domain.power_law_cortex`), standard bending of K_B, K_S at 1 s. From the
stress-free droplet at h0 = 2R - 0.01 µm the plate ramps at RAMP_UM_PER_S down to h = R, in
calls of `solver.time_domain.TimeShell.advance` of --step-um each (the robust step: it chooses
its own sub-steps). The elastic solver (`solver.fast.advance`, moduli K(1 s), the same mesh and
reference) is taken over the same gaps; where it stops, the case says so.

Cases: the 32 corners of R 5-10 µm, γ_a 0.2-2 mN/m, K_B 5-50 mN/m, K̃_S 0.1-2, β 0-0.4 plus
--cases points of a Latin hypercube over it (seed 0; γ_a, K_B, K̃_S uniform in log).
Prints one JSON object: per case the parameters, the depth reached (µm, δ = h0 + 0.01 - h),
the calls and sub-steps (equilibria), the failures (calls without an equilibrium), the seconds of
the ramp and of the elastic solver's, the elastic solver's depth and, at β = 0, the largest relative force difference from it and from
`solver.compress` at each gap; then a summary.

    .venv/bin/python bench/free_sphere_ramps.py [--cases 200] [--step-um 0.25] [--quick] [--beta-zero]
    (--quick: the corners with R 5 µm only; --beta-zero: the corners with β = 0 only)
"""

import argparse
import dataclasses
import itertools
import json
import sys
import time
from typing import Any

import numpy as np
from scipy.stats import qmc

from common.errors import SolverError
from solver import fast
from solver.time_domain import power_law_cortex
from solver.compression import compress
from solver.model import Shell
from solver.time_domain import TimeShell

START_UM = 0.01            # the reference's gap below the free sphere's diameter 2R
RAMP_UM_PER_S = 1.0        # plate speed (SPEC 11: 0.5-3 µm/s)
RANGE = {"radius_um": (5.0, 10.0), "tension_mN_per_m": (0.2, 2.0), "bulk_mN_per_m": (5.0, 50.0),
         "ks_tilde": (0.1, 2.0), "beta": (0.0, 0.4)}
LOG = ("tension_mN_per_m", "bulk_mN_per_m", "ks_tilde")


def cases(n: int, quick: bool, beta_zero: bool = False) -> list[dict[str, float]]:
    """The corners, then n Latin-hypercube points (module docstring); `beta_zero`: the corners
    with β = 0 only."""
    corners = [dict(zip(RANGE, c)) for c in itertools.product(*RANGE.values())]
    if beta_zero:
        corners = [c for c in corners if c["beta"] == 0.0]
    if quick:
        return [c for c in corners if c["radius_um"] == 5.0]
    if beta_zero:
        return corners
    unit = qmc.LatinHypercube(d=len(RANGE), seed=0).random(n)
    points = []
    for row in unit:
        p = {}
        for x, (key, (lo, hi)) in zip(row, RANGE.items()):
            p[key] = float(np.exp(np.log(lo) + x * np.log(hi / lo)) if key in LOG else lo + x * (hi - lo))
        points.append(p)
    return corners + points


def run(case: dict[str, float], step_um: float) -> dict[str, Any]:
    """One ramp (module docstring)."""
    R, bulk = case["radius_um"], case["bulk_mN_per_m"]
    shear = case["ks_tilde"] * bulk
    shell = Shell(volume_um3=4.0 * np.pi / 3.0 * R**3, h0_um=2.0 * R - START_UM, bulk_mN_per_m=bulk,
                  shear_mN_per_m=shear, tension_mN_per_m=case["tension_mN_per_m"])
    gaps = np.r_[np.arange(shell.h0_um - step_um, R, -step_um), R]
    start = time.perf_counter()
    state, forces, failures = TimeShell(shell, power_law_cortex(bulk, shear, case["beta"], case["beta"])), [], []
    for h in gaps:
        try:
            forces.append(state.advance(float(h), step_um / RAMP_UM_PER_S))
        except SolverError as err:
            failures.append({"gap_um": float(h), "error": str(err)})
            break
    seconds = time.perf_counter() - start
    start = time.perf_counter()
    elastic = elastic_forces(shell, gaps)
    elastic_seconds = time.perf_counter() - start
    out: dict[str, Any] = {**case, "depth_reached_um": float(shell.h0_um + START_UM - state.h_um),
                              "depth_asked_um": float(shell.h0_um + START_UM - R), "calls": len(forces),
                              "equilibria": state.equilibria, "failures": failures, "seconds": seconds,
                              "elastic_seconds": elastic_seconds,
                              "elastic_depth_um": float(shell.h0_um + START_UM - gaps[len(elastic) - 1])
                              if elastic else 0.0}
    if case["beta"] == 0.0:
        n = min(len(elastic), len(forces))
        out["elastic_difference"] = float(np.max(np.abs(np.array(forces[:n]) / np.array(elastic[:n]) - 1)))
        out["compress_difference"] = compress_difference(shell, gaps[:len(forces)], forces)
    return out


def compress_difference(shell: Shell, gaps: np.ndarray, forces: list[float]) -> float | None:
    """The largest |F / F_compress - 1| over the gaps where `solver.compress` finds one."""
    worst = None
    for g, f in zip(gaps, forces):
        try:
            c = compress(dataclasses.replace(shell, dh_um=shell.h0_um - float(g))).solution.force_nN
        except SolverError:
            continue
        worst = max(worst or 0.0, abs(f / c - 1.0))
    return worst


def elastic_forces(shell: Shell, gaps: np.ndarray) -> list[float]:
    """The elastic solver's plate force (nN) at each gap, one continuation, until it stops."""
    lag = fast.problem(shell)
    u, h, step, last, forces = fast.reference_state(lag), shell.h0_um, None, None, []
    for g in gaps:
        try:
            u, _, step, last = fast.advance(lag, shell, u, h, float(g), step, last)
        except SolverError:
            break
        h = float(g)
        forces.append(fast.plate_force_nN(lag, u, h))
    return forces


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--cases", type=int, default=200, help="Latin-hypercube points beside the 32 corners")
    parser.add_argument("--step-um", type=float, default=0.25, help="the plate move of one advance call (um)")
    parser.add_argument("--quick", action="store_true", help="the corners of R 5 um only")
    parser.add_argument("--beta-zero", action="store_true", help="the 16 corners of beta 0 only")
    args = parser.parse_args()
    results = []
    for i, case in enumerate(todo := cases(args.cases, args.quick, args.beta_zero)):
        results.append(run(case, args.step_um))
        print(f"{i + 1}/{len(todo)} failures {len(results[-1]['failures'])}", file=sys.stderr, flush=True)
    beta0 = [r["elastic_difference"] for r in results if "elastic_difference" in r]
    versus = [r["compress_difference"] for r in results if r.get("compress_difference") is not None]
    summary = {"cases": len(results), "failed_cases": sum(bool(r["failures"]) for r in results),
               "reached_depth_R": sum(r["depth_reached_um"] >= r["depth_asked_um"] - 1e-9 for r in results),
               "elastic_stopped_early": sum(r["elastic_depth_um"] < r["depth_asked_um"] - 1e-9 for r in results),
               "largest_beta0_difference": max(beta0) if beta0 else None,
               "largest_beta0_compress_difference": max(versus) if versus else None,
               "equilibria_per_case": float(np.mean([r["equilibria"] for r in results])),
               "seconds_per_case": float(np.mean([r["seconds"] for r in results])),
               "elastic_seconds_per_case": float(np.mean([r["elastic_seconds"] for r in results])),
               "step_um": args.step_um, "ramp_um_per_s": RAMP_UM_PER_S}
    print(json.dumps({"summary": summary, "results": results}, indent=1))


if __name__ == "__main__":
    main()
