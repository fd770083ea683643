"""Throughput and speed-up of the campaign engine; prints one JSON object.

tasks_per_s: 10,000 no-op tasks ([test] noop = true: each returns zeros at
once) through `mpiexec -n 2 cortex campaign run`, store and journal included,
wall time of the whole command (start-up included), the best of --repeat
runs (`noop_runs_s`: each run's wall time).
startup_s: the same command on a campaign of one no-op task (imports, the
store, MPI start-up), best of --repeat; tasks_per_s_after_startup = 10,000 /
(wall - startup_s), the rate the engine itself sustains.
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
--base CHECKOUT pairs the two figures a change of the engine is held to
with another checkout (with its own .venv, made by `make setup` there; e.g.
the engine before a change), in the same sitting: its 10,000 no-op runs
and its 2-rank paper runs alternate with this checkout's, best of --repeat
each: base_tasks_per_s, tasks_per_s_ratio (this / base), base_paper_wall_s_2,
paper_wall_ratio_2 (this / base), and each run's time (base_noop_runs_s,
base_paper_runs_s_2); null without --base.
Every command runs with Python's byte-code caches (PYTHONDONTWRITEBYTECODE
is dropped for them: an installed package has its caches, and recompiling
every module would time the compiler); a one-task run of each checkout
writes them before anything is timed.
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
if "--futures-child" not in sys.argv:   # the mpi4py.futures child times its own pool: no campaign, no faults
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


ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}   # module docstring


def _timed(cmd, ok=(0,), cwd=ROOT):
    started = time.perf_counter()
    out = subprocess.run(cmd, capture_output=True, text=True, cwd=cwd, env=ENV)
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


def _noop_config(tmp, name, h0, shear, tension):
    cfg = tmp / f"{name}.toml"
    cfg.write_text(NOOP.format(h0=h0, shear=shear, tension=tension))
    return cfg


def _noop_run(cfg, checkout=ROOT):
    """Wall time of `mpiexec -n 2 cortex campaign run` of the no-op campaign
    file `cfg` with `checkout`'s engine, into a fresh store."""
    store = cfg.with_suffix(f".{abs(hash(checkout))}.h5")
    for path in (store, pathlib.Path(f"{store}.journal"), pathlib.Path(f"{store}.lock")):
        path.unlink(missing_ok=True)        # ours: made by the last run of this config
    binary = pathlib.Path(checkout) / ".venv" / "bin"
    return _timed([str(binary / "mpiexec"), "-n", "2", str(binary / "cortex"), "campaign", "run", str(cfg),
                   "--store", str(store), "--quiet"], cwd=checkout)[0]


def _alternated(run, checkouts, repeat):
    """{checkout: [wall s of `run(checkout)`] * repeat}, the checkouts taking turns
    to go first (a drift of the machine's speed falls on each alike)."""
    walls = {c: [] for c in checkouts}
    for r in range(repeat):
        for c in (checkouts if r % 2 == 0 else checkouts[::-1]):
            walls[c].append(run(c))
    return walls


def _engine(tmp, repeat, base=None):
    """The no-op figures: 10,000 tasks (paired with `base` if given), 100,000
    tasks, the one-task start-up, the import floor, and mpi4py.futures on the
    same 10,000 calls."""
    noop = _noop_config(tmp, "noop", _grid(10.0, 15.0, 25), _grid(5.0, 25.0, 20), _grid(0.5, 3.0, 20))
    one = _noop_config(tmp, "one", "12.0", "8.0", "1.0")
    checkouts = [ROOT] + ([base] if base else [])
    for c in checkouts:
        _noop_run(one, c)                   # byte-code caches written: not timed
    runs = _alternated(lambda c: _noop_run(noop, c), checkouts, repeat)
    wall = min(runs[ROOT])
    wall_100k = _noop_run(_noop_config(tmp, "noop100k", _grid(10.0, 15.0, 50), _grid(5.0, 25.0, 40),
                                       _grid(0.5, 3.0, 50)))
    mpiexec = str(BIN / "mpiexec")
    floor = min(_timed([mpiexec, "-n", "2", sys.executable, "-c", "import numpy, h5py, mpi4py.MPI"])[0]
                for _ in range(repeat))
    startup = min(_noop_run(one) for _ in range(repeat))
    futures_wall, out = _timed([mpiexec, "-n", "2", sys.executable, "-m", "mpi4py.futures",
                                str(pathlib.Path(__file__).resolve()), "--futures-child"])
    return {
        "tasks_per_s": round(N_NOOP / wall, 1),
        "noop_runs_s": [round(t, 3) for t in runs[ROOT]],
        **_base_noop(runs, base),
        "startup_s": round(startup, 2),
        "tasks_per_s_after_startup": round(N_NOOP / (wall - startup), 1) if wall > startup else None,
        "tasks_per_s_100k": round(N_BIG / wall_100k, 1),
        "startup_floor_s": round(floor, 2),
        "futures_tasks_per_s": round(N_NOOP / futures_wall, 1),
        "futures_map_only_tasks_per_s": round(N_NOOP / json.loads(out.strip().splitlines()[-1])["wall_s"], 1)}


def _base_noop(runs, base):
    """The paired no-op figures of `base` (module docstring)."""
    if base is None:
        return {"base_tasks_per_s": None, "tasks_per_s_ratio": None, "base_noop_runs_s": []}
    return {"base_tasks_per_s": round(N_NOOP / min(runs[base]), 1),
            "tasks_per_s_ratio": round(min(runs[base]) / min(runs[ROOT]), 3),
            "base_noop_runs_s": [round(t, 3) for t in runs[base]]}


def _paper_commands(base=None):
    """The command lines timed, each with the folder it runs in: 1 rank, 2
    ranks, 2 ranks on the parallel-HDF5 stack where it is built and installed
    with this checkout, and 2 ranks of the checkout `base` if given."""
    cortex = str(BIN / "cortex")
    commands = {1: ([cortex], ROOT), 2: ([str(BIN / "mpiexec"), "-n", "2", cortex], ROOT)}
    if (MPIO / "with-mpi").exists() and subprocess.run(
            [str(MPIO / "python"), "-I", "-c", "import campaign.store"], capture_output=True, cwd=ROOT).returncode == 0:
        commands["mpio"] = ([str(MPIO / "with-mpi"), "mpiexec", "-n", "2", str(MPIO / "cortex")], ROOT)
    if base is not None:
        binary = base / ".venv" / "bin"
        commands["base"] = ([str(binary / "mpiexec"), "-n", "2", str(binary / "cortex")], base)
    return commands


def _paper(tmp, config, repeat, base=None):
    """The paper campaign's figures: every run of each command (taking turns,
    the order reversed every other round), the best, the speed-up, the
    failed compressions and trial cells of a 2-rank store, and `base`'s."""
    commands = _paper_commands(base)
    runs = {n: [] for n in commands}
    for r in range(repeat):
        for n, (cmd, cwd) in list(commands.items())[::1 if r % 2 == 0 else -1]:
            cmd = cmd + ["campaign", "run", config, "--store", str(tmp / f"paper{n}-{r}.h5"), "--quiet"]
            runs[n].append(_timed(cmd, ok=(0, 1), cwd=cwd)[0])     # 1: some tasks failed (counted below)
    best = {n: min(runs[n]) for n in runs}
    status = json.loads(_timed([str(BIN / "cortex"), "campaign", "status", str(tmp / "paper2-0.h5"), "--json"])[1])
    return {
        "paper_wall_s_1": round(best[1], 2), "paper_wall_s_2": round(best[2], 2),
        "speedup_2": round(best[1] / best[2], 3),
        "paper_runs_s_1": [round(t, 2) for t in runs[1]], "paper_runs_s_2": [round(t, 2) for t in runs[2]],
        "paper_wall_s_2_mpio": round(best["mpio"], 2) if "mpio" in best else None,
        "paper_runs_s_2_mpio": [round(t, 2) for t in runs.get("mpio", [])],
        "paper_config": pathlib.Path(config).name,
        "paper_failed_2": status["failed"] + status.get("trials", {}).get("failed", 0),
        "base_paper_wall_s_2": round(best["base"], 2) if "base" in best else None,
        "paper_wall_ratio_2": round(best[2] / best["base"], 3) if "base" in best else None,
        "base_paper_runs_s_2": [round(t, 2) for t in runs.get("base", [])]}


NO_PAPER = {"paper_wall_s_1": None, "paper_wall_s_2": None, "speedup_2": None, "paper_runs_s_1": [],
            "paper_runs_s_2": [], "paper_wall_s_2_mpio": None, "paper_runs_s_2_mpio": [], "paper_config": None,
            "paper_failed_2": None, "base_paper_wall_s_2": None, "paper_wall_ratio_2": None,
            "base_paper_runs_s_2": []}


def main():
    if "--futures-child" in sys.argv:
        return _futures_child()
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--no-paper", action="store_true", help="skip the paper campaign runs")
    parser.add_argument("--paper", metavar="CONFIG", default=str(ROOT / "campaigns/paper.toml"),
                        help="the campaign file timed under 1 and 2 ranks (default campaigns/paper.toml)")
    parser.add_argument("--repeat", type=int, default=3, metavar="R",
                        help="runs of the 10,000 no-op tasks, the start-up and each paper command; "
                             "the best is kept (default 3)")
    parser.add_argument("--base", metavar="CHECKOUT", type=pathlib.Path,
                        help="another checkout (with its own .venv) paired with this one: no-op and "
                             "2-rank paper runs alternate, best of --repeat each")
    args = parser.parse_args()
    base = args.base.resolve() if args.base else None
    if base is not None and not (base / ".venv" / "bin" / "cortex").is_file():
        parser.error(f"--base {args.base}: no .venv/bin/cortex there (run `make setup` in it)")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        figures = _engine(tmp, args.repeat, base)
        figures.update(NO_PAPER if args.no_paper else _paper(tmp, str(pathlib.Path(args.paper).resolve()),
                                                              args.repeat, base))
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
