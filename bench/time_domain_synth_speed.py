"""The cost of a time-domain synthetic experiment (`cortex afm synth --time-domain`) against
another checkout of the project, measured in one run. Prints one JSON object.

Both checkouts simulate the same cells (same --cells and --seed) at the same time, one process
each, so the machine's load falls on both alike. Each side reports its CPU time (the child's
rusage: user + system, seconds), its wall time, and from truth.json the steps of every cell;
`cpu_ratio` is this checkout's CPU over the reference's (≤ 1: no slower) and `same_steps` says
whether every cell took the same number of equilibrium steps.

    python bench/time_domain_synth_speed.py --reference OLD_CHECKOUT [--cells 40 --seed 0 --work DIR]
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parents[1]


def start(checkout: Path, out: Path, cells: int, seed: int) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": str(checkout), "OPENBLAS_NUM_THREADS": "1"}
    cmd = [sys.executable, "-c", "from cortex.cli import main; main()", "afm", "synth", "--time-domain", "--cells", str(cells),
           "--seed", str(seed), "--jobs", "1", "--out", str(out)]
    return subprocess.Popen(cmd, env=env, cwd=checkout, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)


def side(out: Path, cpu_s: float, wall_s: float) -> dict:
    truth = json.loads((out / "truth.json").read_text())
    rows = truth["time_domain"]["cost"]
    return {"cpu_s": cpu_s, "wall_s": wall_s, "cells": len(rows),
            "steps": {r["cell_id"]: r["steps"] for r in rows},
            "failed_cells": len(truth["time_domain"].get("failed_cells", {}))}


def run(reference: Path, work: Path, cells: int, seed: int) -> dict:
    procs = {name: start(path, work / name, cells, seed) for name, path in (("this", HERE), ("reference", reference))}
    t0, done = time.perf_counter(), {}
    while len(done) < len(procs):
        pid, status, usage = os.wait4(-1, 0)
        name = next(n for n, p in procs.items() if p.pid == pid)
        if status != 0:
            sys.exit(f"{name}: afm synth exited {status}: {procs[name].stderr.read().decode()[-400:]}")
        done[name] = side(work / name, usage.ru_utime + usage.ru_stime, time.perf_counter() - t0)
    this, ref = done["this"], done["reference"]
    return {"cells": cells, "seed": seed, "reference": str(reference), "this": this, "reference_run": ref,
            "cpu_ratio": this["cpu_s"] / ref["cpu_s"], "same_steps": this["steps"] == ref["steps"]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reference", type=Path, required=True, help="another checkout of the project")
    ap.add_argument("--cells", type=int, default=40)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--work", type=Path, help="folder for the two experiments (default: a temporary one)")
    a = ap.parse_args()
    if a.work:
        a.work.mkdir(parents=True, exist_ok=True)
        print(json.dumps(run(a.reference.resolve(), a.work, a.cells, a.seed)))
        return
    with tempfile.TemporaryDirectory() as tmp:
        print(json.dumps(run(a.reference.resolve(), Path(tmp), a.cells, a.seed)))


if __name__ == "__main__":
    main()
