"""Known-truth ramps and holds of power-law cells read by the power-law shell (issue 45).

Cells of `studies.powerlaw_ramps.cells` (R 5-10 µm, γ_a 0.2-2 mN/m, K_B(1 s) 5-50 mN/m,
K̃_S 0.1-2, β 0.1-0.3, 0.3-3 µm/s, every other one with a hold of 10-30 s (--hold: at
constant height, the default, or constant force),
tilts 0-0.15 nN/µm, noise 0.02 nN, pressed to 0.14 R; seed --seed), made by the time-domain
shell, each fitted by `analysis.afm.tension.powerlaw_fit.fit_ramp_hold` with its K̃_S given
(--profile: unknown, profiled by `powerlaw_shear.fit_ramp_hold_profiled`); with --elastic also by today's elastic shell (K̃_S given, `shell_fit.fit_shell`) on the ramp.
Prints one JSON object: per cell the truth, the fit (γ_a, its 95 % interval, K_B(1 s), β),
γ_a's relative error and whether the interval holds it (profiled: K̃_S, its interval and whether
it holds K̃_S), the CPU seconds of the fit; then a summary: median and worst |error|, median
error, coverage (profiled: of K̃_S too), for all cells, those with a hold
and those without, and the CPU per recording (and for 100).

    .venv/bin/python bench/powerlaw_ramp_hold.py [--cells 40] [--seed 0] [--elastic] [--hold force] [--profile]
"""

import argparse
import dataclasses
import json
import sys
import time
from typing import Any

import numpy as np

from analysis.afm.tension.powerlaw_fit import fit_ramp_hold
from analysis.afm.tension.powerlaw_shear import fit_ramp_hold_profiled
from analysis.afm.tension.shell_fit import Fixed, fit_shell
from common.errors import InputError, SolverError
from studies.powerlaw_ramps import Cell, cells, recording


def run(cell: Cell, seed: int, elastic: bool, profile: bool = False) -> dict[str, Any]:
    """One cell: made, fitted, compared (module doc)."""
    made = recording(cell, seed=seed)
    out: dict[str, Any] = {"truth": dataclasses.asdict(cell)}
    start = time.process_time()
    try:
        if profile:
            fit = fit_ramp_hold_profiled(made.time_s, made.x_um, made.force_nN, made.ramp_samples, cell.radius_um,
                                         cell.hold_kind)
        else:
            fit = fit_ramp_hold(made.time_s, made.x_um, made.force_nN, made.ramp_samples, cell.radius_um,
                                cell.shear_tilde, cell.hold_kind)
    except (InputError, SolverError) as err:
        return {**out, "error": str(err), "cpu_s": time.process_time() - start}
    lo, hi = fit.tension_interval_mN_per_m
    truth = cell.tension_mN_per_m
    out.update(cpu_s=time.process_time() - start, tension_mN_per_m=fit.tension_mN_per_m,
               tension_lo95_mN_per_m=lo, tension_hi95_mN_per_m=hi, bulk_1s_mN_per_m=fit.bulk_1s_mN_per_m,
               beta=fit.beta, beta_sd=fit.beta_sd, noise_nN=fit.noise_nN,
               baseline_slope_nN_per_um=fit.baseline_slope_nN_per_um,
               surrogate_tension_mN_per_m=fit.surrogate[0],
               relative_error=fit.tension_mN_per_m / truth - 1.0, covered=bool(lo <= truth <= hi))
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
    if any("shear_covered" in r for r in ok):
        out["shear_coverage"] = float(np.mean([r["shear_covered"] for r in ok if "shear_covered" in r]))
    ratio = [r["elastic_tension_over_truth"] for r in ok if "elastic_tension_over_truth" in r]
    if ratio:
        out["elastic_tension_over_truth_median"] = float(np.median(ratio))
        out["elastic_tension_over_truth_range"] = [float(min(ratio)), float(max(ratio))]
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--cells", type=int, default=40)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--elastic", action="store_true", help="also today's elastic shell on each ramp")
    parser.add_argument("--profile", action="store_true", help="K_S/K_B unknown: profiled, not given")
    parser.add_argument("--hold", choices=("height", "force"), default="height", help="how the holds are held")
    args = parser.parse_args()
    rows = []
    for i, cell in enumerate(cells(args.cells, seed=args.seed)):
        cell = dataclasses.replace(cell, hold_kind=args.hold)
        rows.append(run(cell, args.seed * 10_000 + i, args.elastic, args.profile))
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
