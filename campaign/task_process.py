"""The process that computes a rank's tasks (`python -m campaign.task_process`),
started and watched by `campaign.isolation`: a task that crashes or wedges it
takes only this process down, never the rank.

It is forked from `cortex campaign run` before MPI is loaded, or else (a
restart after a crash; the scheduler called where MPI is loaded already) a
fresh interpreter started with exec, never a fork of an MPI process; it
never imports MPI. Its life:

1. it ignores SIGINT and SIGTERM (the rank decides when to stop: a signal
   lets the batches in flight finish), dies with its rank (PR_SET_PDEATHSIG),
   and imports the solver meanwhile the rank starts up (`eager`; rank 0 of a
   run with workers: once the rank sends its campaign);
2. it receives `(campaign, rank, memory_limit_mb)` on its pipe, caps its
   address space at memory_limit_mb (RLIMIT_AS), warms up
   (`campaign.tasks.warm_up`: numba's compiled functions loaded from the
   on-disk cache) and answers READY;
3. for each batch it receives (a list of (task, payload, attempts)) it
   computes the tasks in order (`campaign.tasks.run_task`: a Python-level
   failure or timeout is a failed entry, as in any process) and sends back
   `(entries, seconds computing)`, a batch of compressions as its columns
   (`campaign.entry_batch`). Before each task it writes into the slot
   shared with the rank (`Slot`) the task's place in the batch and when it
   started; between batches the start is +inf (no task running).

It exits when its pipe closes.
"""

import ctypes
import gc
import math
import mmap
import os
import signal
import struct
import sys
import time
from multiprocessing.connection import Connection
from typing import Any

READY = "ready"
PR_SET_PDEATHSIG = 1
_PAIR = struct.Struct("dd")


class Slot:
    """Two float64 shared by the rank and its task process through a memfd:
    [place in the batch of the task running, its start (time.monotonic, s)];
    the start is +inf while no task runs."""

    def __init__(self, fd: int):
        self.fd = fd
        self.map = mmap.mmap(fd, 16)

    @classmethod
    def create(cls) -> "Slot":
        fd = os.memfd_create("cortex-task-slot", 0)
        os.ftruncate(fd, 16)
        slot = cls(fd)
        slot.idle()
        return slot

    def idle(self) -> None:
        _PAIR.pack_into(self.map, 0, -1.0, math.inf)

    def start(self, place: int) -> None:
        _PAIR.pack_into(self.map, 0, place, time.monotonic())

    def read(self) -> tuple[int, float]:
        """(place, started) of the task running, (-1, inf) if none; read until
        two reads agree (the task process may be writing it)."""
        old, new = None, _PAIR.unpack_from(self.map, 0)
        while new != old:
            old, new = new, _PAIR.unpack_from(self.map, 0)
        return int(new[0]), new[1]

    def close(self) -> None:
        self.map.close()
        os.close(self.fd)


def _die_with_parent():
    """SIGKILL this process when the rank that started it dies (Linux), and
    leave the stop signals to the rank."""
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, signal.SIG_IGN)
    try:
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGKILL)
    except (OSError, AttributeError):
        pass


def _limit_memory(limit_mb):
    """Cap this process's address space at `limit_mb` (None: no cap)."""
    if limit_mb:
        import resource
        limit = int(limit_mb * 2**20)
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))


def serve(conn: Connection, slot: Slot, parent: int, inherited: Any = None) -> None:
    """Steps 2 and 3 of the module docstring, until the pipe closes (or the
    rank is gone). A process forked with its campaign (`inherited`) is sent None instead."""
    sent, rank, limit_mb = conn.recv()
    from campaign.entry_batch import CompressionBatch
    from campaign.tasks import run_task, warm_up
    campaign = sent or inherited
    _limit_memory(limit_mb)
    warm_up(campaign)
    gc.freeze()      # what the imports and numba's loads made, out of the collector's sight (as in the rank)
    conn.send(READY)
    while os.getppid() == parent:
        batch = conn.recv()
        started, done = time.perf_counter(), []
        for place, (task, payload, attempts) in enumerate(batch):
            slot.start(place)
            done.append(run_task(campaign, task, payload, attempts, rank))
        slot.idle()
        conn.send((CompressionBatch.of(done) or done, time.perf_counter() - started))


def run(conn: Connection, slot: Slot, parent: int, inherited: Any = None, eager: bool = True) -> None:
    """The task process's life (module docstring), `serve` once it is set up;
    `inherited`: the campaign of a forked task process; `eager`: the solver
    imported at once (else only once the rank sends the campaign)."""
    _die_with_parent()
    if os.getppid() != parent:        # the rank died before the death signal was set
        return
    if eager:
        from campaign import tasks  # noqa: F401  (the solver's imports, while the rank starts up)
    try:
        serve(conn, slot, parent, inherited)
    except (EOFError, OSError):         # the rank closed the pipe (or is gone): nothing more to do
        pass


def main(argv: list[str]) -> int:
    conn_fd, slot_fd, parent = (int(a) for a in argv)
    run(Connection(conn_fd), Slot(slot_fd), parent)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
