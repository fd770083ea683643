"""A synthetic experiment simulated in time (`cortex afm synth --time-domain`) read by
`cortex afm analyze`, against its truth (SPEC 10 and 12). Prints one JSON object.

- `cost`: per cell the simulation steps and wall time (truth.json's `time_domain.cost`, with
  the number of processes that shared the machine), per recording (one oscillation segment:
  a mean height at one frequency) and per step;
- `bulk`, `shear`: over the cells `afm analyze` gave exponents (rheology.csv; cells with three
  frequencies or more), the median estimate against the median of the true exponents, the
  largest error, and the share of cells whose 95 % interval holds the true exponent;
- `paired_test`: summary.json's test of β_S > β_B; `tension_deviation`: over the cells, the
  largest deviation of the mean tension per height from its median (cells.csv; the published
  filter excludes a cell above 10 %).

    cortex afm synth --time-domain --cells 40 --out EXP [--bulk-exponent 0.1 --shear-exponent 0.3
                     --wait-s 100 --jobs 2]
    cortex afm analyze EXP --out ANALYSIS [--wait-s inf]   # protocol-aware (its provenance); inf: the relaxed state
    python bench/time_domain_synth.py EXP ANALYSIS
"""

import json
import sys
from pathlib import Path

import numpy as np
import pandas as pd


def cost(truth: dict) -> dict:
    rows = pd.DataFrame(truth["time_domain"]["cost"])
    per_rec = rows["wall_s"] / rows["recordings"]
    return {"cells": len(rows), "processes": truth["time_domain"]["jobs"],
            "wall_s_per_cell_median": float(rows["wall_s"].median()), "wall_s_per_cell_max": float(rows["wall_s"].max()),
            "wall_s_total": float(rows["wall_s"].sum()), "steps_per_cell_median": float(rows["steps"].median()),
            "recordings": int(rows["recordings"].sum()), "wall_s_per_recording_median": float(per_rec.median()),
            "steps_per_recording_median": float((rows["steps"] / rows["recordings"]).median()),
            "ms_per_step": float(1e3 * rows["wall_s"].sum() / rows["steps"].sum())}


def exponents(truth: dict, rheo: pd.DataFrame) -> dict:
    cells = {c["cell_id"]: c for c in truth["cells"]}
    out: dict = {"n_cells_with_exponents": int(len(rheo)), "n_cells": len(cells)}
    for name in ("bulk", "shear") if len(rheo) else ():
        t = rheo["cell_id"].map(lambda c: cells[c][f"{name}_exponent"]).to_numpy(float)
        est = rheo[f"{name}_exponent"].to_numpy(float)
        inside = (rheo[f"{name}_exponent_lo95"] <= t) & (t <= rheo[f"{name}_exponent_hi95"])
        out[name] = {"median": float(np.median(est)), "median_true": float(np.median(t)),
                     "median_error": float(np.median(est) - np.median(t)),
                     "median_abs_error": float(np.median(np.abs(est - t))),
                     "max_abs_error": float(np.max(np.abs(est - t))), "interval_coverage": float(np.mean(inside))}
    return out


def main() -> None:
    exp, analysis = Path(sys.argv[1]), Path(sys.argv[2])
    truth = json.loads((exp / "truth.json").read_text())
    out = {"medians": [truth["viscoelastic"]["bulk_exponent_median"], truth["viscoelastic"]["shear_exponent_median"]],
           "wait_s": truth["time_domain"]["wait_s"], "errors": truth["errors"], "cost": cost(truth),
           **exponents(truth, pd.read_csv(analysis / "rheology.csv"))}
    paired = json.loads((analysis / "summary.json").read_text()).get("viscoelastic", {}).get("paired_test", {})
    out["paired_test"] = {k: paired.get(k) for k in ("median_difference", "p_value_greater", "shear_exponent_greater")}
    cells = pd.read_csv(analysis / "cells.csv").groupby("cell_id")["tension_deviation"].first()
    out["tension_deviation"] = {"median": float(cells.median()), "min": float(cells.min()), "max": float(cells.max())}
    print(json.dumps(out))


if __name__ == "__main__":
    main()
