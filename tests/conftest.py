"""What the tests share: ROOT, the project checkout (commands run there), and
BIN, the virtual environment's bin directory (`cortex`, `mpiexec`); `cortex`,
the one way a test runs the installed command (optionally under mpiexec); and the
one way a test waits for something: `poll_until` a condition it can observe
(a journal entry, a state in the store, a job's state), never a guessed
number of seconds. `journal_counts` is the progress a campaign test observes.

`--serial {only,skip}` picks the tests marked `serial` (those that must not run
beside another test: docs/testing.md) or all the others; `make test-serial`
runs the others on two processes (pytest-xdist, `-n 2`), then these alone.

The test suite's faults (`faults.py`: a campaign file's `[test]` section) are
installed here for the session and every process it starts (`cortex` under
mpiexec, the task processes): the environment names them
(`faults.environment()`, `campaign.task_hooks`)."""

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

import faults

os.environ.update(faults.environment())
ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent
POLL_S = 0.01           # between two looks: short against any task a test waits for
CORTEX = BIN / "cortex"


def pytest_addoption(parser):
    parser.addoption("--serial", choices=("only", "skip"), default=None,
                     help="only the tests marked `serial`, or all but them (default: every test)")


def pytest_collection_modifyitems(config, items):
    """Deselect by `--serial`: a test is serial if it, its class or its module has the marker."""
    pick = config.getoption("serial")
    if pick is None:
        return
    wanted = pick == "only"
    keep = [item for item in items if (item.get_closest_marker("serial") is not None) == wanted]
    drop = [item for item in items if (item.get_closest_marker("serial") is not None) != wanted]
    if drop:
        config.hook.pytest_deselected(items=drop)
        items[:] = keep


def cortex(*args, env=None, mpi=0, timeout=600):
    """`cortex ARGS` as a user runs it (the installed command, from ROOT, stdin
    closed), under `mpiexec -n MPI` if `mpi`; `env` adds to the environment.
    The CompletedProcess, with text stdout and stderr."""
    cmd = ([str(BIN / "mpiexec"), "-n", str(mpi)] if mpi else []) + [str(CORTEX), *map(str, args)]
    return subprocess.run(cmd, capture_output=True, text=True, env={**os.environ, **(env or {})},
                          cwd=ROOT, timeout=timeout, stdin=subprocess.DEVNULL)


@pytest.fixture(name="cortex")
def cortex_fixture():
    """The `cortex` helper as a fixture, for tests that take it as an argument."""
    return cortex


def poll_until(condition, timeout_s, what, proc=None, every_s=POLL_S):
    """Call `condition()` until it returns something true, and return that.

    Fails the test, naming `what`, if `timeout_s` pass first (a bound for a
    hung run, not a guess at its speed), or if the process `proc` (a Popen)
    ends first: then whatever was waited for cannot happen any more."""
    deadline = time.monotonic() + timeout_s
    while True:
        got = condition()
        if got:
            return got
        if proc is not None and proc.poll() is not None:
            pytest.fail(f"the process ended (status {proc.returncode}) before {what}")
        if time.monotonic() > deadline:
            pytest.fail(f"not within {timeout_s:g} s: {what}")
        time.sleep(every_s)


def on_one_and_two_ranks(tmp, config, name):
    """The campaign file `config` run into TMP/NAME1.h5 on 1 rank and TMP/NAME2.h5 under
    `mpiexec -n 2`: {ranks: store}."""
    out = {}
    for ranks in (1, 2):
        store = tmp / f"{name}{ranks}.h5"
        done = cortex("campaign", "run", config, "--store", store, "--quiet", mpi=ranks if ranks > 1 else 0)
        assert done.returncode == 0, done.stderr
        out[ranks] = store
    return out


def in_one_thread(code, arg):
    """The JSON that `python -c code arg` prints, in a fresh process on one BLAS thread (as a
    campaign rank computes)."""
    import json
    done = subprocess.run([sys.executable, "-c", code, arg], capture_output=True, text=True,
                          cwd=ROOT, env={**os.environ, "OPENBLAS_NUM_THREADS": "1"}, timeout=300)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)


def journal_counts(store):
    """(compression entries, trial-task entries) in the journal of `store`
    as it is on disk now (0, 0 before it exists)."""
    from campaign.store import journal
    from campaign.task_key import split
    compressions, trials = split(journal.read(f"{store}.journal"))
    return len(compressions), len(trials)


def first_heights(monkeypatch, n):
    """`afm synth` draws its cells with only their first `n` mean heights (small time-domain cells)."""
    from analysis.afm.synth import cells as sy
    draw = sy.parameters

    def keep(i, rng):
        p, truth = draw(i, rng)
        p["h_means"] = p["h_means"][:n]
        return p, truth
    monkeypatch.setattr(sy, "parameters", keep)
