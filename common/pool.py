"""A process pool of `jobs` workers, or the same map in this process for one job; how many
CPUs this process may use (`usable_cores`, the default number of jobs)."""

import os
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from typing import Any, Callable, Iterable, Iterator


class Serial:
    """The pool's map in this process."""

    def __enter__(self) -> "Serial":
        return self

    def __exit__(self, *exc: object) -> None:
        return None

    def map(self, fn: Callable[[Any], Any], items: Iterable[Any]) -> Iterator[Any]:
        return map(fn, items)


def usable_cores() -> int:
    """The CPUs this process may run on (its affinity where the system says, else the machine's count)."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


def pool(jobs: int) -> Any:
    """A forked `ProcessPoolExecutor` of `jobs` workers (jobs > 1), else `Serial` (a context manager with `map`)."""
    return ProcessPoolExecutor(jobs, mp_context=get_context("fork")) if jobs > 1 else Serial()
