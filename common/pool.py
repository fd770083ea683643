"""A process pool of `jobs` workers, or the same map in this process for one job; how many
CPUs this process may use (`usable_cores`, the default number of jobs); under an MPI launcher,
the other ranks as the pool (`ranks`).

    with ranks() as main:          # every rank of `mpiexec -n N cortex ...` enters
        if main:                   # rank 0 (or the only process): the command's work, whose
            ...                    # pools map over ranks 1..N-1 (mpi4py.futures.MPICommExecutor)

A rank other than 0 serves rank 0's tasks inside `ranks()` until rank 0 leaves it, then gets
False and does nothing more: every output stays rank 0's to write. With N ranks, N - 1 compute
(rank 0 hands out the tasks and gathers their answers, as in mpi4py.futures).
"""

import os
from contextlib import contextmanager
from typing import Any, Callable, Iterable, Iterator

_RANKS: list[Any] = []      # rank 0's executor over the other ranks while `ranks()` is open


class Serial:
    """The pool's map in this process."""

    def __enter__(self) -> "Serial":
        return self

    def __exit__(self, *exc: object) -> None:
        return None

    def map(self, fn: Callable[[Any], Any], items: Iterable[Any]) -> Iterator[Any]:
        return map(fn, items)


class _Ranks(Serial):
    """The pool's map over the other MPI ranks (`ranks`'s executor, kept open on leaving)."""

    def __init__(self, executor: Any) -> None:
        self._executor = executor

    def map(self, fn: Callable[[Any], Any], items: Iterable[Any]) -> Iterator[Any]:
        return self._executor.map(fn, items)


def usable_cores() -> int:
    """The CPUs this process may run on (its affinity where the system says, else the machine's count)."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


_LAUNCHERS = (("PMI_RANK", "PMI_SIZE"), ("OMPI_COMM_WORLD_RANK", "OMPI_COMM_WORLD_SIZE"))   # MPICH's, Open MPI's


def launched_ranks() -> int:
    """How many ranks an MPI launcher started this process among, as its environment says
    (MPICH's PMI_SIZE, Open MPI's OMPI_COMM_WORLD_SIZE); 1 without a launcher."""
    for _, size in _LAUNCHERS:
        if os.environ.get(size, "").isdigit():
            return int(os.environ[size])
    return 1


def launched_rank() -> int:
    """This process's rank as the MPI launcher's environment says; 0 without a launcher."""
    for rank, _ in _LAUNCHERS:
        if os.environ.get(rank, "").isdigit():
            return int(os.environ[rank])
    return 0


@contextmanager
def ranks() -> Iterator[bool]:
    """True on rank 0 (or without a launcher of two ranks or more), whose `pool`s inside map over
    the other ranks; False on the others, once rank 0 has left (module docstring)."""
    if launched_ranks() < 2:
        yield True
        return
    from mpi4py import MPI
    from mpi4py.futures import MPICommExecutor
    with MPICommExecutor(MPI.COMM_WORLD, root=0) as executor:
        if executor is None:        # a serving rank: rank 0 has shut the executor down
            yield False
            return
        _RANKS.append(executor)
        try:
            yield True
        finally:
            _RANKS.pop()


def inside_ranks() -> bool:
    """Whether this is rank 0 inside `ranks()` with other ranks (its pools are those ranks)."""
    return bool(_RANKS)


def pool(jobs: int) -> Any:
    """Inside `ranks()` with other ranks: those ranks (`jobs` is not used); else a forked
    `ProcessPoolExecutor` of `jobs` workers (jobs > 1), else `Serial` (a context manager with `map`)."""
    if _RANKS:
        return _Ranks(_RANKS[-1])
    if jobs < 2:
        return Serial()
    from concurrent.futures import ProcessPoolExecutor      # here: `cortex`'s start-up does not pay for it
    from multiprocessing import get_context
    return ProcessPoolExecutor(jobs, mp_context=get_context("fork"))
