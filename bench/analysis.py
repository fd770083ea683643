"""Benchmark of `cortex analysis calibrate` (target: under 10 s for the paper
store). Prints one JSON object.

`calibrate_wall_s`: the whole analysis (read, calibrate three variants,
reconstruction, Monte-Carlo, figures, report) of the paper store
(`results/paper.h5`, or the path given as first argument), or null when it
does not exist. `synthetic_paper_size`: the same run on tables of the paper
size (540 compressions, 3 true ν x 2 height-error modes x 100 studies x 55
cells) generated from the laws (`analysis.synthetic`), reading excluded —
the analysis cost alone, measurable before any campaign has run.

    python bench/analysis.py [STORE]
"""

import json
import os
import sys
import tempfile
import time
from pathlib import Path

# This file is called analysis.py: keep its folder off the path so that
# `analysis` is the package, not this script.
sys.path = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

import analysis.report as report  # noqa: E402
from analysis.synthetic import reference_law, results_table, trials_table  # noqa: E402


def timed_run(store, out):
    start = time.perf_counter()
    result = report.run(store, out, progress=lambda message: None)
    return round(time.perf_counter() - start, 3), result


def main():
    store = Path(sys.argv[1] if len(sys.argv) > 1 else "results/paper.h5")
    out = {"benchmark": "analysis", "store": str(store), "calibrate_wall_s": None,
           "cpu_count": os.cpu_count(),
           "note": "2 cores shared with other work: timings are noisy"}
    with tempfile.TemporaryDirectory() as tmp:
        if store.exists():
            wall, result = timed_run(store, Path(tmp) / "real")
            out["calibrate_wall_s"] = wall
            out["timings_s"] = result["timings_s"]
        laws = {b: reference_law(b) for b in ("standard", "double", "none")}
        results = results_table(laws, noise=0.003, rng=0)
        trials = trials_table(laws["standard"], n_cells=55, n_studies=100, seed=0)
        original = report.read_store
        report.read_store = lambda path: (results, trials)
        try:
            fake = Path(tmp) / "synthetic.h5"
            fake.write_bytes(b"")
            wall, result = timed_run(fake, Path(tmp) / "synthetic")
        finally:
            report.read_store = original
        out["synthetic_paper_size"] = {"wall_s": wall, "timings_s": result["timings_s"],
                                       "compressions": len(results),
                                       "trials": int(trials["trial_id"].nunique())}
    out["target_s"] = 10.0
    print(json.dumps(out))


if __name__ == "__main__":
    main()
