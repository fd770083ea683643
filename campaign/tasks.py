"""One task, computed where it runs (a rank's task process,
`campaign.task_process`): a compression or a Monte-Carlo trial task, under
the per-task timeout, and its journal entry. In a campaign of another task
kind (`[campaign] task`, `campaign.kinds`: the tables' nodes, registered by
their owners) a grid point is computed by its kind's function instead
(`compute_node`). The engine's own kind, `compression`, is registered here.

A task that raises (a MemoryError too: the process's memory is capped),
exceeds the per-task timeout (SIGALRM) or (a compression) returns a
non-finite result is failed with its message; nothing escapes, so one bad
task never stops the others. (A task that kills its process, or is stuck
where SIGALRM cannot end it, is failed by `campaign.isolation`.) A task comes
as its number (`campaign.task_key.TaskNumbers`). A campaign's `[test]`
section (the test suite's only) changes what a task does through its hooks
(`campaign.task_hooks.TaskHooks`, the campaign's `test`).
"""

import functools
import math
import signal
import socket
import time
import traceback
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from campaign.kinds import COMPRESSION as COMPRESSION_KIND, Kind, register
from campaign.task_hooks import TaskHooks
from campaign.task_key import COMPRESSION, CompressionEntry, TrialEntry, compression_entry, trial_entry
from solver.compression import compress
from solver.model import Shell

if TYPE_CHECKING:
    from campaign.config import Campaign

Outcome = tuple[str, dict[str, Any], str, float]    # (state, results, error, started as Unix time)

# the engine's own kind: one compression per grid point (`compute`), its results schema.RESULTS
KIND = register(Kind(COMPRESSION_KIND, 1, {}, doc="one compression of the shell (SPEC 2-3)"))


class TaskTimeout(Exception):
    pass


class _NonFinite(Exception):
    pass


def _alarm(signum, frame):
    raise TaskTimeout()


_handler_set = False


def _set_handler():
    global _handler_set
    signal.signal(signal.SIGALRM, _alarm)
    _handler_set = True


def compute(shell: Shell, method: str, timeout_s: float, row: int = 0,
            hooks: TaskHooks | None = None) -> Outcome:
    """Run one compression (grid index `row`): (state, results, error, started);
    `hooks`: the `[test]` section's (`campaign.task_hooks`), or None."""
    if hooks is not None:
        hooks.prepare(row, shell)      # start-up costs outside the task's timer

    def work():
        if hooks is None:
            result = compress(shell, method).to_dict()
        else:
            result = hooks.compression(row, shell, lambda: compress(shell, method).to_dict())
        result.pop("method", None)
        if not _finite(result.values()):
            raise _NonFinite()
        return result
    return _guarded(work, timeout_s)


def compute_node(point: Any, timeout_s: float, node_results: Callable[[Any], dict[str, float]]) -> Outcome:
    """One grid point `point` of a campaign of another task kind (`campaign.kinds.Kind.compute`,
    `node_results`), with its `converged` (True) and `wall_s`."""
    def work():
        start = time.perf_counter()
        result = node_results(point)
        result.update(converged=True, wall_s=time.perf_counter() - start)
        if not _finite(result.values()):
            raise _NonFinite()
        return result
    return _guarded(work, timeout_s)


def _finite(values):
    """Whether every float among `values` is finite (the others: ints, bools,
    the odd name). All numbers, as a solver's results are, in one C-level pass."""
    try:
        return all(map(math.isfinite, values))
    except (TypeError, OverflowError):
        return all(math.isfinite(v) for v in values if isinstance(v, float))


def compute_study(study: Any, forces: Any, errors: Any, timeout_s: float,
                  hooks: TaskHooks | None = None) -> Outcome:
    """Run one Monte-Carlo trial task: (state, per-cell lists, error, started)."""
    from campaign.trials import run_study

    def trial():
        # numbers stay arrays (sent and journalled as raw float64), the strings become lists
        return {k: v.tolist() if v.dtype.kind in "UO" else v for k, v in run_study(study, forces, errors).items()}
    return _guarded(trial if hooks is None else lambda: hooks.trial(trial), timeout_s)


def _guarded(work, timeout_s):
    """work() under the per-task timeout; a failure becomes (failed, {}, message).
    The timer is armed and disarmed inside the handled block, so an alarm that
    fires at any moment (even while disarming) is this task's timeout."""
    started = time.time()
    if not _handler_set:          # once per process: setting (or asking) it per task cost a no-op task a third
        _set_handler()
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
    except MemoryError as err:
        return "failed", {}, f"MemoryError: {err or 'out of memory'}{_memory_limit()}", started
    except Exception as err:  # a failed task is recorded, the campaign goes on
        msg = f"{type(err).__name__}: {err}".splitlines()[0]
        if not isinstance(err, (ArithmeticError, RuntimeError, ValueError)):
            msg += " | " + traceback.format_exc(limit=2).splitlines()[-1]
        return "failed", {}, msg, started


def _memory_limit():
    """' (the process is limited to N MB: [solver] memory_limit_mb)' when its address space is capped."""
    import resource
    limit = resource.getrlimit(resource.RLIMIT_AS)[0]
    if limit == resource.RLIM_INFINITY:
        return ""
    return f" (the process is limited to {limit / 2**20:.0f} MB: [solver] memory_limit_mb)"


def warm_up(campaign: "Campaign") -> None:
    """Pay, before any task, the once-per-process costs of the campaign's first
    compression: its solver's modules imported, the droplet geometry's
    compiled quadrature and inverse table loaded, and the solver's own warm-up
    where it has one (the fast solver loads its compiled functions by solving
    the first compression and throwing it away): 0.6-1 s here, mostly
    importing numba and its first loads from the on-disk compile cache; or
    what its `[test]` faults need. Each rank's task process does this
    (`campaign.task_process`) while the rank starts up and prepares the
    store, so it is not paid in the run. Nothing is recorded; a failure here
    is left for the task itself to meet and report."""
    if not campaign.shells:
        return
    shell = campaign.shells[0]
    shell = getattr(shell, "shell", shell)         # a protocol node's shell
    try:
        if campaign.test is not None and campaign.test.warm_up(shell):
            return
        from solver.compression import warm_up as warm_up_solver
        from solver.geometry import droplet
        droplet(shell.volume_um3, shell.h1_um)
        warm_up_solver(shell, campaign.method)     # a solver's own (the fast one's: its first compression)
    except Exception:  # noqa: BLE001  (the task reports it, with its message)
        pass


def execute(campaign: "Campaign", task: int, payload: Any) -> Outcome:
    """Task number `task`: (state, results, error, started); `payload` is a trial
    task's (forces, errors) (`campaign.trial_inputs`), None for a compression."""
    (kind, i), test = campaign.numbers.key(task), campaign.test
    if kind == COMPRESSION and campaign.kind.compute is not None:
        return compute_node(campaign.shells[i], campaign.timeout_s, campaign.kind.compute)
    if kind == COMPRESSION:
        return compute(campaign.shells[i], campaign.method, campaign.timeout_s, i, test)
    forces, errors = payload
    return compute_study(campaign.studies[i], forces, errors, campaign.timeout_s, test)


def entry(campaign: "Campaign", task: int, attempts: int, rank: int,
          outcome: Outcome) -> CompressionEntry | TrialEntry:
    """Task `task`'s journal entry from its `outcome` = (state, results, error,
    started) as `execute` returns it: a compression's `row` and `results`, or a
    trial task's `task` and per-cell `cells`. A failed task's message ends
    with where it ran, '(rank R on HOST)'."""
    state, results, error, started = outcome
    if state == "failed":
        error = f"{error} (rank {rank} on {_host()})"
    kind, i = campaign.numbers.key(int(task))
    make = compression_entry if kind == COMPRESSION else trial_entry
    return make(i, results, state, error, int(attempts), int(rank), started)


@functools.cache
def _host():
    """This machine's name, as a failed task's message gives it."""
    return socket.gethostname()


def run_task(campaign: "Campaign", task: int, payload: Any, attempts: int,
             rank: int) -> CompressionEntry | TrialEntry:
    """Compute task `task` (attempt `attempts`) on `rank`: its journal entry."""
    return entry(campaign, task, attempts, rank, execute(campaign, task, payload))
