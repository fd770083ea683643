"""One function run in a forked process beside this one, while this one works on.

    with beside(fn, *args) as later:     # fn(*args) starts now in a forked child
        ...                              # this process works meanwhile
        value = later.result()           # fn's value, or the exception fn raised, raised here

The child is a copy of this process (fork: the arguments need no pickling, only
the value does, back through a pipe); it runs the same code on the same numbers,
so its value is the one this process would have computed. It only computes: it
writes no file, so every output stays this process's to write. An exception in
`fn` is raised again by `result()` (the same type and message; the child's
traceback as its cause); a child that dies without answering (killed, out of
memory) is a `RuntimeError`. Leaving the `with` block stops a child still at work
(an error in this process meanwhile).

Policy, `forking()`: a child only where it can run beside this process, i.e. where
the fork start method exists and this process may run on two CPUs or more
(`common.pool.usable_cores`), and not on an MPI rank 0 whose pools are the other ranks
(`common.pool.ranks`: a process with MPI started is not forked); elsewhere `fn(*args)` runs in this process when
`result()` is first asked (the same value, serially). At most one child: the
callers use two processes in all.
"""

from __future__ import annotations

import multiprocessing
import pickle
import traceback
from contextlib import contextmanager
from typing import Any, Callable, Generic, Iterator, TypeVar

from common.pool import inside_ranks, usable_cores

T = TypeVar("T")


def forking() -> bool:
    """Whether a forked child can run beside this process (module docstring)."""
    if "fork" not in multiprocessing.get_all_start_methods() or inside_ranks():
        return False
    return usable_cores() >= 2


class RemoteTraceback(Exception):
    """The child's traceback, the cause of an exception raised again here."""

    def __str__(self) -> str:
        return str(self.args[0])


def _answer(send: Any, fn: Callable[..., Any], args: tuple[Any, ...]) -> None:
    """In the child: (True, fn(*args)) or (False, (the exception, its traceback)) into the pipe."""
    try:
        message: tuple[bool, Any] = (True, fn(*args))
    except Exception as err:            # noqa: BLE001 - every error goes back to the parent
        text = "".join(traceback.format_exception(err))
        try:
            pickle.dumps(err)
        except Exception:               # noqa: BLE001 - an exception that cannot travel: its words do
            err = RuntimeError(f"{type(err).__name__}: {err}")
        message = (False, (err, text))
    send.send(message)
    send.close()


class Later(Generic[T]):
    """The value of `fn(*args)`, computed in a forked child or, without one, here on demand."""

    def __init__(self, fn: Callable[..., T], args: tuple[Any, ...], fork: bool) -> None:
        self._fn, self._args = fn, args
        self._process: Any = None
        if fork:
            ctx = multiprocessing.get_context("fork")
            self._receive, send = ctx.Pipe(duplex=False)
            self._process = ctx.Process(target=_answer, args=(send, fn, args), daemon=True)
            self._process.start()
            send.close()                 # the child's end: EOF here if the child dies

    def result(self) -> T:
        """fn's value; the exception it raised; RuntimeError if the child died without answering."""
        if self._process is None:
            return self._fn(*self._args)
        try:
            ok, value = self._receive.recv()
        except EOFError:
            self._process.join()
            raise RuntimeError(f"the worker process stopped without an answer (exit status "
                               f"{self._process.exitcode})") from None
        finally:
            self._receive.close()
        self._process.join()
        self._process = None
        if ok:
            return value
        err, text = value
        raise err from RemoteTraceback(text)

    def stop(self) -> None:
        """Stop the child if it is still at work."""
        if self._process is not None:
            self._process.kill()
            self._process.join()
            self._receive.close()
            self._process = None


@contextmanager
def beside(fn: Callable[..., T], *args: Any) -> Iterator[Later[T]]:
    """`fn(*args)` in a forked child where `forking()`, else here when asked: a `Later`,
    whose child is stopped on leaving the block."""
    later = Later(fn, args, forking())
    try:
        yield later
    finally:
        later.stop()
