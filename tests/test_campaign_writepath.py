"""The store's two write paths (campaign.store, campaign.store.mpio_writer): parallel HDF5 (mpio, every
rank writes its own rows) and rank 0 writing every row give the same rows,
bit for bit, for the demo campaign (real solves and Monte-Carlo trials) under
1, 2 and 3 ranks, and the mpio path survives SIGKILL as the rank-0 path does.

These run where h5py was built with MPI: `make test-mpi-parallel` runs this
file with .venv-mpio's Python (`.venv-mpio/bin/with-mpi`). Elsewhere they
skip, saying so, except the check that forcing mpio there is refused."""

import json
import os
import subprocess

import h5py
import numpy as np
import pytest
from conftest import BIN, ROOT, journal_counts, poll_until

from campaign.store.verify import verify

DEMO = ROOT / "campaigns" / "demo.toml"
N_COMPRESSIONS, N_TRIAL_TASKS = 60, 20                 # the demo's tasks
TIMING = {"rank", "started_unix_s", "wall_s", "checksum"}   # who and when (a row's checksum covers both): differ between any two runs
MPI_H5PY = bool(h5py.get_config().mpi)
needs_mpio = pytest.mark.skipif(not MPI_H5PY, reason="h5py here was built without MPI "
                                "(make test-mpi-parallel runs this with .venv-mpio, which has it)")


def run(store, ranks, *extra, env=None, wait=True, config=DEMO):
    cmd = [str(BIN / "mpiexec"), "-n", str(ranks), str(BIN / "cortex"), "campaign", "run", str(config),
           "--store", str(store), *extra]
    if not wait:
        return subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                start_new_session=True, env={**os.environ, **(env or {})})
    return subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, timeout=600,
                          env={**os.environ, **(env or {})})


def rows(store):
    """Every dataset of the store but the timing ones, and the runs' provenance; every row's
    checksum holds (`campaign.store.verify`: the rank that wrote it computed it)."""
    assert verify(store) == []
    out = {}
    with h5py.File(store, "r") as f:
        def take(name, obj):
            if isinstance(obj, h5py.Dataset) and name.split("/")[-1] not in TIMING:
                out[name] = obj.asstr()[:] if h5py.check_string_dtype(obj.dtype) else obj[:]
        f.visititems(take)
        return out, json.loads(f.attrs["runs"])


def assert_same_rows(a, b):
    assert a.keys() == b.keys()
    for key in a:
        assert a[key].dtype == b[key].dtype, key
        assert np.array_equal(a[key], b[key], equal_nan=a[key].dtype.kind == "f"), key


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The demo campaign on 2 ranks, rank 0 writing every row."""
    store = tmp_path_factory.mktemp("rank0") / "demo.h5"
    out = run(store, 2, "--write-path", "rank0")
    assert out.returncode == 0, out.stderr
    assert "store writes: rank0" in out.stderr
    return rows(store)


@needs_mpio
@pytest.mark.parametrize("ranks", [1, 2, 3])
def test_mpio_gives_the_rows_of_rank0(reference, tmp_path, ranks):
    extra = ("--write-path", "mpio") if ranks == 1 else ()       # auto picks mpio from 2 ranks on
    out = run(tmp_path / "demo.h5", ranks, *extra)
    assert out.returncode == 0, out.stderr
    assert "store writes: mpio (parallel HDF5)" in out.stderr
    got, runs = rows(tmp_path / "demo.h5")
    assert runs[-1]["write_path"] == "mpio" and runs[-1]["ranks"] == ranks
    assert_same_rows(reference[0], got)
    assert (got["state"] == 2).all() and (got["attempts"] == 1).all()     # all done (2), once
    assert (got["trials/state"] == 2).all() and np.isfinite(got["trials/modulus_mN_per_m"]).any()
    with h5py.File(tmp_path / "demo.h5", "r") as f:
        if ranks > 1:     # the workers wrote rows themselves (rank 0, warming up as they start, may compute none)
            assert set(range(1, ranks)) <= set(f["rank"][:]) <= set(range(ranks))
        assert f.attrs["journal_bytes"] == os.path.getsize(f"{tmp_path / 'demo.h5'}.journal")


# The demo with every task sleeping first (a [test] knob that changes no number):
# 60 x 0.15 s of compressions and 20 x 0.5 s of trials on 2 ranks, so each
# stage outlasts the 2 s between two journal writes on a machine of any speed.
SLEEPY = "\n[test]\ncompression_sleep_s = 0.15\ntrial_sleep_s = 0.5\n"


@needs_mpio
@pytest.mark.parametrize("moment", ["3", "task4"])
def test_mpio_killed_mid_write_then_rerun_gives_the_same_rows(reference, tmp_path, moment):
    """Rank 0 journals an entry, marks its row done in the file and is killed
    before the worker (if it computed it) wrote the rest: the rerun's replay fixes it.
    The tasks sleep (SLEEPY), so they come back one batch at a time, spread over
    the run, and the journal is surely incomplete when compression 3 or trial task
    4 is written (without the sleeps one batch may hold every trial task)."""
    store, config = tmp_path / "demo.h5", tmp_path / "demo.toml"
    config.write_text(DEMO.read_text() + SLEEPY)
    killed = run(store, 2, env={"CORTEX_TEST_KILL_MID_WRITE": moment}, config=config)
    assert killed.returncode != 0
    done, trial_tasks = journal_counts(store)        # killed on its own progress, mid-run
    assert 0 < done + trial_tasks < N_COMPRESSIONS + N_TRIAL_TASKS
    rerun = run(store, 2, config=config)
    assert rerun.returncode == 0, rerun.stderr
    got, _ = rows(store)
    assert_same_rows(reference[0], got)
    assert (got["attempts"] == 1).all() and (got["trials/attempts"] == 1).all()


MOMENTS = {   # journal_counts(store) -> whether to kill now
    "start-up": lambda n: n == (0, 0),                        # the journal made, nothing in it yet
    "compressions": lambda n: 0 < n[0] < N_COMPRESSIONS,
    "trials": lambda n: 0 < n[1] < N_TRIAL_TASKS,
}


@needs_mpio
@pytest.mark.parametrize("moment", list(MOMENTS))
def test_mpio_sigkill_then_rerun_gives_the_same_rows(reference, tmp_path, moment):
    """SIGKILL to every rank at start-up, among the compressions and among the
    trials, each seen in the journal while the run goes on; the rerun of the
    same command gives the rows of the uninterrupted run."""
    store, config = tmp_path / "demo.h5", tmp_path / "demo.toml"
    config.write_text(DEMO.read_text() + SLEEPY)
    proc = run(store, 2, wait=False, config=config)
    try:
        poll_until(lambda: os.path.exists(f"{store}.journal") and MOMENTS[moment](journal_counts(store)),
                   300, f"the journal at {moment}", proc=proc)
    finally:
        os.killpg(proc.pid, 9)
        proc.wait()
    assert sum(journal_counts(store)) < N_COMPRESSIONS + N_TRIAL_TASKS     # killed before the end
    rerun = run(store, 2, config=config)
    assert rerun.returncode == 0, rerun.stderr
    got, _ = rows(store)
    assert_same_rows(reference[0], got)
    assert (got["attempts"] == 1).all() and (got["trials/attempts"] == 1).all()


@pytest.mark.skipif(MPI_H5PY, reason="h5py here has MPI: forcing mpio is allowed")
def test_forcing_mpio_without_mpi_h5py_is_refused(tmp_path):
    out = subprocess.run([str(BIN / "cortex"), "campaign", "run", str(DEMO), "--store", str(tmp_path / "s.h5"),
                          "--write-path", "mpio"], capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert out.returncode == 2
    assert out.stderr.strip().count("\n") == 0 and "built without MPI" in out.stderr
    assert not (tmp_path / "s.h5").exists()
