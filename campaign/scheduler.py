"""Master/worker over MPI with dynamic load balancing: the mechanism.

Rank 0 owns the store and asks `campaign.policy.Policy` what to hand out:
which tasks, in batches of how many, how many each worker is kept ahead, and
whether rank 0 computes tasks itself between messages. A batch travels as one
message (TAG_TASK: a list of (task, payload, attempts)), sent without waiting
for it to be received (a worker takes it when it has finished the batch
before); the worker computes
it (`campaign.tasks`) and sends its entries back as one message (TAG_RESULT:
(entries, seconds computing)) without waiting for it to be received. Rank 0
records each entry (`store.record`) and flushes the store once per batch it
received (`store.flush`: the journal fsync'd, then the rows). A worker passes
its task process's answer on as that process pickled it (on the rank0
path), so the entries are pickled once and unpickled once, on rank 0. Without
`mpiexec` the same code runs in one process.

A trial task is sent with the forces and failure messages of the
compressions it uses (`campaign.trial_inputs`), so workers never read the
store. Every rank computes its tasks in a task process of its own, which it
watches (`campaign.isolation`): a task that raises, crashes that process or
does not answer is recorded as failed with its message; the others go on.
SIGTERM or SIGINT (`campaign.signals`; mpiexec passes them on to every rank,
and rank 0's flag is the one read): no new tasks are handed out, the batches
in flight finish and are written (a batch holds a worker for at most about
`policy.BATCH_S`), and the run stops saying how to resume (exit status 3).

On the mpio write path (`campaign.store.mpio_writer`) a worker also keeps its entries and
writes their rows when rank 0, after each fsync of the journal, tells it how
many of its entries the journal holds (TAG_WRITE; the final count comes with
TAG_STOP, before every rank closes the file together).
"""

import contextlib
import gc
import pickle
import sys
import time
from collections import deque
from typing import TYPE_CHECKING

from campaign.policy import Policy, master_may_compute
from campaign.progress import Progress
from campaign.signals import stop as _stop
from campaign import isolation, task_hooks
from campaign.store import DONE, FAILED, PENDING, Store, Writer, open_parallel, write_path
from campaign.isolation import Isolated, memory_share_mb
from campaign.entry_batch import is_batch
from campaign.task_key import COMPRESSION, is_compression
from campaign.trial_inputs import TrialInputs
from common.errors import (EXIT_BAD_INPUT, EXIT_DONE, EXIT_SIGNAL, EXIT_SOME_FAILED, EXIT_WRITE_FAILED, InputError,
                           is_write_failure)

if TYPE_CHECKING:
    from campaign.config import Campaign

TAG_TASK, TAG_RESULT, TAG_STOP, TAG_WRITE = 1, 2, 3, 4
FLUSH_S = 2.0           # s: rank 0's own results are flushed at least this often
ANSWER_S = 0.002        # s: rank 0's longest wait for its task process's answer before it serves again
IDLE_S = 0.0002         # s: rank 0's nap while it waits for results and computes nothing (a batch of
                        # 512 no-op tasks is ~2.6 ms of work: naps of 1 ms left the worker waiting for its next)
SPIN_POLLS = 100        # a waiting worker's polls before it naps between them ...
NAP_S = (2e-5, 0.001)   # s: ... its first and its longest nap (each nap twice the last)


def run(campaign: "Campaign", store_path: str, new: bool = False, retry_failed: bool = False, progress: bool = True,
        writes: str = "auto") -> int:
    """Run or resume `campaign` into `store_path` with the write path `writes`
    (auto, mpio or rank0; `campaign.store.mpio_writer.write_path`); returns the exit status:
    0 all done, 1 some tasks failed, 3 stopped by a signal (rerun to resume).
    Bad input and a failed write (disk full) are raised on rank 0 (the command
    line says why, status 2 or 5); the other ranks return that status quietly.
    The signal handlers are the caller's (`campaign.signals.install`, first
    thing in `cortex campaign run`)."""
    from mpi4py import MPI
    comm = MPI.COMM_WORLD
    serving = comm.Get_rank() == 0 and comm.Get_size() > 1     # its task process: once the store is open
    tasks = None if serving else _isolated(campaign, comm.Get_rank())
    store, path, error = _open_store(comm, campaign, store_path, new, writes)
    if error is not None:
        if tasks is not None:
            tasks.close()
        isolation.discard_early()
        if comm.Get_rank() == 0 or not isinstance(error, (InputError, OSError)):
            raise error
        return EXIT_WRITE_FAILED if is_write_failure(error) else EXIT_BAD_INPUT   # rank 0 says why
    parallel_file = open_parallel(store_path, comm) if path == "mpio" else None   # every rank
    gc.freeze()      # what the imports made, out of the collector's sight: the collections the result
    #                  entries trigger would walk it each time (unpickling an entry 2.7 us instead of 1.6)
    if comm.Get_rank() != 0:
        assert tasks is not None           # a worker's task process: started above
        try:
            _worker(comm, tasks, parallel_file and Writer(parallel_file))
        finally:
            tasks.close()
        return EXIT_DONE
    if parallel_file:
        store.attach(parallel_file)
    workers = comm.Get_size() - 1
    if workers and master_may_compute(workers):
        tasks = _isolated(campaign, 0)      # it warms up while rank 0 serves (rank 0 computes once it is warm)
    elif workers:
        isolation.discard_early()           # rank 0 only serves: its task process is not needed
    if progress:
        print(f"campaign: {comm.Get_size()} rank{'s' * (comm.Get_size() > 1)}, store writes: {path}"
              f"{' (parallel HDF5)' if path == 'mpio' else ' (rank 0 writes every row)'}",
              file=sys.stderr, flush=True)
    try:
        status = _master(comm, store, campaign, retry_failed, progress, tasks)
    except BaseException as err:
        if is_write_failure(err):
            store.abort()             # nothing more is written: the rerun resumes from the journal
        else:
            store.close()
        raise
    finally:
        if tasks is not None:
            tasks.close()
    store.close()
    return status


def _isolated(campaign, rank):
    """Rank `rank`'s task process (`campaign.isolation.Isolated`), told to warm up."""
    return Isolated(campaign, rank, campaign.memory_limit_mb or memory_share_mb(), campaign.retries)


def _open_store(comm, campaign, store_path, new, writes):
    """(store on rank 0 else None, write path, error or None), the same path
    and error on every rank: rank 0 opens the store while the workers' task
    processes warm up (`campaign.isolation`; rank 0's, behind its serving)."""
    store, path, error = None, None, None
    if comm.Get_rank() == 0:
        try:
            path = write_path(writes, comm.Get_size())
            store = Store(store_path, campaign, new=new, ranks=comm.Get_size(), parallel=path == "mpio",
                          on_record=task_hooks.record_hook())
        except Exception as err:
            error = err
    arrived = comm.Ibarrier()        # the workers wait here napping: MPI's blocking bcast would spin,
    _polled(lambda: arrived.Test() or None)   # taking a core from the task processes' warm-ups
    error, path = comm.bcast((error, path), root=0)
    return store, path, error


def _worker(comm, tasks, writer=None):
    """A worker's loop: compute each batch it is sent (in its task process,
    `tasks`), send its entries back as one message."""
    from mpi4py import MPI
    status = MPI.Status()
    sent: list = []         # results in flight: received only when rank 0 gets to them
    while True:
        message = _next_message(comm, status)
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
            result = tasks.run_pickled(message)     # passed on as the task process pickled it
            if writer is not None:
                done, busy_s = result = pickle.loads(result)
                for e in done:
                    writer.keep(e)
            sent = [r for r in sent if not r.Test()]
            sent.append(comm.isend(result, dest=0, tag=TAG_RESULT))


def _next_message(comm, status):
    """The next message from rank 0 (its tag in `status`), waited for without
    holding a core. MPI's blocking receive polls at full speed, so on a node
    with more ranks than cores the waiting workers would take the CPU from
    rank 0 and from the ranks that compute (16 ranks on 2 cores: every rank
    running, 80 % of the time in the kernel). A worker polls SPIN_POLLS times,
    then naps between polls, each nap twice the last, from NAP_S[0] up to
    NAP_S[1]: a message waits at most NAP_S[1] longer than with a blocking
    receive, and a worker only waits when rank 0 has nothing queued for it."""
    from mpi4py import MPI
    return _polled(lambda: comm.improbe(source=0, tag=MPI.ANY_TAG, status=status)).recv()


def _polled(probe):
    """What `probe()` returns once it is not None, polled as `_next_message` says."""
    polls, nap = 0, NAP_S[0]
    while (got := probe()) is None:
        polls += 1
        if polls > SPIN_POLLS:
            time.sleep(nap)
            nap = min(2.0 * nap, NAP_S[1])
    return got


def _master(comm, store, campaign, retry_failed, progress, tasks=None):
    """Rank 0's loop: serve the workers' results, compute tasks itself (in its
    task process, `tasks`) when the policy says so and that process has warmed
    up, until nothing is left (or a signal stopped the hand-outs). Its task
    process computes one batch while rank 0 serves and records the last: rank
    0 waits for the answer at most ANSWER_S at a time (woken by it at once),
    so a worker is not kept waiting meanwhile."""
    master = _Master(comm, store, campaign, retry_failed, progress, tasks)
    master.refill()
    while master.active():
        master.serve()
        computes = master.handing_out() and master.policy.master_computes()
        if tasks is not None and tasks.busy():
            if tasks.answered(ANSWER_S):
                master.collect(computes)
        elif computes and (not master.policy.workers or tasks.ready(IDLE_S)):
            master.submit()
        elif not computes:
            time.sleep(IDLE_S)
        if time.time() - master.last_flush > FLUSH_S:
            master.flush()
    master.flush(TAG_STOP)
    master.bar.close()
    return _exit_status(master.policy.left(), master.failed, store.path)


def _are_trials(entries):
    """Whether a batch's entries (one kind: `Policy.take`) are trial tasks'."""
    return not is_batch(entries) and len(entries) > 0 and not is_compression(entries[0])


def _exit_status(left, failed, store_path):
    """The run's exit status, with a line saying what to do next."""
    if _stop["flag"] and left:
        print(f"campaign: stopped by a signal with {left} tasks left; rerun the same command to resume",
              file=sys.stderr, flush=True)
        return EXIT_SIGNAL
    if failed:
        print(f"campaign: {failed} tasks failed; see `cortex campaign status {store_path}`, "
              "rerun with --retry-failed to retry them", file=sys.stderr, flush=True)
        return EXIT_SOME_FAILED
    return EXIT_DONE


class _Master:
    """Rank 0's state: the policy's queue, the attempts, the trials' inputs, the
    messages (`_Link`), the progress and the count of failed tasks (this run's, and the
    store's earlier ones it does not retry)."""

    def __init__(self, comm, store, campaign, retry_failed, progress, tasks):
        import numpy as np
        self.store, self.campaign, self.numbers, self.tasks = store, campaign, campaign.numbers, tasks
        states = store.state()
        rows = np.flatnonzero((states == PENDING) | ((states == FAILED) if retry_failed else False)).tolist()
        self.inputs = TrialInputs(store, campaign, retry_failed)
        self.policy = Policy(rows, self.inputs.waits(), self.numbers.compressions, comm.Get_size() - 1)
        self.attempts = store.attempts()
        self.link = _Link(comm, store)
        done0 = int(np.sum(states == DONE)) + self.inputs.done0
        self.bar = Progress(self.numbers.count, done0, enabled=progress)
        # failed tasks a rerun without --retry-failed leaves as they are still fail the run
        self.failed = 0 if retry_failed else int(np.sum(states == FAILED))
        self.last_flush = time.time()

    def handing_out(self):
        return bool(self.policy.todo) and not _stop["flag"]

    def active(self):
        return self.handing_out() or self.link.busy() or (self.tasks is not None and self.tasks.busy())

    def prepared(self, tasks):
        """(task, payload, attempt) of each task, shown running from the next flush on."""
        keys = self.numbers.keys(tasks)
        self.store.mark_running(keys)
        out = []
        for t, (kind, i) in zip(tasks, keys):
            if kind == COMPRESSION:
                count, payload = self.attempts, None
            else:
                count, payload = self.inputs.attempts, self.inputs.payload(i)
            count[i] += 1
            out.append((t, payload, int(count[i])))
        return out

    def refill(self):
        """Every worker its batches, as many as the policy keeps it ahead."""
        if _stop["flag"]:
            return
        for w in self.link.workers():
            for batch in self.policy.batches_for(self.link.in_flight(w)):
                self.link.send(w, self.prepared(batch))

    def record(self, entries):
        """Finished tasks (entries, or a `CompressionBatch`): journalled, their
        trials' inputs noted, the policy told."""
        with self.link.guard():
            self.store.record_all(entries)
        if is_batch(entries) and not self.inputs.studies:     # no trial task waits for its forces
            self.failed += entries.failed()
            for t in self.numbers.of_compressions(entries.row.tolist()):
                self.policy.finished(t)
        else:
            for e in entries:
                if is_compression(e):
                    self.inputs.compression_finished(e["row"], e["state"], e["results"], e["error"])
                    self.failed += e["state"] == "failed"
                else:
                    self.failed += e["state"] == "failed" or "failed" in e["cells"].get("state", ())
                self.policy.finished(self.numbers.of_entry(e))
        self.bar.update(len(entries))

    def serve(self):
        """Every result batch waiting: each recorded, the store flushed once for
        all of them (once per batch, or less when batches queue up), the
        workers refilled; the policy told the task time and rank 0's cost per message."""
        started, messages = time.perf_counter(), 0
        while (got := self.link.receive()) is not None:
            entries, busy_s = got
            self.record(entries)
            self.policy.timed(len(entries), busy_s, _are_trials(entries))
            messages += 1
        if messages:
            self.flush()
            self.refill()
            self.policy.served(messages, time.perf_counter() - started)

    def submit(self):
        """Rank 0's task process handed the next tasks, as many as the policy
        says (one message), if any are queued."""
        batch = self.prepared(self.policy.take(self.policy.master_batch()))
        if batch:
            self.tasks.submit(batch)

    def collect(self, more):
        """Rank 0's task process's answer recorded; first, if `more`, the next
        batch handed to it (it computes while rank 0 records)."""
        entries, busy_s = self.tasks.collect()
        if more:
            self.submit()
        self.policy.timed(len(entries), busy_s, _are_trials(entries))
        self.record(entries)
        self.refill()                 # a finished compression may have made trials ready

    def flush(self, tag=TAG_WRITE):
        self.link.flush(tag)
        self.last_flush = time.time()


class _Link:
    """Rank 0's side of the messages: batches out, result batches in, and on
    the mpio path how many of each worker's entries the journal holds."""

    def __init__(self, comm, store):
        from mpi4py import MPI
        self.comm, self.store, self.status, self.any = comm, store, MPI.Status(), MPI.ANY_SOURCE
        self.batches: dict[int, deque[int]] = {w: deque() for w in range(1, comm.Get_size())}   # sizes of the batches in flight
        self.received = dict.fromkeys(self.batches, 0)   # entries journalled, per worker
        self.synced = dict(self.received)                # entries the fsync'd journal holds, per worker
        self.sending = []                                # batches sent, not yet known received

    def workers(self):
        return self.batches.keys()

    def in_flight(self, worker):
        return sum(self.batches[worker])

    def busy(self):
        return any(self.batches.values())

    def send(self, worker, batch):
        """A batch out without waiting for it to be received: a blocking send of
        a message above MPI's eager limit (a batch of trial tasks with their
        forces) waits until the worker, busy with its current batch, posts its
        receive, and kept rank 0 from serving and computing for up to a batch."""
        self.sending = [r for r in self.sending if not r.Test()]
        self.sending.append(self.comm.isend(batch, dest=worker, tag=TAG_TASK))
        self.batches[worker].append(len(batch))

    def receive(self):
        """The next result batch waiting, (entries, seconds computing), or None."""
        if not self.comm.Iprobe(source=self.any, tag=TAG_RESULT, status=self.status):
            return None
        worker = self.status.Get_source()
        got = self.comm.recv(source=worker, tag=TAG_RESULT)
        entries, busy_s = pickle.loads(got) if isinstance(got, bytes) else got
        self.batches[worker].popleft()
        self.received[worker] += len(entries)
        return entries, busy_s

    def flush(self, tag=TAG_WRITE):
        """The journal fsync'd and rank 0's rows written; on the mpio path the
        workers then write theirs (with TAG_STOP: and stop)."""
        with self.guard():
            self.store.flush()
        told = dict(self.synced)
        if tag == TAG_STOP:
            from mpi4py import MPI
            MPI.Request.waitall(self.sending)    # all received: every batch's results came back
        self.synced.update(self.received)
        for w in self.batches:       # TAG_WRITE only to the workers with new entries in the journal
            if tag == TAG_STOP or (self.store.parallel and self.synced[w] != told[w]):
                self.comm.send(self.received[w], dest=w, tag=tag)

    @contextlib.contextmanager
    def guard(self):
        """A write that fails on rank 0 (disk full) stops the run: the batches
        still coming are taken in but not journalled (the rerun redoes them),
        then each worker is stopped with the count of its entries the fsync'd
        journal holds (on the mpio path, the rows it may write), and the error
        goes on up."""
        try:
            yield
        except OSError as err:
            if not is_write_failure(err):
                raise
            for w, sizes in self.batches.items():
                for _ in sizes:
                    self.comm.recv(source=w, tag=TAG_RESULT)
                sizes.clear()
                self.comm.send(self.synced[w], dest=w, tag=TAG_STOP)
            raise
