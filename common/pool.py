"""A process pool of `jobs` workers, or the same map in this process for one job."""

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


def pool(jobs: int) -> Any:
    """A forked `ProcessPoolExecutor` of `jobs` workers (jobs > 1), else `Serial` (a context manager with `map`)."""
    return ProcessPoolExecutor(jobs, mp_context=get_context("fork")) if jobs > 1 else Serial()
