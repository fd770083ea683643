"""A running campaign sent SIGTERM (a SLURM time limit) or SIGINT (Ctrl-C).

`cortex campaign run` is started on tests/data/signals.toml (60 made-up
compressions, then 40 Monte-Carlo trial tasks of 200 cells that each sleep
0.25 s first: at least 10 s of work on one rank however fast the machine),
under one process and under `mpiexec -n 2`. Once the store shows a
finished trial task, the signal goes to the command (SIGTERM, as
jobs/campaign.sbatch sends it to mpiexec) or to its whole process group
(SIGINT, as a terminal's Ctrl-C does). The engine must stop handing out work,
finish and write the tasks in flight, and exit with status 3 and a line saying
how to resume, leaving no task marked running. Rerunning the same command must
then complete the store with every task done exactly once (attempts 1) and the
same numbers as an uninterrupted run.
"""

import os
import signal
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest

from campaign.store.reader import read_results, read_trials, summary
from conftest import BIN, poll_until

CONFIG = Path(__file__).parent / "data" / "signals.toml"
N_TASKS, N_CELLS = 60, 2 * 2 * 10 * 200     # compressions; nu x modes x studies x cells
TRIAL_VALUES = ["volume_used_um3", "h0_used_um", "h1_used_um", "h_tilde", "modulus_mN_per_m",
                "gamma_eff_mN_per_m", "tension_seen_mN_per_m"]


def command(store, ranks):
    run = [str(BIN / "cortex"), "campaign", "run", str(CONFIG), "--store", str(store), "--quiet"]
    return ([str(BIN / "mpiexec"), "-n", str(ranks)] if ranks > 1 else []) + run


def done_trials(store):
    try:
        return summary(store)["trials"]["done"]
    except Exception:  # the store is still being created
        return 0


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The campaign run without interruption (one process)."""
    store = tmp_path_factory.mktemp("reference") / "ref.h5"
    run = subprocess.run(command(store, 1), capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    return read_results(store), read_trials(store)


@pytest.mark.parametrize("ranks, signum, to_group", [
    (1, signal.SIGTERM, False), (1, signal.SIGINT, True),
    (2, signal.SIGTERM, False), (2, signal.SIGINT, True)],
    ids=["1rank-SIGTERM", "1rank-SIGINT-group", "2ranks-SIGTERM-mpiexec", "2ranks-SIGINT-group"])
def test_signal_stops_cleanly_and_rerun_completes(tmp_path, reference, ranks, signum, to_group):
    store = tmp_path / "s.h5"
    proc = subprocess.Popen(command(store, ranks), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    poll_until(lambda: done_trials(store) > 0, 120, "a finished trial task in the store", proc=proc)
    sent = time.monotonic()
    if to_group:
        os.killpg(proc.pid, signum)
    else:
        proc.send_signal(signum)
    try:
        out, err = proc.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        pytest.fail("the campaign did not stop within 60 s of the signal")
    stopped_s = time.monotonic() - sent

    assert proc.returncode == 3, (proc.returncode, err)
    assert "stopped by a signal" in err and "rerun the same command to resume" in err, err
    assert "Traceback" not in err, err
    assert stopped_s < 20, f"took {stopped_s:.1f} s to stop"   # the tasks in flight, not the rest
    partial = summary(store)
    assert partial["running"] == 0 and partial["trials"]["running"] == 0, partial
    assert partial["done"] == N_TASKS                           # compressions are handed out first
    assert 0 < partial["trials"]["done"] < N_CELLS, partial["trials"]
    assert (read_trials(store)["attempts"] <= 1).all()

    rerun = subprocess.run(command(store, ranks), capture_output=True, text=True, timeout=300)
    assert rerun.returncode == 0, rerun.stderr
    results, trials = read_results(store), read_trials(store)
    assert len(results) == N_TASKS and (results["state"] == "done").all()
    assert (results["attempts"] == 1).all()                      # each done exactly once
    attempts = read_trials(store).groupby("trial_id")["attempts"].first()
    assert len(attempts) == N_CELLS and (attempts == 1).all()
    assert (trials["state"] == "done").all()

    ref_results, ref_trials = reference
    np.testing.assert_array_equal(results["task_id"], ref_results["task_id"])
    np.testing.assert_array_equal(results["force_nN"], ref_results["force_nN"])
    np.testing.assert_array_equal(trials["trial_id"], ref_trials["trial_id"])
    for key in TRIAL_VALUES:   # bitwise, NaN where a drawn height is impossible in both
        np.testing.assert_array_equal(trials[key].to_numpy(), ref_trials[key].to_numpy(), err_msg=key)


def _catches_sigterm(pid):
    """Whether process `pid` has a handler for SIGTERM (Linux: SigCgt in /proc)."""
    with open(f"/proc/{pid}/status") as fh:
        mask = next(int(line.split()[1], 16) for line in fh if line.startswith("SigCgt:"))
    return bool(mask >> (signal.SIGTERM - 1) & 1)


def _mpi_loaded(pid):
    with open(f"/proc/{pid}/maps") as fh:
        return "libmpi" in fh.read()


@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="needs Linux /proc")
def test_sigterm_during_start_up_stops_cleanly(tmp_path, reference):
    """SIGTERM as soon as `cortex campaign run` catches it: that must be early
    in its start-up (before it loads MPI, well before the store exists), and
    the signal then gives exit 3 with the resume line (not 143), and the rerun
    completes the campaign."""
    store = tmp_path / "s.h5"
    proc = subprocess.Popen(command(store, 1), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    poll_until(lambda: _catches_sigterm(proc.pid), 60, "a SIGTERM handler in the command", proc=proc,
               every_s=0.001)
    early = not _mpi_loaded(proc.pid)       # read after the handler was seen: it came first
    proc.send_signal(signal.SIGTERM)
    out, err = proc.communicate(timeout=60)
    assert early, "SIGTERM was caught only once MPI was loaded: a signal before that ends the run with 143"
    assert proc.returncode == 3, (proc.returncode, err)
    assert "rerun the same command to resume" in err and "Traceback" not in err, err
    rerun = subprocess.run(command(store, 1), capture_output=True, text=True, timeout=300)
    assert rerun.returncode == 0, rerun.stderr
    results = read_results(store)
    assert (results["attempts"] == 1).all()
    np.testing.assert_array_equal(results["force_nN"], reference[0]["force_nN"])
