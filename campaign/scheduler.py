"""Master/worker over MPI with dynamic load balancing; every rank computes.

Rank 0 owns the store and the list of tasks. Each worker holds up to two
tasks at a time (one computing, one queued), so it never waits for rank 0;
rank 0 answers finished tasks with new ones and, between messages, computes
tasks itself. Without `mpiexec` the same code runs in one process.

A task that raises, exceeds the per-task timeout (SIGALRM) or returns a
non-finite K is recorded as failed with its message; the others go on.
SIGTERM or SIGINT on any rank: no new tasks are handed out, the tasks in
flight finish and are written, and the run stops saying how to resume.
"""

import math
import signal
import sys
import time
import traceback

from campaign.store import DONE, FAILED, PENDING, Store

TAG_TASK, TAG_RESULT, TAG_STOP = 1, 2, 3
_stop = {"flag": False}


def _on_signal(signum, frame):
    _stop["flag"] = True


class TaskTimeout(Exception):
    pass


def _alarm(signum, frame):
    raise TaskTimeout()


def _faulty(fault):
    """The injected faults of a campaign's [test] section."""
    if fault == "raise":
        raise RuntimeError("injected fault: this task raises")
    if fault == "hang":
        time.sleep(1e6)
    from campaign.store import RESULTS
    return {key: 0.0 if fault == "noop" else float("nan") for key in RESULTS}


def compute(shell, method, timeout_s, fault=None):
    """Run one compression: (state, results, error)."""
    from solver.compression import compress
    started = time.time()
    signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, timeout_s)
    try:
        result = _faulty(fault) if fault else compress(shell, method).to_dict()
        result.pop("method", None)
        if not all(math.isfinite(v) for v in result.values() if isinstance(v, float)):
            return "failed", {}, "non-finite result", started
        return "done", result, "", started
    except TaskTimeout:
        return "failed", {}, f"timed out after {timeout_s:g} s", started
    except Exception as err:  # a failed task is recorded, the campaign goes on
        msg = f"{type(err).__name__}: {err}".splitlines()[0]
        if not isinstance(err, (ArithmeticError, RuntimeError, ValueError)):
            msg += " | " + traceback.format_exc(limit=2).splitlines()[-1]
        return "failed", {}, msg, started
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)


def run(campaign, store_path, new=False, retry_failed=False, progress=True):
    """Run or resume `campaign` into `store_path`; returns the exit status:
    0 all done, 1 some tasks failed, 3 stopped by a signal (rerun to resume)."""
    from mpi4py import MPI
    comm = MPI.COMM_WORLD
    rank, size = comm.Get_rank(), comm.Get_size()
    signal.signal(signal.SIGTERM, _on_signal)
    signal.signal(signal.SIGINT, _on_signal)
    store, error = None, None
    if rank == 0:
        try:
            store = Store(store_path, campaign, new=new, ranks=size)
        except Exception as err:
            error = err
    error = comm.bcast(error, root=0)
    if error is not None:
        raise error
    if rank != 0:
        _worker(comm, campaign)
        return 0
    try:
        return _master(comm, store, campaign, retry_failed, progress)
    finally:
        store.close()


def _worker(comm, campaign):
    from mpi4py import MPI
    status = MPI.Status()
    while True:
        row = comm.recv(source=0, tag=MPI.ANY_TAG, status=status)
        if status.Get_tag() == TAG_STOP:
            return
        state, results, err, started = compute(campaign.shells[row], campaign.method, campaign.timeout_s,
                             (campaign.faults or {}).get(row))
        comm.send((row, state, results, err, started), dest=0, tag=TAG_RESULT)


def _master(comm, store, campaign, retry_failed, progress):
    from mpi4py import MPI
    import numpy as np
    states = store.state()
    todo = np.flatnonzero((states == PENDING) | ((states == FAILED) if retry_failed else False)).tolist()
    attempts = store.attempts()
    total, n_done0 = len(states), int(np.sum(states == DONE))
    bar = _Progress(total, n_done0, len(todo), enabled=progress)
    in_flight = {w: 0 for w in range(1, comm.Get_size())}
    last_flush, failed = time.time(), 0

    def finish(row, state, results, err, started, worker):
        nonlocal failed
        attempts[row] += 1
        store.record({"row": int(row), "state": state, "results": results, "error": err,
                      "attempts": int(attempts[row]), "rank": int(worker), "started": started})
        failed += state == "failed"
        bar.update(state)

    def hand_out(worker):
        row = todo.pop(0)
        store.mark_running([row])
        comm.send(row, dest=worker, tag=TAG_TASK)
        in_flight[worker] += 1

    for w in in_flight:
        for _ in range(2):
            if todo and not _stop["flag"]:
                hand_out(w)
    status = MPI.Status()
    while (todo and not _stop["flag"]) or any(in_flight.values()):
        while comm.Iprobe(source=MPI.ANY_SOURCE, tag=TAG_RESULT, status=status):
            worker = status.Get_source()
            row, state, results, err, started = comm.recv(source=worker, tag=TAG_RESULT)
            in_flight[worker] -= 1
            finish(row, state, results, err, started, worker)
            if todo and not _stop["flag"]:
                hand_out(worker)
        if todo and not _stop["flag"]:
            row = todo.pop(0)
            store.mark_running([row])
            finish(row, *compute(campaign.shells[row], campaign.method, campaign.timeout_s,
                             (campaign.faults or {}).get(row)), 0)
        elif any(in_flight.values()):
            time.sleep(0.002)
        if time.time() - last_flush > 2.0:
            store.flush()
            last_flush = time.time()
    for w in in_flight:
        comm.send(None, dest=w, tag=TAG_STOP)
    store.flush()
    bar.close()
    if _stop["flag"] and todo:
        print(f"campaign: stopped by a signal with {len(todo)} tasks left; rerun the same "
              f"command to resume", file=sys.stderr, flush=True)
        return 3
    if failed:
        print(f"campaign: {failed} tasks failed; see `cortex campaign status {store.path}`, "
              "rerun with --retry-failed to retry them", file=sys.stderr, flush=True)
        return 1
    return 0


class _Progress:
    """A tqdm bar on a terminal, a log line every 10 s otherwise."""

    def __init__(self, total, done, todo, enabled):
        self.total, self.done, self.todo, self.start, self.last = total, done, todo, time.time(), 0.0
        self.bar = None
        self.enabled = enabled
        if enabled and sys.stderr.isatty():
            from tqdm import tqdm
            self.bar = tqdm(total=total, initial=done, unit="task", desc="campaign")

    def update(self, state):
        self.done += 1
        if self.bar is not None:
            self.bar.update(1)
        elif self.enabled and time.time() - self.last > 10.0:
            self.last = time.time()
            rate = (self.done) / max(time.time() - self.start, 1e-9)
            print(f"campaign: {self.done}/{self.total} tasks finished, {rate:.2f} task/s", file=sys.stderr,
                  flush=True)

    def close(self):
        if self.bar is not None:
            self.bar.close()
