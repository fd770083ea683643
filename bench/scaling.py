"""The master's cost per task and how many ranks it can keep busy; prints one JSON object.

1. master_cost_us: the slope of the campaign's span (below) against task
   count of no-op campaigns ([test] noop = true) under `mpiexec -n 2 cortex
   campaign run`, --small and --large tasks, so what every campaign pays
   once cancels: the time rank 0 (which hands out, records and journals
   every task) spends per task, an upper bound on its cost of serving one.
2. The model: R ranks each finishing a task of T seconds ask the master for
   R/T services per second of c = master_cost_us each; with the requests
   arriving at random the master is an M/D/1 queue of load ρ = R c / T, a
   request waits ρ c / (2 (1 - ρ)) on average, and a rank is busy
   f(R) = T / (T + c + ρ c / (2 (1 - ρ))) of the time (0 for ρ ≥ 1).
   max_ranks_90: the largest R with f ≥ 0.9 for T = --task-ms;
   min_task_ms_90: for 64, 256 and 1024 ranks, the shortest task that keeps
   them 90 % busy.
   The scheduler hands out tasks in batches (`campaign.policy`), so c is the
   cost per task of a batch's messages, its journal entries and its flush,
   shared by the batch.
3. The check: --ranks (16) ranks oversubscribed on this machine, every task a
   no-op that first sleeps T_c = --check-task-ms ([test] noop and
   compression_sleep_s: a known wall time that costs no CPU),
   --check-small and --check-large tasks (task counts: multiples of 100);
   measured_busy = T_c ΔM / (R Δspan), against predicted_busy = f(R) for T_c.

Every figure is taken over the campaign's own span, from its first task's
start to its last task's end as the store records them (`campaign.summary`:
span = tasks / tasks_per_s), not over the whole command: starting 16 Python
ranks on 2 cores takes 5-15 s and varies by seconds from run to run, which
is not what the model is about and drowned the difference of two runs
(noop_wall_s and check_wall_s, the whole commands, are printed too).
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
sys.path.insert(1, str(ROOT / "tests"))
import faults  # noqa: E402  (the test suite's [test] section: no-op tasks; installed for every process started)
from campaign.store.reader import summary  # noqa: E402

os.environ.update(faults.environment())
BIN = pathlib.Path(sys.executable).parent
CAMPAIGN = """
[campaign]
name = "scaling"
[grid]
h0_um = [{h0}]
bulk_mN_per_m = 25.0
shear_mN_per_m = [{shear}]
tension_mN_per_m = 1.0
[test]
{test}
"""


def _config(path, tasks, sleep_s=None):
    """A campaign of `tasks` no-op tasks, each first sleeping sleep_s if given."""
    shear = ", ".join(f"{5.0 + 20.0 * i / 99:.6f}" for i in range(100))
    h0 = ", ".join(f"{10.0 + 5.0 * i / max(tasks // 100 - 1, 1):.6f}" for i in range(tasks // 100))
    test = "noop = true" + ("" if sleep_s is None else f"\ncompression_sleep_s = {sleep_s}")
    path.write_text(CAMPAIGN.format(h0=h0, shear=shear, test=test))
    return path


def _wall(tmp, tasks, ranks, sleep_s=None):
    cfg = _config(tmp / f"c{tasks}-{ranks}.toml", tasks, sleep_s)
    cmd = [str(BIN / "mpiexec"), "-n", str(ranks), str(BIN / "cortex"), "campaign", "run", str(cfg),
           "--store", str(tmp / f"s{tasks}-{ranks}.h5"), "--quiet"]
    started = time.perf_counter()
    out = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
    wall = time.perf_counter() - started
    if out.returncode != 0:
        raise SystemExit(f"bench: {' '.join(cmd)} exited {out.returncode}: {out.stderr.strip()[-500:]}")
    return wall, tasks / summary(tmp / f"s{tasks}-{ranks}.h5")["tasks_per_s"]


def busy(ranks, task_s, cost_s):
    """f(R): the fraction of time a rank computes (module docstring, M/D/1)."""
    rho = ranks * cost_s / task_s
    if rho >= 1.0:
        return 0.0
    return task_s / (task_s + cost_s + rho * cost_s / (2.0 * (1.0 - rho)))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--small", type=int, default=2000)
    ap.add_argument("--large", type=int, default=20000)
    ap.add_argument("--task-ms", type=float, default=30.0)
    ap.add_argument("--ranks", type=int, default=16)
    ap.add_argument("--check-task-ms", type=float, default=100.0)
    ap.add_argument("--check-small", type=int, default=500)
    ap.add_argument("--check-large", type=int, default=2000)
    args = ap.parse_args()
    if any(m % 100 or m <= 0 for m in (args.small, args.large, args.check_small, args.check_large)):
        raise SystemExit("bench: task counts must be positive multiples of 100")
    T = args.task_ms / 1e3
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        (w_small, s_small), (w_large, s_large) = _wall(tmp, args.small, 2), _wall(tmp, args.large, 2)
        cost = (s_large - s_small) / (args.large - args.small)
        Tc = args.check_task_ms / 1e3
        (c_small, cs_small), (c_large, cs_large) = (_wall(tmp, m, args.ranks, Tc)
                                                    for m in (args.check_small, args.check_large))
    measured = Tc * (args.check_large - args.check_small) / (args.ranks * (cs_large - cs_small))
    max_ranks = 1
    while busy(max_ranks + 1, T, cost) >= 0.9:
        max_ranks += 1
    min_task = {}
    for r in (64, 256, 1024):
        t = T
        while busy(r, t, cost) < 0.9:
            t *= 1.01
        while busy(r, t / 1.01, cost) >= 0.9:
            t /= 1.01
        min_task[str(r)] = round(1e3 * t, 1)
    print(json.dumps({
        "noop_tasks": [args.small, args.large], "noop_wall_s": [round(w_small, 2), round(w_large, 2)],
        "noop_span_s": [round(s_small, 3), round(s_large, 3)],
        "master_cost_us": round(1e6 * cost, 1), "task_ms": args.task_ms,
        "max_ranks_90": max_ranks, "min_task_ms_90": min_task,
        "check_ranks": args.ranks, "check_task_ms": args.check_task_ms,
        "check_tasks": [args.check_small, args.check_large],
        "check_wall_s": [round(c_small, 2), round(c_large, 2)],
        "check_span_s": [round(cs_small, 3), round(cs_large, 3)],
        "measured_busy": round(measured, 3), "predicted_busy": round(busy(args.ranks, Tc, cost), 3)}))


if __name__ == "__main__":
    main()
