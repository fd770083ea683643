"""What the task processes cost: this checkout paired with a checkout of the
engine without them; prints one JSON object.

--base PATH is that other checkout, with its own .venv (made by `make
setup` there); without it (as `make bench-full` runs every script) nothing
is timed and the figures are null. Each pair runs the same command once with each checkout, in
turn (this one first in odd pairs, the other first in even ones), so a
drift of the shared machine's speed falls on both alike:

- paper: `mpiexec -n 2 cortex campaign run campaigns/paper.toml --new`
  into a fresh store (540 compressions, fast solver, then 600 Monte-Carlo
  trial tasks), the whole command;
- noop: 10,000 no-op tasks (`[test] noop = true`, the test suite's faults,
  installed as `bench/engine.py` does), the whole command.

Every command runs with Python's byte-code caches, as in `bench/engine.py`
(its `ENV`); the first pair writes them and is not counted.

For each: the medians and ranges (min, max) of the pairs' ratios (this
checkout / the other) of wall time and of CPU time (user + system of the
command and every process it waited for), and the medians of each side.
The bounds the engine is held to: the paper wall ratio at most 1.10, and
10,000 no-op tasks at 20,000 per second or more (`bench/engine.py`, best
of three).
"""

import argparse
import json
import os
import pathlib
import statistics
import subprocess
import tempfile
import time

import engine  # bench/engine.py: its no-op grid, and the test suite's faults installed as it installs them

ROOT = pathlib.Path(__file__).resolve().parents[1]


def _timed(checkout, config, store):
    """(wall s, CPU s) of one `mpiexec -n 2 cortex campaign run` from `checkout`."""
    for path in (store, f"{store}.journal", f"{store}.lock"):
        pathlib.Path(path).unlink(missing_ok=True)
    binary = checkout / ".venv" / "bin"
    cmd = [str(binary / "mpiexec"), "-n", "2", str(binary / "cortex"), "campaign", "run", str(config),
           "--store", str(store), "--new", "--quiet"]
    started = time.perf_counter()
    proc = subprocess.Popen(cmd, cwd=checkout, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=engine.ENV)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - started
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"bench: {' '.join(cmd)} (in {checkout}) failed: {proc.stderr.read().decode()[-500:]}")
    return wall, usage.ru_utime + usage.ru_stime


def _paired(base, config, store, pairs):
    """The figures of one command over `pairs` pairs (module docstring)."""
    ours, theirs = [], []
    for checkout in (ROOT, base):
        _timed(checkout, config, store)         # byte-code caches written: not counted
    for i in range(pairs):
        order = [(ROOT, ours), (base, theirs)] if i % 2 == 0 else [(base, theirs), (ROOT, ours)]
        for checkout, runs in order:
            runs.append(_timed(checkout, config, store))
    out = {}
    for k, name in enumerate(("wall", "cpu")):
        ratios = [a[k] / b[k] for a, b in zip(ours, theirs)]
        out[f"{name}_ratio_median"] = round(statistics.median(ratios), 3)
        out[f"{name}_ratio_range"] = [round(min(ratios), 3), round(max(ratios), 3)]
        out[f"{name}_s_median"] = [round(statistics.median(r[k] for r in ours), 3),
                                   round(statistics.median(r[k] for r in theirs), 3)]
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--base", type=pathlib.Path,
                        help="a checkout of the engine without task processes, with its own .venv")
    parser.add_argument("--pairs", type=int, default=8, help="pairs of runs per command (default 8)")
    args = parser.parse_args()
    if args.base is None:
        print(json.dumps({"pairs": 0, "paper": None, "noop_10000": None}))
        return
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        noop = tmp / "noop.toml"
        noop.write_text(engine.NOOP.format(h0=engine._grid(10.0, 15.0, 25), shear=engine._grid(5.0, 25.0, 20),
                                           tension=engine._grid(0.5, 3.0, 20)))
        paper = _paired(args.base.resolve(), ROOT / "campaigns" / "paper.toml", tmp / "paper.h5", args.pairs)
        idle = _paired(args.base.resolve(), noop, tmp / "noop.h5", args.pairs)
    idle["tasks_per_s_median"] = [round(engine.N_NOOP / s, 1) for s in idle["wall_s_median"]]
    print(json.dumps({"pairs": args.pairs, "paper": paper, "noop_10000": idle}))


if __name__ == "__main__":
    main()
