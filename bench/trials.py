"""Speed of the Monte-Carlo trial tasks; prints one JSON object.

study_median_ms: median wall time of one trial task (`campaign.trials.run_study`:
a study of N = 55 cells, each analysed at the grid's six heights with drawn
volume and height errors, SPEC 5) over every --every-th study of
campaigns/paper.toml, one core, each study's best of --repeat calls.
The plate forces are those of the made-up smooth law of the campaign's
[test] fake_law (no solve needed; the cost does not depend on the numbers).
per_cell_us: study_median_ms per cell. droplet_solves_per_s: the droplet
shapes (SPEC 1) a study solves (two per cell and height, at ĥ0 and ĥ1) per
second of its median time.
"""

import argparse
import json
import os
import pathlib
import sys
import time

import numpy as np

from campaign import config
from campaign.trials import run_study

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(1, str(ROOT / "tests"))
import faults  # noqa: E402  (the test suite's [test] section: the made-up law; installed for every process started)

os.environ.update(faults.environment())
_fake_law = faults.fake_law


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--every", type=int, default=10, help="time every n-th study of the paper campaign")
    ap.add_argument("--repeat", type=int, default=3, help="calls per study; its best counts")
    args = ap.parse_args()
    camp = config.load(ROOT / "campaigns" / "paper.toml")
    force = {}
    studies = camp.studies[:: args.every]
    times = []
    for study in studies:
        rows = study.rows
        for r in {r for line in rows for r in line} - force.keys():
            force[r] = _fake_law(camp.shells[r])["force_nN"]
        forces = np.array([[force[r] for r in line] for line in rows])
        errors = [""] * len(rows)
        best = float("inf")
        for _ in range(args.repeat + 1):          # the first call of all pays the compilation
            start = time.perf_counter()
            run_study(study, forces, errors)
            best = min(best, time.perf_counter() - start)
        times.append(best)
    cells = studies[0].n_cells
    median = float(np.median(times))
    print(json.dumps({"studies": len(studies), "cells_per_study": cells,
                      "heights": len(studies[0].heights_um),
                      "study_median_ms": round(1e3 * median, 3),
                      "study_p90_ms": round(1e3 * float(np.percentile(times, 90)), 3),
                      "per_cell_us": round(1e6 * median / cells, 2),
                      "droplet_solves_per_s": round(2 * cells * len(studies[0].heights_um) / median)}))


if __name__ == "__main__":
    main()
