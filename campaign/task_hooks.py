"""The one point where code outside the product changes what a campaign's
tasks do: the test suite's faults (`tests/faults.py`: a task that raises,
hangs, crashes its process, spins in compiled code, returns NaN, or answers
at once with zeros or a made-up law) plug in here, and nowhere else.

A campaign file's `[test]` section is read by the module named in the
environment variable `CORTEX_TASK_HOOKS` (`ENV`; a module importable in every
process of the run: the ranks under mpiexec and their task processes inherit
the environment). Without it, a `[test]` section is refused with one line
(InputError, exit status 2). That module provides

    parse(path, table, n_rows) -> TaskHooks
        the `[test]` table of campaign file `path` (a grid of `n_rows`
        compressions) read, or InputError with one line;
    record_hook() -> Callable[[store, entry], None] | None
        the store's `on_record` (called after each entry is recorded).

A `TaskHooks` travels with the campaign (`campaign.config.Campaign.test`) to
every process that computes its tasks (`campaign.tasks`).
"""

import importlib
import os
from collections.abc import Callable
from types import ModuleType
from typing import Any, Protocol

from common.errors import InputError

ENV = "CORTEX_TASK_HOOKS"


class TaskHooks(Protocol):
    """What a `[test]` section makes of the tasks of a campaign."""

    def prepare(self, row: int, shell: Any) -> None:
        """Before compression `row`'s timer starts: what its hook needs loaded."""

    def compression(self, row: int, shell: Any, solve: Callable[[], dict[str, Any]]) -> dict[str, Any]:
        """Compression `row`'s result (within its timer): `solve()`'s, or the hook's own."""

    def trial(self, run: Callable[[], dict[str, Any]]) -> dict[str, Any]:
        """A Monte-Carlo trial task's result (within its timer): `run()`'s."""

    def warm_up(self, shell: Any) -> bool:
        """A process's warm-up for the hooks' tasks (compression 0 is `shell`);
        True if compression 0 is not solved, so the solver needs no warm-up."""


def _module() -> ModuleType | None:
    """The hooks' module `ENV` names, imported; None if it names none."""
    name = os.environ.get(ENV, "")
    try:
        return importlib.import_module(name) if name else None
    except ImportError as err:
        raise InputError(f"{ENV} names {name!r}, which cannot be imported: {err}") from None


def parse(path: str | os.PathLike[str], table: dict[str, Any], n_rows: int) -> TaskHooks:
    """The `[test]` table of campaign file `path` read by the hooks' module;
    InputError (one line) without one."""
    module = _module()
    if module is None:
        raise InputError(f"{path}: [test] is for the test suite only (its faults are not installed: "
                         f"{ENV} names no module)")
    hooks: TaskHooks = module.parse(path, table, n_rows)
    return hooks


def record_hook() -> Callable[[Any, Any], None] | None:
    """The store's `on_record` from the hooks' module, or None without one."""
    module = _module()
    return None if module is None else module.record_hook()
