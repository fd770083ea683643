"""The test suite's fault injection: what a campaign's `[test]` section asks
for, installed through the product's one registration point
(`campaign.task_hooks`): the environment variable CORTEX_TASK_HOOKS names
this module (`environment()`; tests/conftest.py sets it for the test session
and every process it starts: the ranks under mpiexec and their task
processes inherit it). Without it the product refuses a `[test]` section.

Nothing here runs unless a campaign file has a `[test]` section (or, for the
kill, the environment variable below is set); only the scheduler calls
these hooks (the store gets the kill as its `on_record`, knowing nothing of
it). The knobs (`parse`):

    raise_task, hang_task, nan_task   grid indices whose compression raises,
                                      sleeps past the per-task timeout, or
                                      returns NaN instead of being solved
    memory_task                       grid indices whose compression asks for
                                      1 TB at once (a MemoryError under
                                      [solver] memory_limit_mb)
    segv_task, spin_task              grid indices whose compression crashes
                                      its process (a read of address 0: a real
                                      SIGSEGV) or spins forever in compiled
                                      code (`spin`, where no Python signal
                                      handler runs, so only the watchdog of
                                      `campaign.isolation` ends it)
    noop = true       every compression returns zeros at once (throughput benchmark)
    fake_law = true   every compression returns at once the force of a made-up
                      smooth law (`fake_law`; tests of the trials and the analysis)
    compression_sleep_s, trial_sleep_s   every compression / every Monte-Carlo
                      trial task first sleeps this many seconds (default 0):
                      a known wall time that uses no CPU, so a test can kill or
                      signal a run that is surely still going, on a machine of
                      any speed. The sleep counts towards the task's timeout_s.

`kill_mid_write`: with CORTEX_TEST_KILL_MID_WRITE=ROW (a compression's grid
index) or =taskJ (trial task J), rank 0 journals that task's entry, writes its
rows (and marks a compression done), then kills itself with SIGKILL: the
moment between "rows written" and "the file says the journal is in". The
store knows nothing of it: `record_hook()` is what the scheduler hands the
store as its `on_record` (None unless the variable is set).

None of these changes a task's numbers or the campaign's fingerprint, so a
store made with them is resumed (and compared) with or without them.
"""

import math
import os
import signal
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from campaign import task_hooks
from campaign.store.schema import RESULTS
from campaign.task_key import COMPRESSION, entry_key
from common.errors import InputError

FAULTS = ("raise", "hang", "nan", "segv", "spin", "memory", "noop", "fake_law")
ROW_KEYS = ("raise_task", "hang_task", "nan_task", "segv_task", "spin_task", "memory_task")
SLEEP_KEYS = ("compression_sleep_s", "trial_sleep_s")
KEYS = set(ROW_KEYS) | set(SLEEP_KEYS) | {"noop", "fake_law"}
HANG_S = 1e6            # "forever" for a hung task: only the per-task timeout ends it
KILL_ENV = "CORTEX_TEST_KILL_MID_WRITE"
HERE = Path(__file__).resolve().parent


def environment(base: dict[str, str] | None = None) -> dict[str, str]:
    """The variables that install these faults in a process and every process
    it starts: `base` (default os.environ) with CORTEX_TASK_HOOKS naming this
    module, and this folder and the repository root (`studies`, which the fake
    law comes from) on PYTHONPATH."""
    base = dict(os.environ if base is None else base)
    path = [p for p in base.get("PYTHONPATH", "").split(os.pathsep) if p]
    for folder in (str(HERE.parent), str(HERE)):
        if folder not in path:
            path.insert(0, folder)
    return {**base, task_hooks.ENV: "faults", "PYTHONPATH": os.pathsep.join(path)}


@dataclass(frozen=True)
class Knobs:
    """The parsed `[test]` section; the default asks for nothing."""
    by_row: dict = field(default_factory=dict)    # grid index -> one of FAULTS
    compression_sleep_s: float = 0.0
    trial_sleep_s: float = 0.0
    every_row: str | None = None                  # noop or fake_law: the fault of the rows by_row leaves out

    def fault(self, row: int) -> str | None:
        """Compression `row`'s fault (one of FAULTS), or None. (`every_row` is
        one name, not a dict of every row: a million no-op rows took 70 MB on each rank.)"""
        return self.by_row.get(row, self.every_row)

    # campaign.task_hooks.TaskHooks: how the product's tasks meet the knobs

    def prepare(self, row: int, shell: Any) -> None:
        """Before compression `row`'s timer: what its fault needs loaded (`prepare`)."""
        fault = self.fault(row)
        if fault:
            prepare(fault, shell)

    def compression(self, row: int, shell: Any, solve: Callable[[], dict[str, Any]]) -> dict[str, Any]:
        """Compression `row`: its sleep, then its fault's result, or `solve()`'s without one."""
        pause(self.compression_sleep_s)
        fault = self.fault(row)
        return injected(fault, shell) if fault else solve()

    def trial(self, run: Callable[[], dict[str, Any]]) -> dict[str, Any]:
        """A trial task: its sleep, then `run()`."""
        pause(self.trial_sleep_s)
        return run()

    def warm_up(self, shell: Any) -> bool:
        """Every fault of the campaign prepared (`shell`: compression 0); True
        if compression 0 has a fault (so the solver needs no warm-up)."""
        fault = self.fault(0)
        for other in set(self.by_row.values()) - {fault}:
            prepare(other, shell)
        if fault:
            prepare(fault, shell)
        return bool(fault)


def parse(path: str, table: dict[str, Any], n_rows: int) -> Knobs:
    """The `[test]` table of campaign file `path` (grid of `n_rows`) as Knobs;
    InputError with one line if a key or a value is wrong."""
    unknown = set(table) - KEYS
    if unknown:
        raise InputError(f"{path}: unknown key {sorted(unknown)[0]!r} in [test]")
    table = dict(table)
    by_row, every_row = {}, None
    for key in ("noop", "fake_law"):
        value = table.pop(key, False)
        if not isinstance(value, bool):
            raise InputError(f"{path}: [test] {key} must be true or false (got {value!r})")
        if value and every_row is None:
            every_row = key
    sleeps = {}
    for key in SLEEP_KEYS:
        value = table.pop(key, 0.0)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 <= value < math.inf:
            raise InputError(f"{path}: [test] {key} must be a number of seconds >= 0 (got {value!r})")
        sleeps[key] = float(value)
    for key, value in table.items():
        for row in value if isinstance(value, list) else [value]:
            if isinstance(row, bool) or not isinstance(row, int) or not 0 <= row < n_rows:
                raise InputError(f"{path}: [test] {key} must be grid indices 0..{n_rows - 1} (got {row!r})")
            by_row[row] = key.removesuffix("_task")
    return Knobs(by_row=by_row, every_row=every_row, **sleeps)


def pause(seconds: float) -> None:
    """Sleep `seconds` of wall time (no CPU); nothing for 0."""
    if seconds > 0:
        time.sleep(seconds)


def prepare(fault: str, shell: Any) -> None:
    """Load, before the task's timer starts, what `injected(fault, shell)` needs
    (the imports and the compiled droplet geometry of the fake law): a short
    test timeout then times the fault itself, not a process's start-up, on a
    machine of any speed. Once per process and shape."""
    if fault == "fake_law":
        import studies.synthetic  # noqa: F401  (the law's coefficients: its import outside the timer)
        from solver.geometry import droplet
        from solver.modulus import effective_modulus
        effective_modulus(shell.volume_um3, shell.h0_um, shell.h1_um, shell.tension_mN_per_m, 0.0)
        droplet(shell.volume_um3, shell.h1_um)
    if fault == "spin":
        _spin()(0.0)                    # compiled (or loaded from numba's cache); returns at once for 0


_compiled: dict[str, Callable[[float], float]] = {}


def _spin():
    """The compiled loop of `spin_task`, spin(x): x += 2 until x is 0.
    spin(0.0) returns at once; from x = 1.0 the loop never ends (x grows, odd,
    until x + 2 rounds to x): a task stuck in compiled code, which no Python
    signal interrupts. (A float, so the compiler cannot reason the loop away
    as it may an integer one.) Compiled once (numba's on-disk cache)."""
    if "spin" not in _compiled:
        from numba import njit

        @njit(cache=True)
        def spin(x):
            while x != 0.0:
                x += 2.0
            return x
        _compiled["spin"] = spin
    return _compiled["spin"]


def injected(fault: str, shell: Any) -> dict[str, Any]:
    """The result (or the failure) of `fault` for compression `shell`."""
    if fault == "raise":
        raise RuntimeError("injected fault: this task raises")
    if fault == "hang":
        time.sleep(HANG_S)
    if fault == "segv":
        import ctypes
        ctypes.string_at(0)             # a read of address 0: the process dies of SIGSEGV
    if fault == "spin":
        _spin()(1.0)                    # never returns
    if fault == "memory":
        import numpy as np
        np.ones(2**37)                  # 1 TB
    if fault == "fake_law":
        return fake_law(shell)
    return dict.fromkeys(RESULTS, 0.0 if fault == "noop" else math.nan)


def _cubic(coefficients, x):
    return sum(c * x**i for i, c in enumerate(coefficients))


def fake_law(shell: Any) -> dict[str, Any]:
    """The result of the made-up law of the analysis's synthetic stores
    (`studies.synthetic.REFERENCE_*`) instead of a solve, with the force
    that gives it, F = (γ_a + K ε_A) 2 H(h1) A_c(h1) (SPEC 3 backwards), and
    K and the rest then from that force exactly as after a solve."""
    from studies.synthetic import REFERENCE_C, REFERENCE_D, REFERENCE_LAMBDA
    from solver.geometry import droplet
    from solver.modulus import effective_modulus
    V, h0, h1, bulk, g = shell.volume_um3, shell.h0_um, shell.h1_um, shell.bulk_mN_per_m, shell.tension_mN_per_m
    geo = effective_modulus(V, h0, h1, g, 0.0)
    gt = g / bulk
    alpha = _cubic(REFERENCE_C, gt) * math.log(shell.shear_mN_per_m / bulk) + _cubic(REFERENCE_D, gt)
    K = bulk * (1.0 + alpha * math.exp(float(geo["h_tilde"]) / REFERENCE_LAMBDA))
    force = (g + K * float(geo["area_strain"])) * float(droplet(V, h1).force_per_tension_um)
    out = {k: float(v) for k, v in effective_modulus(V, h0, h1, g, force).items()}
    out.update(force_nN=force, area_strain_shell=out["area_strain"], volume_error=0.0,
               equator_shear_ratio=0.0, iterations=0, wall_s=0.0, converged=True)
    return out


def record_hook() -> Callable[[Any, dict[str, Any]], None] | None:
    """The store's `on_record` hook: `kill_mid_write` if KILL_ENV is set, else None."""
    return kill_mid_write if os.environ.get(KILL_ENV) is not None else None


def kill_mid_write(store: Any, entry: dict[str, Any]) -> None:
    """SIGKILL rank 0 right after `entry`'s rows are written, if KILL_ENV names it."""
    kill, (kind, i) = os.environ.get(KILL_ENV), entry_key(entry)
    if kill is None or kill != (str(i) if kind == COMPRESSION else f"task{i}"):
        return
    store.flush(rows=True)                 # written, then killed: the replay must not redo it
    if kind == COMPRESSION:
        from campaign.store.schema import DONE
        store.file["state"][i] = DONE
    os.kill(os.getpid(), signal.SIGKILL)
