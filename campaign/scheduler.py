"""Master/worker over MPI with dynamic load balancing; every rank computes.

Rank 0 owns the store and the list of tasks. Each worker holds up to AHEAD
tasks at a time (one computing, the others queued) and sends its results
without waiting for them to be received, so it never waits for rank 0, which
answers messages only between the tasks it computes itself (30-40 ms each).
Without `mpiexec` the same code runs in one process.

Tasks are numbered: the compressions 0..n-1 (grid order), then the
Monte-Carlo trial tasks n..n+m-1 (`campaign.trials.Study`). A trial task is
handed out only once every compression it uses has finished in this run (or
before it); it is sent with those compressions' forces and failure messages,
so workers never read the store. The compressions that trials wait for are
handed out first; trials that become ready queue behind the remaining
compressions, so the short tasks come last and even out the ranks' ends.

A task that raises, exceeds the per-task timeout (SIGALRM) or (a compression)
returns a non-finite result is recorded as failed with its message; the
others go on.
SIGTERM or SIGINT on any rank: no new tasks are handed out, the tasks in
flight finish and are written, and the run stops saying how to resume.

A finished task travels as its journal entry (`entry`), built where it ran.
On the mpio write path (`campaign.mpio_writer`) a worker also keeps it and writes
its rows when rank 0, after each fsync of the journal, tells it how many of
its entries the journal holds (TAG_WRITE; the final count comes with
TAG_STOP, before every rank closes the file together).
"""

import contextlib
import math
import signal
import sys
import time
import traceback
from collections import deque

from campaign import faults
from campaign.signals import install as install_signal_handlers
from campaign.signals import stop as _stop
from campaign.mpio_writer import Writer, open_parallel, write_path
from campaign.schema import DONE, FAILED, PENDING
from campaign.store import Store
from solver.errors import (EXIT_BAD_INPUT, EXIT_DONE, EXIT_SIGNAL, EXIT_SOME_FAILED, EXIT_WRITE_FAILED, InputError,
                           is_write_failure)

TAG_TASK, TAG_RESULT, TAG_STOP, TAG_WRITE = 1, 2, 3, 4
AHEAD = 4               # tasks a worker holds: enough to outlast one of rank 0's own tasks


class TaskTimeout(Exception):
    pass


def _alarm(signum, frame):
    raise TaskTimeout()


def compute(shell, method, timeout_s, fault=None, sleep_s=0.0):
    """Run one compression: (state, results, error, started); `fault` and
    `sleep_s` are the test knobs of `campaign.faults`."""
    from solver.compression import compress
    if fault:
        faults.prepare(fault, shell)   # start-up costs outside the task's timer

    def work():
        faults.pause(sleep_s)
        result = faults.injected(fault, shell) if fault else compress(shell, method).to_dict()
        result.pop("method", None)
        if not all(math.isfinite(v) for v in result.values() if isinstance(v, float)):
            raise _NonFinite()
        return result
    return _guarded(work, timeout_s)


def compute_study(study, forces, errors, timeout_s, sleep_s=0.0):
    """Run one Monte-Carlo trial task: (state, per-cell lists, error, started)."""
    from campaign.trials import run_study

    def work():
        faults.pause(sleep_s)
        # numbers stay arrays (sent and journalled as raw float64), the strings become lists
        return {k: v.tolist() if v.dtype.kind in "UO" else v for k, v in run_study(study, forces, errors).items()}
    return _guarded(work, timeout_s)


class _NonFinite(Exception):
    pass


def _guarded(work, timeout_s):
    """work() under the per-task timeout; a failure becomes (failed, {}, message).
    The timer is armed and disarmed inside the handled block, so an alarm that
    fires at any moment (even while disarming) is this task's timeout."""
    started = time.time()
    signal.signal(signal.SIGALRM, _alarm)
    try:
        try:
            signal.setitimer(signal.ITIMER_REAL, timeout_s)
            result = work()
        finally:
            signal.setitimer(signal.ITIMER_REAL, 0)
        return "done", result, "", started
    except _NonFinite:
        return "failed", {}, "non-finite result", started
    except TaskTimeout:
        return "failed", {}, f"timed out after {timeout_s:g} s", started
    except Exception as err:  # a failed task is recorded, the campaign goes on
        msg = f"{type(err).__name__}: {err}".splitlines()[0]
        if not isinstance(err, (ArithmeticError, RuntimeError, ValueError)):
            msg += " | " + traceback.format_exc(limit=2).splitlines()[-1]
        return "failed", {}, msg, started


def run(campaign, store_path, new=False, retry_failed=False, progress=True, writes="auto"):
    """Run or resume `campaign` into `store_path` with the write path `writes`
    (auto, mpio or rank0; `campaign.mpio_writer.write_path`); returns the exit status:
    0 all done, 1 some tasks failed, 3 stopped by a signal (rerun to resume).
    Bad input and a failed write (disk full) are raised on rank 0 (the command
    line says why, status 2 or 5); the other ranks return that status quietly."""
    from mpi4py import MPI
    comm = MPI.COMM_WORLD
    rank, size = comm.Get_rank(), comm.Get_size()
    install_signal_handlers()
    store, path, error = None, None, None
    if rank == 0:
        try:
            path = write_path(writes, size)
            store = Store(store_path, campaign, new=new, ranks=size, parallel=path == "mpio",
                          on_record=faults.record_hook())
        except Exception as err:
            error = err
    error, path = comm.bcast((error, path), root=0)
    if error is not None:
        if rank == 0 or not isinstance(error, (InputError, OSError)):
            raise error
        return EXIT_WRITE_FAILED if is_write_failure(error) else EXIT_BAD_INPUT   # rank 0 says why
    parallel_file = open_parallel(store_path, comm) if path == "mpio" else None   # every rank
    if rank != 0:
        _worker(comm, campaign, parallel_file and Writer(parallel_file))
        return EXIT_DONE
    if parallel_file:
        store.attach(parallel_file)
    if progress:
        print(f"campaign: {size} rank{'s' * (size > 1)}, store writes: {path}"
              f"{' (parallel HDF5)' if path == 'mpio' else ' (rank 0 writes every row)'}",
              file=sys.stderr, flush=True)
    try:
        status = _master(comm, store, campaign, retry_failed, progress)
    except BaseException as err:
        if is_write_failure(err):
            store.abort()             # nothing more is written: the rerun resumes from the journal
        else:
            store.close()
        raise
    store.close()
    return status


def execute(campaign, task, payload):
    """Task `task` (a compression row, or n + j for trial task j): (state, results, error, started)."""
    n, test = len(campaign.shells), campaign.test
    if task < n:
        return compute(campaign.shells[task], campaign.method, campaign.timeout_s, test.by_row.get(task),
                       test.compression_sleep_s)
    return compute_study(campaign.studies[task - n], *payload, campaign.timeout_s, test.trial_sleep_s)


def entry(campaign, task, attempts, rank, state, results, error, started):
    """Task `task`'s journal entry: a compression's `row` and `results`, or a
    trial task's `task` and per-cell `cells`."""
    n = len(campaign.shells)
    key = {"row": int(task), "results": results} if task < n else {"task": int(task - n), "cells": results}
    return {**key, "state": state, "error": error, "attempts": int(attempts), "rank": int(rank),
            "started": started}


def _worker(comm, campaign, writer=None):
    from mpi4py import MPI
    status = MPI.Status()
    sent = []               # results in flight: a large one is received only between rank 0's tasks
    while True:
        message = comm.recv(source=0, tag=MPI.ANY_TAG, status=status)
        tag = status.Get_tag()
        if tag == TAG_WRITE:
            writer.written_upto(message)
        elif tag == TAG_STOP:
            MPI.Request.waitall(sent)
            if writer is not None:
                writer.written_upto(message)
                writer.close()
            return
        else:
            task, payload, attempts = message
            done = entry(campaign, task, attempts, comm.Get_rank(), *execute(campaign, task, payload))
            if writer is not None:
                writer.keep(done)
            sent = [r for r in sent if not r.Test()]
            sent.append(comm.isend(done, dest=0, tag=TAG_RESULT))


class _Trials:
    """Rank 0's bookkeeping of the trial tasks: which wait for which compressions,
    and the forces they are sent with."""

    def __init__(self, store, campaign, comp_todo, retry_failed):
        import numpy as np
        self.n, self.studies = len(campaign.shells), campaign.studies
        state = store.trial_state()
        redo = (state == PENDING) | ((state == FAILED) if retry_failed else False)
        self.todo = [j for j in range(len(self.studies)) if redo[j].any()]
        self.done0 = int(np.sum((state == DONE).all(axis=1))) if len(self.studies) else 0
        self.attempts = store.trial_attempts()
        self.force, self.state, self.error = store.compressions() if self.studies else (None, None, None)
        pending = set(comp_todo)
        self.waiting, self.dependents = {}, {}
        for j in self.todo:
            deps = [r for r in self.studies[j].dependencies() if r in pending]
            self.waiting[j] = len(deps)
            for r in deps:
                self.dependents.setdefault(r, []).append(j)

    def take_ready(self):
        """Trial tasks with nothing left to wait for (task numbers), no longer waiting."""
        ready = [j for j, w in self.waiting.items() if w == 0]
        for j in ready:
            del self.waiting[j]
        return [self.n + j for j in ready]

    def compression_finished(self, row, state, results, error):
        """Note a compression's result; returns the trial tasks it made ready."""
        from campaign.schema import STATES
        if not self.studies:
            return []
        self.state[row] = STATES.index(state)
        self.force[row] = results.get("force_nN", float("nan"))
        self.error[row] = error
        for j in self.dependents.pop(row, []):
            self.waiting[j] -= 1
        return self.take_ready()

    def payload(self, j):
        """(forces (tensions, heights) with NaN where not done, per tension the
        message of its first compression that is not done)."""
        import numpy as np
        study = self.studies[j]
        rows = np.array(study.rows)
        done = self.state[rows] == DONE
        forces = np.where(done, self.force[rows], np.nan)
        errors = []
        for i, line in enumerate(rows):
            bad = [r for r in line if self.state[r] != DONE]
            errors.append("" if not bad else
                          f"compression {bad[0]} (h0 = {study.heights_um[list(line).index(bad[0])]:g} um, "
                          f"gamma_a = {study.tensions_mN_per_m[i]:g} mN/m) failed: {self.error[bad[0]]}")
        return forces, errors

    def left(self):
        return sum(1 for w in self.waiting.values() if w > 0)


def _master(comm, store, campaign, retry_failed, progress):
    from mpi4py import MPI
    import numpy as np
    n = len(campaign.shells)
    states = store.state()
    comp_todo = np.flatnonzero((states == PENDING) | ((states == FAILED) if retry_failed else False)).tolist()
    trials = _Trials(store, campaign, comp_todo, retry_failed)
    comp_todo.sort(key=lambda row: row not in trials.dependents)   # what trials wait for first
    todo = deque(comp_todo + trials.take_ready())
    attempts = store.attempts()
    total = n + len(campaign.studies)
    bar = _Progress(total, int(np.sum(states == DONE)) + trials.done0, len(todo), enabled=progress)
    in_flight = {w: 0 for w in range(1, comm.Get_size())}
    received = dict.fromkeys(in_flight, 0)       # entries journalled per worker
    synced = dict(received)                      # entries the fsync'd journal holds, per worker
    last_flush, failed = time.time(), 0

    def finish(done):
        nonlocal failed
        with _stopping_workers_on_write_failure(comm, in_flight, synced):
            store.record(done)
        state = done["state"]
        if "row" in done:
            todo.extend(trials.compression_finished(done["row"], state, done["results"], done["error"]))
            failed += state == "failed"
        else:
            failed += state == "failed" or "failed" in done["cells"].get("state", ())
        bar.update(state)

    def payload(task):
        return None if task < n else trials.payload(task - n)

    def start(task):
        """Shown running from the next flush on; returns its attempt number."""
        store.mark_running([task if task < n else ("task", task - n)])
        count = attempts if task < n else trials.attempts
        i = task if task < n else task - n
        count[i] += 1
        return count[i]

    def flush(tag=TAG_WRITE):
        """The journal fsync'd and rank 0's rows written; on the mpio path the
        workers then write theirs."""
        with _stopping_workers_on_write_failure(comm, in_flight, synced):
            store.flush()
        synced.update(received)
        for w in in_flight:
            if store.parallel or tag == TAG_STOP:
                comm.send(received[w], dest=w, tag=tag)

    def hand_out(worker):
        task = todo.popleft()
        comm.send((task, payload(task), start(task)), dest=worker, tag=TAG_TASK)
        in_flight[worker] += 1

    def refill():
        """Every worker AHEAD tasks ahead (a finished compression may have made trials ready)."""
        for w in in_flight:
            while in_flight[w] < AHEAD and todo and not _stop["flag"]:
                hand_out(w)

    refill()
    status = MPI.Status()
    while (todo and not _stop["flag"]) or any(in_flight.values()):
        while comm.Iprobe(source=MPI.ANY_SOURCE, tag=TAG_RESULT, status=status):
            worker = status.Get_source()
            done = comm.recv(source=worker, tag=TAG_RESULT)
            in_flight[worker] -= 1
            received[worker] += 1
            finish(done)
            refill()
        if todo and not _stop["flag"]:
            task = todo.popleft()
            finish(entry(campaign, task, start(task), 0, *execute(campaign, task, payload(task))))
            refill()
        elif any(in_flight.values()):
            time.sleep(0.002)
        if time.time() - last_flush > 2.0:
            flush()
            last_flush = time.time()
    flush(TAG_STOP)
    bar.close()
    if _stop["flag"] and (todo or trials.left()):
        print(f"campaign: stopped by a signal with {len(todo) + trials.left()} tasks left; rerun the same "
              f"command to resume", file=sys.stderr, flush=True)
        return EXIT_SIGNAL
    if failed:
        print(f"campaign: {failed} tasks failed; see `cortex campaign status {store.path}`, "
              "rerun with --retry-failed to retry them", file=sys.stderr, flush=True)
        return EXIT_SOME_FAILED
    return EXIT_DONE


@contextlib.contextmanager
def _stopping_workers_on_write_failure(comm, in_flight, synced):
    """A write that fails on rank 0 (disk full) stops the run: the results
    still coming are taken in but not journalled (the rerun redoes them), then
    each worker is stopped with the count of its entries the fsync'd journal
    holds (on the mpio path, the rows it may write), and the error goes on up."""
    try:
        yield
    except OSError as err:
        if not is_write_failure(err):
            raise
        for w, count in in_flight.items():
            for _ in range(count):
                comm.recv(source=w, tag=TAG_RESULT)
            in_flight[w] = 0
            comm.send(synced[w], dest=w, tag=TAG_STOP)
        raise


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
