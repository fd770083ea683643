"""Memory and store access at a million tasks; prints one JSON object.

For each size in --tasks (default 100,000 and 1,000,000), a campaign of that
many no-op tasks ([test] noop = true: each returns zeros at once; a grid of
100 heights × 100 shear moduli × tasks/10,000 tensions) runs under
`mpiexec -n --ranks cortex campaign run` into a fresh store. Every rank runs
under /usr/bin/time, so `peak_rss_rank0_mb` is rank 0's own peak resident
memory (MB) and `peak_rss_other_mb` the largest other rank's; `run_wall_s`
is the whole command's wall time. Then `status_wall_s` is the wall time of
`cortex campaign status STORE --json` (a process of its own, start-up
included; `status_cpu_s` its user + system time, which a loaded machine
does not inflate), `open_wall_s` that of opening the store and reading its
result table (`campaign.store.reader.read_results`, in a fresh process, its
start-up and the imports of pandas and the reader excluded; `open_cpu_s` its
CPU time), each the best of --repeat runs; `verify_wall_s` that of
`cortex campaign verify STORE` (every row checked against its checksum and the
journal against its CRCs, start-up included) and `check_wall_s` (`check_cpu_s`)
that of the rows' check alone, the columns read and summed
(`campaign.store.verify.damaged_rows`, in a fresh process, imports excluded),
which every open and reader pays; `check_per_million_s` is it scaled to a
million rows from the largest size. `store_mb` and `journal_mb` the
sizes on disk. From two sizes,
`rss_rank0_per_task_bytes` is the growth of rank 0's peak per task.
"""

import argparse
import json
import os
import pathlib
import resource
import subprocess
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(1, str(ROOT / "tests"))
import faults  # noqa: E402  (the test suite's [test] section: no-op tasks; installed for every process started)

os.environ.update(faults.environment())
BIN = pathlib.Path(sys.executable).parent
NOOP = """
[campaign]
name = "million"
max_tasks = {max_tasks}
[grid]
h0_um = [{h0}]
bulk_mN_per_m = 25.0
shear_mN_per_m = [{shear}]
tension_mN_per_m = [{tension}]
[test]
noop = true
"""
OPEN = """
import sys, time
import pandas
from campaign.store.reader import read_results
started, cpu = time.perf_counter(), time.process_time()
rows = read_results(sys.argv[1])
print(time.perf_counter() - started, time.process_time() - cpu, len(rows))
"""

CHECK = """
import sys, time
from campaign.store.files import open_read
from campaign.store.verify import damaged_rows
started, cpu = time.perf_counter(), time.process_time()
with open_read(sys.argv[1]) as f:
    bad = damaged_rows(f)
print(time.perf_counter() - started, time.process_time() - cpu, len(bad["rows"]))
"""


def _grid(lo, hi, n):
    return ", ".join(f"{lo + (hi - lo) * i / max(n - 1, 1):.6f}" for i in range(n))


def _run(cmd, **kw):
    """Wall and CPU (user + system) seconds of the command, and its output."""
    cpu0, started = _children_cpu(), time.perf_counter()
    out = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, **kw)
    wall = time.perf_counter() - started
    if out.returncode != 0:
        raise SystemExit(f"bench: {' '.join(map(str, cmd))} failed ({out.returncode}): {out.stderr.strip()[-500:]}")
    return wall, _children_cpu() - cpu0, out.stdout


def _children_cpu():
    use = resource.getrusage(resource.RUSAGE_CHILDREN)
    return use.ru_utime + use.ru_stime


def one_size(tmp, tasks, ranks, repeat):
    """Run, status and open for a campaign of `tasks` no-op tasks."""
    cfg, store = tmp / f"noop{tasks}.toml", tmp / f"noop{tasks}.h5"
    cfg.write_text(NOOP.format(max_tasks=tasks, h0=_grid(10.0, 15.0, 100), shear=_grid(5.0, 25.0, 100),
                               tension=_grid(0.5, 3.0, max(tasks // 10_000, 1))))
    rss = tmp / f"rss{tasks}"
    # each rank under /usr/bin/time, its peak RSS (KB) in a file named by its MPI rank
    per_rank = (f'exec /usr/bin/time -f %M -o "{rss}.$PMI_RANK" "{BIN / "cortex"}" campaign run '
                f'"{cfg}" --store "{store}" --quiet')
    run_wall, _, _ = _run([str(BIN / "mpiexec"), "-n", str(ranks), "sh", "-c", per_rank])
    peaks = {int(p.suffix[1:]): int(p.read_text().split()[-1]) / 1024 for p in tmp.glob(f"rss{tasks}.*")}
    status = [_run([str(BIN / "cortex"), "campaign", "status", str(store), "--json"]) for _ in range(repeat)]
    status_wall, status_cpu, info = min(status)[0], min(s[1] for s in status), json.loads(status[0][2])
    opened = [_run([sys.executable, "-c", OPEN, str(store)], env={**os.environ, "PYTHONPATH": str(ROOT)})[2].split()
              for _ in range(repeat)]
    open_wall, open_cpu, rows = min(float(o[0]) for o in opened), min(float(o[1]) for o in opened), opened[0][2]
    verify_wall = min(_run([str(BIN / "cortex"), "campaign", "verify", str(store)])[0] for _ in range(repeat))
    checked = [_run([sys.executable, "-c", CHECK, str(store)], env={**os.environ, "PYTHONPATH": str(ROOT)})[2].split()
               for _ in range(repeat)]
    if any(int(c[2]) for c in checked):
        raise SystemExit(f"bench: {store} has damaged rows")
    check_wall, check_cpu = min(float(c[0]) for c in checked), min(float(c[1]) for c in checked)
    return {"tasks": tasks, "done": info["done"], "rows_read": int(rows), "run_wall_s": round(run_wall, 2),
            "tasks_per_s": round(tasks / run_wall, 1), "peak_rss_rank0_mb": round(peaks[0], 1),
            "peak_rss_other_mb": round(max((v for k, v in peaks.items() if k), default=0.0), 1),
            "status_wall_s": round(status_wall, 3), "status_cpu_s": round(status_cpu, 3),
            "open_wall_s": round(open_wall, 3), "open_cpu_s": round(open_cpu, 3),
            "verify_wall_s": round(verify_wall, 3), "check_wall_s": round(check_wall, 3),
            "check_cpu_s": round(check_cpu, 3),
            "store_mb": round(store.stat().st_size / 2**20, 1),
            "journal_mb": round(os.path.getsize(f"{store}.journal") / 2**20, 1)}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tasks", default="100000,1000000", help="comma-separated campaign sizes")
    ap.add_argument("--ranks", type=int, default=2)
    ap.add_argument("--repeat", type=int, default=3, help="runs of status and open per size (best reported)")
    args = ap.parse_args()
    sizes = [int(x) for x in args.tasks.split(",")]
    with tempfile.TemporaryDirectory() as tmp:
        runs = [one_size(pathlib.Path(tmp), n, args.ranks, args.repeat) for n in sizes]
    out = {"ranks": args.ranks, "runs": runs,
           "check_per_million_s": round(runs[-1]["check_wall_s"] * 1e6 / runs[-1]["tasks"], 2)}
    if len(runs) >= 2:
        a, b = runs[0], runs[-1]
        out["rss_rank0_per_task_bytes"] = round((b["peak_rss_rank0_mb"] - a["peak_rss_rank0_mb"]) * 2**20
                                                / (b["tasks"] - a["tasks"]), 1)
    print(json.dumps(out))


if __name__ == "__main__":
    main()
