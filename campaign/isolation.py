"""A rank's tasks computed in a process of their own (`campaign.task_process`),
watched: a task that kills that process or wedges it is failed with a message
naming what happened, the process is started again, and the rank goes on
with the rest of its batch.

- **Crash.** The task process dies (any signal: SIGSEGV, SIGBUS, SIGABRT,
  SIGFPE, the kernel's OOM kill): the task it was computing (its place in the
  batch is in the shared `Slot`) is failed, "process died of SIGSEGV while
  computing this task"; the tasks of the batch before it, whose results died
  with the process, are computed again (the same numbers: a task depends on
  nothing else); the ones after it follow.
- **No answer.** A task runs past `timeout_s + GRACE_S` (code that ignores
  Python signals, e.g. a loop in compiled code, so the task process's own
  SIGALRM timeout could not end it): the process is killed (SIGKILL) and the
  task failed, "no answer after T s (+ G s grace): the process was killed".
- **Retries.** A task failed in either way is computed again, in the new
  process, up to `retries` times (its `attempts` counting each); then it is
  failed for good. (A Python-level failure is not retried here: it is what
  the task computes, every time.)
- **Memory.** The task process's address space is capped at
  `memory_limit_mb` (RLIMIT_AS), so a task that needs more fails alone (a
  MemoryError is a failed task; a process the kernel kills is a crash).

How it is started: `cortex campaign run` forks it once the campaign file is
read and before MPI is loaded (`start_early`): it costs no start-up, and its
warm-up (numba's loads from the on-disk cache) runs while the rank loads MPI
and opens the store. Rank 0 of a run with workers is the exception: its task
process waits, importing nothing, until rank 0 has opened the store and
starts it (`campaign.scheduler`), then warms up while rank 0 serves; so the
store and the workers' warm-ups have the cores first, as without task
processes (three warm-ups at once on two cores delayed the workers' first
tasks). Forking after MPI_Init is unsafe (MPICH's state, memory
registered with the network), so a restart after a crash, or a scheduler
called where MPI is loaded already, starts a fresh interpreter by exec
instead (`python -m campaign.task_process`: about a second of imports and
loads, paid only then).
"""

import gc
import math
import os
import pickle
import select
import signal
import socket
import subprocess
import sys
import time
from multiprocessing.connection import Connection
from typing import TYPE_CHECKING, Any

from campaign.task_process import READY, Slot
from common.pool import launched_rank, launched_ranks

if TYPE_CHECKING:
    from campaign.config import Campaign

Item = tuple[int, Any, int]    # a task of a batch: (task, payload, attempts)

GRACE_S = 2.0           # s: past timeout_s, the grace before a task that does not answer is killed
_early: dict[str, Any] = {}   # the task process `start_early` started, taken by the first `Isolated`


def memory_share_mb() -> float:
    """The default `memory_limit_mb`: the machine's memory shared among the
    ranks of this node (MPI_LOCALNRANKS of MPICH's mpiexec, Open MPI's or
    SLURM's local task count; else one rank), in MB."""
    total_mb = os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE") / 2**20
    for key in ("MPI_LOCALNRANKS", "OMPI_COMM_WORLD_LOCAL_SIZE", "SLURM_NTASKS_PER_NODE"):
        value = os.environ.get(key, "")
        if value.isdigit() and int(value) > 0:
            return total_mb / int(value)
    return total_mb


def _spawn():
    """(process, connection, slot, False): a task process started by exec,
    not yet told its campaign. In a session of its own: a Ctrl-C to the
    terminal's process group reaches the rank (which stops cleanly), not the
    task process."""
    ours, theirs = socket.socketpair()
    slot = Slot.create()
    argv = [sys.executable, "-m", "campaign.task_process", str(theirs.fileno()), str(slot.fd), str(os.getpid())]
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [root, os.environ.get("PYTHONPATH")]))}
    proc = subprocess.Popen(argv, pass_fds=(theirs.fileno(), slot.fd), env=env, start_new_session=True)
    theirs.close()
    return proc, Connection(ours.detach()), slot, False


def _fork(campaign, eager=True):
    """(process, connection, slot, True): a task process forked from this
    one, which holds `campaign` already (only before MPI is loaded); `eager`:
    it imports the solver at once, else when its rank starts it (`Isolated`)."""
    from campaign import task_process
    ours, theirs = socket.socketpair()
    slot, parent = Slot.create(), os.getpid()
    gc.freeze()       # what both processes hold, out of the collector's sight: a collection in either
    pid = os.fork()   # would write to every object's header, copying the pages they share
    if pid == 0:                      # the task process
        status = 1
        try:
            os.setsid()
            ours.close()
            task_process.run(Connection(theirs.detach()), slot, parent, campaign, eager)
            status = 0
        except BaseException:         # a bug here, said as an exec'd process would say it
            import traceback
            traceback.print_exc()
        finally:
            os._exit(status)          # nothing of the rank's (its atexit, its buffers) runs here
    theirs.close()
    return _Forked(pid), Connection(ours.detach()), slot, True


class _Forked:
    """A forked task process, with the part of `subprocess.Popen` used here."""

    def __init__(self, pid):
        self.pid, self.returncode = pid, None

    def poll(self):
        if self.returncode is None:
            pid, status = os.waitpid(self.pid, os.WNOHANG)
            if pid:
                self.returncode = os.waitstatus_to_exitcode(status)
        return self.returncode

    def wait(self, timeout=None):
        if self.returncode is None and timeout is not None:
            fd = os.pidfd_open(self.pid)      # readable once the process has ended
            try:
                if not select.select([fd], [], [], timeout)[0]:
                    raise subprocess.TimeoutExpired(f"task process {self.pid}", timeout)
            finally:
                os.close(fd)
        if self.returncode is None:
            self.returncode = os.waitstatus_to_exitcode(os.waitpid(self.pid, 0)[1])
        return self.returncode

    def kill(self):
        if self.returncode is None:
            os.kill(self.pid, signal.SIGKILL)


def start_early(campaign: "Campaign") -> None:
    """Start this process's task process now, for the first `Isolated` of
    `campaign` to take: forked (no start-up to pay: it has what this process
    imported) if MPI is not loaded yet, else started by exec."""
    if not _early:
        _early["spawned"] = _spawn() if "mpi4py.MPI" in sys.modules else _fork(campaign, not _serving_rank())


def discard_early() -> None:
    """The task process `start_early` started, if no `Isolated` took it: told to stop and reaped."""
    spawned = _early.pop("spawned", None)
    if spawned is not None:
        proc, conn, slot, _ = spawned
        conn.close()
        proc.wait()
        slot.close()


def _serving_rank():
    """Whether this process is rank 0 of a run with other ranks, as the MPI
    launcher's environment says (MPICH's PMI_*, Open MPI's OMPI_COMM_WORLD_*).
    Its task process then waits to warm up until the rank has opened the
    store (`campaign.scheduler`), so the two cores go to the store and the
    workers' warm-ups first, as they would without task processes."""
    return launched_rank() == 0 and launched_ranks() > 1


def signal_name(returncode: int | None) -> str:
    """'SIGSEGV' for a process killed by signal 11 (returncode -11); 'status N' for an exit."""
    if returncode is not None and returncode < 0:
        try:
            return signal.Signals(-returncode).name
        except ValueError:
            return f"signal {-returncode}"
    return f"status {returncode}"


class Isolated:
    """Rank `rank`'s tasks of `campaign` computed in a watched task process
    (module docstring); `run(batch)` -> (entries, seconds computing)."""

    def __init__(self, campaign: "Campaign", rank: int, memory_limit_mb: float | None = None, retries: int = 0):
        self.campaign, self.rank, self.retries = campaign, rank, retries
        self.memory_limit_mb = memory_limit_mb
        self.limit_s = campaign.timeout_s + GRACE_S
        self.warm = False
        self.pending: list[Item] | None = None    # the batch `submit` handed out, until `collect`
        self.sent = False
        self._start(_early.pop("spawned", None) or _spawn())

    def _start(self, spawned):
        self.proc, self.conn, self.slot, forked = spawned
        self.conn.send((None if forked else self.campaign, self.rank, self.memory_limit_mb))
        self.warm = False

    def ready(self, wait_s: float = 0.0) -> bool:
        """Whether the task process has warmed up, waiting at most `wait_s` for it
        (woken at once when it answers, where a nap would sleep on)."""
        if not self.warm and self.conn.poll(wait_s):
            self._take_ready()
        return self.warm

    def _take_ready(self):
        if self.conn.recv() != READY:
            raise RuntimeError("task process: unexpected first message")
        self.warm = True

    def run(self, batch: list[Item]) -> tuple[list[dict[str, Any]], float]:
        """`run_pickled`, unpickled: (entries, seconds computing)."""
        return pickle.loads(self.run_pickled(batch))

    def submit(self, batch: list[Item]) -> None:
        """Hand `batch` to the task process without waiting for it (`collect`
        takes the answer): the rank does its own work meanwhile."""
        self.pending, self.sent = list(batch), self._send(batch)

    def _send(self, todo):
        """Whether `todo` reached the task process (if not, it died: `_attempt` says how)."""
        try:
            if not self.warm:
                self._take_ready()
            self.conn.send(todo)
            return True
        except (EOFError, OSError):
            return False

    def busy(self) -> bool:
        """Whether a batch handed out by `submit` is still to `collect`."""
        return self.pending is not None

    def answered(self, wait_s: float) -> bool:
        """Whether `collect` would not wait (the answer is there, the process has
        ended, or its task is past the limit), waiting at most `wait_s` for it."""
        if self.conn.poll(wait_s):
            return True
        return time.monotonic() - self.slot.read()[1] > self.limit_s

    def collect(self) -> tuple[list[dict[str, Any]], float]:
        """`run` of the batch `submit` handed out: (entries, seconds computing)."""
        batch, self.pending = self.pending or [], None
        return pickle.loads(self.run_pickled(batch, self.sent))

    def run_pickled(self, batch: list[Item], sent: bool = False) -> bytes:
        """Every task of `batch` (a list of (task, payload, attempts)) computed,
        as pickled bytes of (entries, seconds computing: the task process's
        own count, or the wall time of a batch that lost its process); a task
        that crashed or did not answer is a failed entry (after its retries).
        `sent`: the batch is with the task process already (`submit`)."""
        started, todo, outside = time.perf_counter(), list(batch), 0
        entries: list = []
        while todo:
            raw, lost = self._attempt(todo, sent)
            sent = False
            if lost is None:
                if not entries:
                    return raw            # as the task process sent it: the common case
                return pickle.dumps(([*entries, *pickle.loads(raw)[0]], time.perf_counter() - started))
            place, reason, when = lost
            if place < 0:             # died outside any task (starting up, say): once, the batch is
                outside += 1          # computed again; twice in a row, its first task is failed
                if outside < 2:
                    continue
                place = 0
            outside = 0
            task, payload, attempts = todo[place]
            if attempts - batch_attempts(batch, task) < self.retries:
                todo = todo[:place] + [(task, payload, attempts + 1)] + todo[place + 1:]
            else:
                from campaign.tasks import entry
                entries.append(entry(self.campaign, task, attempts, self.rank, ("failed", {}, reason, when)))
                todo = todo[:place] + todo[place + 1:]
        return pickle.dumps((entries, time.perf_counter() - started))

    def _attempt(self, todo, sent=False):
        """(pickled (entries, seconds computing), None) if the task process computed all of `todo`, else
        (None, (place of the task lost, why, when it started)) with the process started again.
        `sent`: `todo` is with the task process already."""
        try:
            if not sent and not self._send(todo):
                raise EOFError
            while not self.conn.poll(self._wait_s()):
                place, started = self.slot.read()
                if time.monotonic() - started > self.limit_s:
                    self.proc.kill()
                    return None, self._restart(place, started, f"no answer after {self.campaign.timeout_s:g} s "
                                                             f"(+ {GRACE_S:g} s grace): the process was killed")
            return self.conn.recv_bytes(), None
        except (EOFError, OSError):
            place, started = self.slot.read()
            code = self.proc.wait()
            return None, self._restart(place, started, f"process died of {signal_name(code)} while computing "
                                                     "this task")

    def _wait_s(self):
        """How long to wait for the answer before looking at the clock again."""
        started = self.slot.read()[1]
        if math.isinf(started):
            return 1.0
        return min(max(started + self.limit_s - time.monotonic(), 0.0) + 0.01, 1.0)

    def _restart(self, place, started, reason):
        """(place, reason, start as Unix time): the dead process reaped, a new one started."""
        self.proc.wait()
        self.conn.close()
        self.slot.close()
        when = time.time() - (time.monotonic() - started) if math.isfinite(started) else time.time()
        self._start(_spawn())
        return place, reason, when

    def close(self) -> None:
        """The task process told to stop (its pipe closed) and reaped; one still
        warming up (a run that ended before rank 0 needed it) is killed: it
        holds nothing, and would answer only once warm."""
        try:
            if not self.ready():
                self.proc.kill()
        except (EOFError, OSError):       # it has ended already
            pass
        self.conn.close()
        try:
            self.proc.wait(timeout=5.0)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        self.slot.close()


def batch_attempts(batch: list[Item], task: int) -> int:
    """The attempts `task` was handed out with in `batch`."""
    return next(a for t, _, a in batch if t == task)
