"""Known-truth ramps and holds of power-law cells read by the power-law shell (issue 45).

Cells of `studies.powerlaw_ramps.cells` (R 5-10 µm, γ_a 0.2-2 mN/m, K_B(1 s) 5-50 mN/m,
K̃_S 0.1-2, β 0.1-0.3, 0.3-3 µm/s, every other one with a hold of 10-30 s (--hold: at
constant height, the default, or constant force), tilts 0-0.15 nN/µm, noise 0.02 nN,
pressed to 0.14 R; seed --seed), made by the time-domain shell, each fitted by
`analysis.afm.tension.powerlaw_fit.fit_ramp_hold` with its K̃_S given (--profile: unknown,
profiled by `powerlaw_shear.fit_ramp_hold_profiled`); with --elastic also by today's
elastic shell (K̃_S given, `shell_fit.fit_shell`) on the ramp. Prints one JSON object: per
cell the truth, the fit (γ_a, its 95 % interval, K_B(1 s), β), γ_a's relative error and
whether the interval holds it (profiled: K̃_S, its interval and whether it holds K̃_S), the
CPU seconds of the fit, its simulations and whether it settled; then a summary: median and
worst |error|, median error, coverage (profiled: of K̃_S too), the median simulations, for
all cells, those with a hold and those without, and the CPU per recording (and for 100).

With --reference N the first N cells are also read by the simulator's own least squares
(`powerlaw_fit.solve`, finite differences, up to 60 simulations) from the defect correction's
fit (β free, K̃_S given; without a hold before β's profile): γ_a's relative difference and the
ratio of the SDs (the corrected surrogate's Jacobian over the simulator's, at one σ²). With
--speed the fit's CPU on 100 recordings of ramp plus constant-height hold (the cells with a hold
of `cells(200)`; made first, not counted), best of --repeat runs, K̃_S given (--profile:
profiled). With --table the tabled simulator (`powerlaw_tabled`, the shipped table) against
the simulator at each cell's truth (its recording's protocol, no fit): the largest difference
over the ramp and over the hold relative to the largest force, and whether the table holds the cell.

    .venv/bin/python bench/powerlaw_ramp_hold.py [--cells 40] [--seed 0] [--elastic] [--hold force] [--profile]
        [--reference 10] [--speed [--repeat 3]] [--table]
"""

import argparse
import dataclasses
import json
import sys
import time
from typing import Any

import numpy as np

from analysis.afm.tension import powerlaw_fit, powerlaw_shell, powerlaw_simulated, powerlaw_tabled
from analysis.afm.tension.powerlaw_fit import fit_ramp_hold
from analysis.afm.tension.powerlaw_shear import fit_ramp_hold_profiled
from analysis.afm.tension.shell_fit import Fixed, fit_shell
from common.errors import InputError, SolverError
from studies.powerlaw_ramps import Cell, Made, cells, recording


def read(cell: Cell, made: Made, profile: bool) -> powerlaw_fit.PowerLawFit:
    """The default reading of one recording, K̃_S given or profiled."""
    if profile:
        return fit_ramp_hold_profiled(made.time_s, made.x_um, made.force_nN, made.ramp_samples, cell.radius_um,
                                      cell.hold_kind)
    return fit_ramp_hold(made.time_s, made.x_um, made.force_nN, made.ramp_samples, cell.radius_um, cell.shear_tilde,
                         cell.hold_kind)


def reference(cell: Cell, made: Made) -> dict[str, Any]:
    """The defect correction's fit (β free, K̃_S given) against the simulator's own least
    squares from it (module doc)."""
    s, drop = powerlaw_fit.prepare(made.time_s, made.x_um, made.force_nN, made.ramp_samples, cell.radius_um,
                                   cell.hold_kind)
    fast, _ = powerlaw_fit.start(s, cell.radius_um, cell.shear_tilde, drop)
    start = time.process_time()
    slow = powerlaw_fit.solve(s, cell.radius_um, cell.shear_tilde, fast.q)
    sigma2 = fast.sse / max(s.time_s.size - 6, 1)
    ratio = powerlaw_fit.sds(fast, sigma2) / powerlaw_fit.sds(slow, sigma2)
    return {"simulator_tension_mN_per_m": float(slow.q[1]), "simulator_cpu_s": time.process_time() - start,
            "tension_over_simulator": float(fast.q[1] / slow.q[1]),
            "tension_difference_over_sd": float((fast.q[1] - slow.q[1]) / powerlaw_fit.sds(slow, sigma2)[1]),
            "sd_ratio_tension_bulk_beta": [float(r) for r in ratio[1:]],
            "sse_over_simulator": float(fast.sse / slow.sse), "simulations": fast.simulations}


def run(cell: Cell, seed: int, elastic: bool, profile: bool = False, compare: bool = False) -> dict[str, Any]:
    """One cell: made, fitted, compared (module doc)."""
    made = recording(cell, seed=seed)
    out: dict[str, Any] = {"truth": dataclasses.asdict(cell)}
    start = time.process_time()
    try:
        fit = read(cell, made, profile)
    except (InputError, SolverError) as err:
        return {**out, "error": str(err), "cpu_s": time.process_time() - start}
    lo, hi = fit.tension_interval_mN_per_m
    truth = cell.tension_mN_per_m
    out.update(cpu_s=time.process_time() - start, tension_mN_per_m=fit.tension_mN_per_m,
               tension_lo95_mN_per_m=lo, tension_hi95_mN_per_m=hi, bulk_1s_mN_per_m=fit.bulk_1s_mN_per_m,
               beta=fit.beta, beta_sd=fit.beta_sd, noise_nN=fit.noise_nN,
               baseline_slope_nN_per_um=fit.baseline_slope_nN_per_um,
               surrogate_tension_mN_per_m=fit.surrogate[0],
               relative_error=fit.tension_mN_per_m / truth - 1.0, covered=bool(lo <= truth <= hi),
               simulations=fit.simulations, converged=fit.converged)
    if compare:
        try:
            out["reference"] = reference(cell, made)
        except (InputError, SolverError) as err:
            out["reference"] = {"error": str(err)}
    if fit.shear_band is not None:
        out.update(shear_tilde=fit.shear_tilde, shear_lo95=fit.shear_band[0], shear_hi95=fit.shear_band[1],
                   shear_covered=bool(fit.shear_band[0] <= cell.shear_tilde <= fit.shear_band[1]))
    if elastic:
        ramp = slice(0, made.ramp_samples)
        try:
            shell = fit_shell(made.x_um[ramp], made.force_nN[ramp], cell.radius_um, Fixed(cell.shear_tilde))
            out["elastic_tension_over_truth"] = shell.tension_mN_per_m / truth
        except InputError as err:
            out["elastic_error"] = str(err)
    return out


def table_check(cell: Cell, made: Made) -> dict[str, Any]:
    """The tabled force against the simulated one at the cell's truth (module doc)."""
    from analysis.afm.tension.powerlaw_simulated import RampHold
    table = powerlaw_tabled.resolve(None)
    history = RampHold(made.time_s, made.x_um, made.ramp_samples, cell.hold_kind)
    q = np.array([2.0 * cell.radius_um, cell.tension_mN_per_m, cell.bulk_1s_mN_per_m, cell.beta])
    sim = powerlaw_simulated.force_nN(history, q[0], cell.radius_um, *q[1:3], cell.beta, cell.shear_tilde)
    force = powerlaw_tabled.TabledForce(history, cell.radius_um, cell.shear_tilde, table)
    try:
        tab = force(q)
    except SolverError:
        return {"inside": False}
    top = float(np.max(np.abs(sim)))
    ramp, hold = slice(0, made.ramp_samples), slice(made.ramp_samples, None)
    out = {"inside": True, "ramp_max_difference_over_peak": float(np.max(np.abs(tab - sim)[ramp]) / top)}
    if made.time_s.size > made.ramp_samples:
        out["hold_max_difference_over_peak"] = float(np.max(np.abs(tab - sim)[hold]) / top)
    return out


def table_summary(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """The largest and median differences of `table_check`'s rows the table holds."""
    inside = [r for r in rows if r["inside"]]
    out: dict[str, Any] = {"cells": len(rows), "inside": len(inside)}
    for key in ("ramp_max_difference_over_peak", "hold_max_difference_over_peak"):
        v = [r[key] for r in inside if key in r]
        if v:
            out[key] = {"median": float(np.median(v)), "worst": float(np.max(v))}
    return out


def summary(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Median and worst |error|, median error and coverage of the rows that were fitted."""
    ok = [r for r in rows if "relative_error" in r]
    if not ok:
        return {"cells": len(rows), "fitted": 0}
    err = np.array([r["relative_error"] for r in ok])
    out: dict[str, Any] = {"cells": len(rows), "fitted": len(ok), "median_abs_error": float(np.median(np.abs(err))),
           "worst_abs_error": float(np.max(np.abs(err))), "median_error": float(np.median(err)),
           "coverage": float(np.mean([r["covered"] for r in ok])),
           "within_10_percent": float(np.mean(np.abs(err) <= 0.1))}
    out["simulations_median"] = float(np.median([r["simulations"] for r in ok]))
    out["settled"] = float(np.mean([r["converged"] for r in ok]))
    ref = [r["reference"] for r in ok if "tension_over_simulator" in r.get("reference", {})]
    if ref:
        diff = np.array([r["tension_over_simulator"] - 1.0 for r in ref])
        sd = np.array([r["sd_ratio_tension_bulk_beta"] for r in ref])
        out["reference"] = {"cells": len(ref), "tension_difference_median": float(np.median(diff)),
                            "tension_difference_worst": float(diff[np.argmax(np.abs(diff))]),
                            "tension_difference_over_sd_median_abs":
                                float(np.median([abs(r["tension_difference_over_sd"]) for r in ref])),
                            "sd_ratio_median_tension_bulk_beta": [float(v) for v in np.median(sd, axis=0)],
                            "sd_ratio_range_tension": [float(sd[:, 0].min()), float(sd[:, 0].max())]}
    if any("shear_covered" in r for r in ok):
        out["shear_coverage"] = float(np.mean([r["shear_covered"] for r in ok if "shear_covered" in r]))
    ratio = [r["elastic_tension_over_truth"] for r in ok if "elastic_tension_over_truth" in r]
    if ratio:
        out["elastic_tension_over_truth_median"] = float(np.median(ratio))
        out["elastic_tension_over_truth_range"] = [float(min(ratio)), float(max(ratio))]
    return out


def speed(seed: int, profile: bool, repeat: int) -> dict[str, Any]:
    """The fit's CPU seconds on 100 recordings of ramp plus constant-height hold (module doc),
    the surrogate's caches emptied before each run."""
    made = [(c, recording(c, seed=seed * 10_000 + i)) for i, c in enumerate(cells(200, seed=seed)) if c.hold_s > 0]
    totals: list[float] = []
    simulations: list[int] = []
    for _ in range(repeat):
        powerlaw_shell.clear_caches()
        start = time.process_time()
        simulations, failed = [], 0
        for cell, m in made:
            try:
                simulations.append(read(cell, m, profile).simulations)
            except (InputError, SolverError):
                failed += 1
        totals.append(time.process_time() - start)
    best = min(totals)
    return {"speed": {"recordings": len(made), "profiled": profile, "cpu_s_runs": totals, "cpu_s_best": best,
                      "cpu_s_per_recording": best / len(made), "cpu_s_for_100_recordings": 100 * best / len(made),
                      "cpu_target_s_for_100": 30.0, "simulations_median": float(np.median(simulations)),
                      "simulations_total": int(np.sum(simulations)), "failed": failed}}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--cells", type=int, default=40)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--elastic", action="store_true", help="also today's elastic shell on each ramp")
    parser.add_argument("--profile", action="store_true", help="K_S/K_B unknown: profiled, not given")
    parser.add_argument("--hold", choices=("height", "force"), default="height", help="how the holds are held")
    parser.add_argument("--reference", type=int, default=0, metavar="N",
                        help="the first N cells also by the simulator's own least squares")
    parser.add_argument("--speed", action="store_true", help="CPU of 100 recordings with a constant-height hold")
    parser.add_argument("--repeat", type=int, default=3, help="--speed: runs, the best counted")
    parser.add_argument("--table", action="store_true", help="the tabled simulator against the simulator")
    args = parser.parse_args()
    if args.table:
        checks = [table_check(c, recording(c, seed=args.seed * 10_000 + i))
                  for i, c in enumerate(cells(args.cells, seed=args.seed))]
        print(json.dumps({"summary": table_summary(checks), "cells": checks}, indent=1))
        return
    if args.speed:
        print(json.dumps(speed(args.seed, args.profile, args.repeat), indent=1))
        return
    rows = []
    for i, cell in enumerate(cells(args.cells, seed=args.seed)):
        cell = dataclasses.replace(cell, hold_kind=args.hold)
        rows.append(run(cell, args.seed * 10_000 + i, args.elastic, args.profile, i < args.reference))
        print(f"{i + 1}/{args.cells} {rows[-1].get('relative_error', rows[-1].get('error'))}", file=sys.stderr,
              flush=True)
    cpu = [r["cpu_s"] for r in rows]
    result = {"summary": {"all": summary(rows), "with_hold": summary([r for r in rows if r["truth"]["hold_s"] > 0]),
                          "ramp_only": summary([r for r in rows if r["truth"]["hold_s"] == 0]),
                          "cpu_s_per_recording": float(np.mean(cpu)),
                          "cpu_s_for_100_recordings": float(100 * np.mean(cpu)), "cpu_target_s_for_100": 30.0},
              "cells": rows}
    print(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
