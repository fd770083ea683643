"""Throughput and speed-up of the campaign engine; prints one JSON object.

tasks_per_s: 10,000 no-op tasks ([test] noop = true: each returns zeros at
once) through `mpiexec -n 2 cortex campaign run`, store and journal included,
wall time of the whole command (start-up included).
startup_s: the same command on a campaign of one no-op task (imports, the
store, MPI start-up); tasks_per_s_after_startup = 10,000 / (wall - startup_s),
the rate the engine itself sustains.
tasks_per_s_100k: 100,000 no-op tasks, the same whole command, start-up
included (where the start-up weighs a tenth as much as at 10,000).
startup_floor_s: `mpiexec -n 2 python -c "import numpy, h5py, mpi4py.MPI"`,
the interpreter and the libraries any run of the command starts with: no
campaign can start faster than this.
futures_tasks_per_s: the same 10,000 no-op calls through mpi4py.futures'
MPIPoolExecutor.map under `mpiexec -n 2 python -m mpi4py.futures`, same run.
paper_wall_s_1, paper_wall_s_2: campaigns/paper.toml (540 compressions, fast
solver, then its 600 Monte-Carlo trial tasks) under 1 and 2 ranks, each into a
fresh temporary store, wall time of the whole command, the best of --repeat
runs (alternating 1 and 2 ranks; every run's time is printed too, since the
shared machine's speed drifts by 20-40 % between runs); speedup_2 = their
ratio.
paper_wall_s_2_mpio: the 2-rank run on the parallel-HDF5 stack (.venv-mpio,
`--write-path mpio`), best of --repeat too; null where that stack is not built
(or cannot import this checkout's code: rebuild it with `make setup-parallel`).
--no-paper skips the paper runs (null); --paper CONFIG times another campaign
file instead (e.g. a subset of the paper grid; `paper_config` names it).
The machine is shared: timings noisy.
"""

import argparse
import json
import os
import pathlib
import subprocess
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
if "--futures-child" not in sys.argv:   # mpi4py.futures puts bench/ first on sys.path: `campaign` would be this file
    sys.path.insert(1, str(ROOT / "tests"))
    import faults  # noqa: E402  (the test suite's [test] section: no-op tasks; installed for every process started)

    os.environ.update(faults.environment())
MPIO = ROOT / ".venv-mpio" / "bin"
BIN = pathlib.Path(sys.executable).parent
N_NOOP = 10_000
N_BIG = 100_000        # 50 x 40 x 50: the largest campaign [campaign] max_tasks allows by default
NOOP = """
[campaign]
name = "noop"
[grid]
h0_um = [{h0}]
bulk_mN_per_m = 25.0
shear_mN_per_m = [{shear}]
tension_mN_per_m = [{tension}]
[test]
noop = true
"""


def _noop(x):
    return x


def _grid(lo, hi, n):
    return ", ".join(f"{lo + (hi - lo) * i / (n - 1):.6f}" for i in range(n))


def _timed(cmd, ok=(0,)):
    started = time.perf_counter()
    out = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
    wall = time.perf_counter() - started
    if out.returncode not in ok or (out.returncode == 1 and "tasks failed" not in out.stderr):
        raise SystemExit(f"bench: {' '.join(map(str, cmd))} failed: {out.stderr.strip()[-500:]}")
    return wall, out.stdout


def _futures_child():
    """Runs under `python -m mpi4py.futures`: the same no-op calls through its pool."""
    from mpi4py.futures import MPIPoolExecutor
    with MPIPoolExecutor() as pool:
        started = time.perf_counter()
        n = sum(1 for _ in pool.map(_noop, range(N_NOOP)))
        print(json.dumps({"n": n, "wall_s": time.perf_counter() - started}))


def _noop_run(tmp, name, h0, shear, tension):
    """Wall time of `mpiexec -n 2 cortex campaign run` of a no-op grid."""
    cfg = tmp / f"{name}.toml"
    cfg.write_text(NOOP.format(h0=h0, shear=shear, tension=tension))
    return _timed([str(BIN / "mpiexec"), "-n", "2", str(BIN / "cortex"), "campaign", "run", str(cfg),
                   "--store", str(tmp / f"{name}.h5"), "--quiet"])[0]


def _engine(tmp):
    """The no-op figures: 10,000 and 100,000 tasks, the one-task start-up, the
    import floor, and mpi4py.futures on the same 10,000 calls."""
    wall = _noop_run(tmp, "noop", _grid(10.0, 15.0, 25), _grid(5.0, 25.0, 20), _grid(0.5, 3.0, 20))
    wall_100k = _noop_run(tmp, "noop100k", _grid(10.0, 15.0, 50), _grid(5.0, 25.0, 40), _grid(0.5, 3.0, 50))
    mpiexec = str(BIN / "mpiexec")
    floor, _ = _timed([mpiexec, "-n", "2", sys.executable, "-c", "import numpy, h5py, mpi4py.MPI"])
    startup = _noop_run(tmp, "one", "12.0", "8.0", "1.0")
    futures_wall, out = _timed([mpiexec, "-n", "2", sys.executable, "-m", "mpi4py.futures",
                                str(pathlib.Path(__file__).resolve()), "--futures-child"])
    return {
        "tasks_per_s": round(N_NOOP / wall, 1),
        "startup_s": round(startup, 2),
        "tasks_per_s_after_startup": round(N_NOOP / (wall - startup), 1) if wall > startup else None,
        "tasks_per_s_100k": round(N_BIG / wall_100k, 1),
        "startup_floor_s": round(floor, 2),
        "futures_tasks_per_s": round(N_NOOP / futures_wall, 1),
        "futures_map_only_tasks_per_s": round(N_NOOP / json.loads(out.strip().splitlines()[-1])["wall_s"], 1)}


def _paper_commands():
    """The command lines timed: 1 rank, 2 ranks, and 2 ranks on the parallel-HDF5
    stack where it is built and installed with this checkout."""
    cortex = str(BIN / "cortex")
    commands = {1: [cortex], 2: [str(BIN / "mpiexec"), "-n", "2", cortex]}
    if (MPIO / "with-mpi").exists() and subprocess.run(
            [str(MPIO / "python"), "-I", "-c", "import campaign.store"], capture_output=True, cwd=ROOT).returncode == 0:
        commands["mpio"] = [str(MPIO / "with-mpi"), "mpiexec", "-n", "2", str(MPIO / "cortex")]
    return commands


def _paper(tmp, config, repeat):
    """The paper campaign's figures: every run of each command (alternating), the best, the speed-up,
    and the failed compressions and trial cells of a 2-rank store."""
    commands = _paper_commands()
    runs = {n: [] for n in commands}
    for r in range(repeat):
        for n, cmd in commands.items():
            cmd = cmd + ["campaign", "run", config, "--store", str(tmp / f"paper{n}-{r}.h5"), "--quiet"]
            runs[n].append(_timed(cmd, ok=(0, 1))[0])     # 1: some tasks failed (counted below)
    best = {n: min(runs[n]) for n in runs}
    status = json.loads(_timed([str(BIN / "cortex"), "campaign", "status", str(tmp / "paper2-0.h5"), "--json"])[1])
    return {
        "paper_wall_s_1": round(best[1], 2), "paper_wall_s_2": round(best[2], 2),
        "speedup_2": round(best[1] / best[2], 3),
        "paper_runs_s_1": [round(t, 2) for t in runs[1]], "paper_runs_s_2": [round(t, 2) for t in runs[2]],
        "paper_wall_s_2_mpio": round(best["mpio"], 2) if "mpio" in best else None,
        "paper_runs_s_2_mpio": [round(t, 2) for t in runs.get("mpio", [])],
        "paper_config": pathlib.Path(config).name,
        "paper_failed_2": status["failed"] + status.get("trials", {}).get("failed", 0)}


NO_PAPER = {"paper_wall_s_1": None, "paper_wall_s_2": None, "speedup_2": None, "paper_runs_s_1": [],
            "paper_runs_s_2": [], "paper_wall_s_2_mpio": None, "paper_runs_s_2_mpio": [], "paper_config": None,
            "paper_failed_2": None}


def main():
    if "--futures-child" in sys.argv:
        return _futures_child()
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--no-paper", action="store_true", help="skip the paper campaign runs")
    parser.add_argument("--paper", metavar="CONFIG", default=str(ROOT / "campaigns/paper.toml"),
                        help="the campaign file timed under 1 and 2 ranks (default campaigns/paper.toml)")
    parser.add_argument("--repeat", type=int, default=3, metavar="R",
                        help="paper runs per rank count; the best is kept (default 3)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        figures = _engine(tmp)
        figures.update(NO_PAPER if args.no_paper else _paper(tmp, str(pathlib.Path(args.paper).resolve()),
                                                              args.repeat))
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
