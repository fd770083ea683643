"""A task that kills its process or spins in compiled code (campaign.isolation).

The demo grid's compressions (campaigns/demo.toml without its Monte-Carlo
study: 60 real solves) with one shell made to misbehave, h0 = 12 µm and
K_S = 8.33 mN/m (its four tensions), by the test knobs of tests/faults.py:
`segv_task` (a read of address 0: the task process dies of SIGSEGV) or
`spin_task` (a loop in compiled code, which the task process's SIGALRM
cannot end: only the rank's watchdog, past timeout_s + GRACE_S, does). One
`cortex campaign run`, under one process and under `mpiexec -n 2`, must end
with status 1, the four failed with a message naming what happened, and the
other 56 done with the numbers of an undisturbed run, bit for bit, on the
write path h5py here allows (rank 0 writing; parallel HDF5 under
.venv-mpio). The spinning task is found by the timeout, never by a guessed sleep.
"""

import json
import re
from pathlib import Path

import h5py
import numpy as np
import pytest

from campaign import config
from campaign.isolation import GRACE_S
from campaign.store.reader import read_results
from conftest import ROOT, cortex

DEMO = (ROOT / "campaigns" / "demo.toml").read_text().split("# SPEC 5")[0]   # its compressions
TIMEOUT_S = 2.0          # a demo solve takes milliseconds: the spin's timeout, kept short
VALUES = ["force_nN", "modulus_mN_per_m", "h_tilde", "volume_error", "iterations"]
# the store's write path: parallel HDF5 where h5py has MPI (make test-mpi-parallel runs this file with
# .venv-mpio), else rank 0 writing every row
WRITE_PATH = "mpio" if h5py.get_config().mpi else "rank0"


def campaign_file(folder, test=""):
    path = Path(folder) / "demo.toml"
    path.write_text(DEMO.replace("timeout_s = 120.0", f"timeout_s = {TIMEOUT_S}") + test)
    return path


def bad_rows(path):
    """The grid indices of the bad shell: h0 = 12 µm, K_S = 8.33 mN/m."""
    shells = config.load(path).shells
    return [i for i, s in enumerate(shells) if s.h0_um == 12.0 and s.shear_mN_per_m == 8.33]


@pytest.fixture(scope="module")
def undisturbed(tmp_path_factory):
    folder = tmp_path_factory.mktemp("undisturbed")
    store = folder / "s.h5"
    out = cortex("campaign", "run", campaign_file(folder), "--store", store, "--quiet", mpi=2)
    assert out.returncode == 0, out.stderr
    return read_results(store)


CASES = {"segv": r"process died of SIGSEGV while computing this task \(rank \d on [^)]+\)",
         "spin": rf"no answer after {TIMEOUT_S:g} s \(\+ {GRACE_S:g} s grace\): the process was killed"}


@pytest.mark.parametrize("ranks", [2, 1], ids=["2ranks", "1rank"])
@pytest.mark.parametrize("fault", list(CASES))
def test_a_task_that_kills_or_wedges_its_process_fails_alone(undisturbed, tmp_path, fault, ranks):
    path = campaign_file(tmp_path)
    rows = bad_rows(path)
    assert len(rows) == 4
    path = campaign_file(tmp_path, f"\n[test]\n{fault}_task = {rows}\n")
    store = tmp_path / "s.h5"
    out = cortex("campaign", "run", path, "--store", store, "--quiet", "--write-path", WRITE_PATH,
                 mpi=ranks if ranks > 1 else 0)
    assert out.returncode == 1, out.stderr
    with h5py.File(store, "r") as f:
        assert json.loads(f.attrs["runs"])[-1]["write_path"] == WRITE_PATH
    assert "4 tasks failed" in out.stderr and "Traceback" not in out.stderr, out.stderr

    frame = read_results(store)
    failed = np.flatnonzero(frame["state"] == "failed")
    assert failed.tolist() == rows
    for message in frame["error"][failed]:
        assert re.search(CASES[fault], message), message
    done = frame.drop(index=rows)
    assert (done["state"] == "done").all() and len(done) == 56
    assert (frame["attempts"] == 1).all()
    for key in VALUES:                        # bit for bit, as undisturbed
        np.testing.assert_array_equal(done[key].to_numpy(), undisturbed.drop(index=rows)[key].to_numpy(),
                                      err_msg=key)

    status = json.loads(cortex("campaign", "status", store, "--json").stdout)
    assert status["failed"] == 4 and status["done"] == 56
    listed = status["failed_tasks"]
    assert [t["row"] for t in listed] == rows
    for task in listed:
        assert task["h0_um"] == 12.0 and task["shear_mN_per_m"] == 8.33 and task["bending"] == "standard"
        assert task["rank"] in range(ranks) and task["host"] and re.search(CASES[fault], task["error"])
    if (fault, ranks) == ("segv", 2):         # the partial analysis names them in its report
        out = cortex("analysis", "calibrate", store, "--out", tmp_path / "analysis", "--partial")
        assert out.returncode == 0, out.stderr
        report = (tmp_path / "analysis" / "report.md").read_text()
        assert "Failed compression tasks (4)" in report
        for task in listed:
            assert f"| {task['task_id']} | 12 | 8.33 | {task['tension_mN_per_m']:g} | standard | process died of " \
                   "SIGSEGV" in report
    # a rerun leaves the failed tasks alone (nothing computed again) and still ends with status 1
    rerun = cortex("campaign", "run", path, "--store", store, "--quiet", mpi=ranks if ranks > 1 else 0)
    again = read_results(store)
    assert rerun.returncode == 1 and "4 tasks failed" in rerun.stderr, rerun.stderr
    assert (again["attempts"] == 1).all()
    assert again["state"].tolist() == frame["state"].tolist()


def test_retries_and_the_memory_limit(tmp_path):
    """[solver] retries = 1: a crashing task is computed twice (attempts 2),
    then failed; [solver] memory_limit_mb: a task asking for more fails alone,
    its message naming the limit; the solves beside them are done."""
    path = campaign_file(tmp_path)
    rows = bad_rows(path)
    text = path.read_text().replace(f"timeout_s = {TIMEOUT_S}", "timeout_s = 60.0\nmemory_limit_mb = 1500\nretries = 1")
    path.write_text(text + f"\n[test]\nsegv_task = [{rows[0]}]\nmemory_task = [{rows[1]}]\n")
    store = tmp_path / "s.h5"
    out = cortex("campaign", "run", path, "--store", store, "--quiet", mpi=2)
    assert out.returncode == 1 and "2 tasks failed" in out.stderr, out.stderr
    frame = read_results(store)
    assert np.flatnonzero(frame["state"] == "failed").tolist() == rows[:2]
    assert frame["attempts"][rows[0]] == 2 and "died of SIGSEGV" in frame["error"][rows[0]]
    assert frame["attempts"][rows[1]] == 1               # a MemoryError is the task's answer, not retried
    assert "MemoryError" in frame["error"][rows[1]] and "limited to 1500 MB" in frame["error"][rows[1]]
    assert (frame.drop(index=rows[:2])["state"] == "done").all()


@pytest.mark.parametrize("table, message", [
    ({"retries": -1}, "[solver] retries must be an integer >= 0"),
    ({"retries": 1.5}, "[solver] retries must be an integer >= 0"),
    ({"memory_limit_mb": 0}, "[solver] memory_limit_mb must be a positive number of MB"),
    ({"memory_limit_mb": "lots"}, "[solver] memory_limit_mb must be a positive number of MB"),
])
def test_bad_isolation_settings_are_refused_in_one_line(tmp_path, table, message):
    path = campaign_file(tmp_path)
    key, value = next(iter(table.items()))
    path.write_text(path.read_text().replace("[solver]", f"[solver]\n{key} = {value!r}".replace("'", '"')))
    out = cortex("campaign", "run", path, "--store", tmp_path / "s.h5", "--quiet")
    assert out.returncode == 2 and message in out.stderr and len(out.stderr.strip().splitlines()) == 1, out.stderr
    assert not (tmp_path / "s.h5").exists()


SLOW = """
[campaign]
name = "slow"
[grid]
h0_um = [12.0, 11.0, 10.0]
bulk_mN_per_m = 25.0
shear_mN_per_m = 8.33
tension_mN_per_m = [1.0, 2.0]
[test]
fake_law = true
compression_sleep_s = 1.0
"""


def _children(pid):
    """Every descendant of process `pid` (Linux /proc)."""
    found, todo = [], [pid]
    while todo:
        parent = todo.pop()
        for task in Path(f"/proc/{parent}/task").iterdir():
            kids = (task / "children").read_text().split() if (task / "children").exists() else []
            found += map(int, kids)
            todo += map(int, kids)
    return found


def _worker_rank(mpiexec_pid):
    """The pid of rank 1: the process with PMI_RANK=1 whose parent is not itself a rank (its task process is)."""
    for pid in _children(mpiexec_pid):
        try:
            env = Path(f"/proc/{pid}/environ").read_bytes().split(b"\0")
            parent = int(Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[1])
            parent_env = Path(f"/proc/{parent}/environ").read_bytes().split(b"\0")
        except (FileNotFoundError, ProcessLookupError):
            continue
        if b"PMI_RANK=1" in env and b"PMI_RANK=1" not in parent_env:
            return pid
    return None


@pytest.mark.skipif(not Path("/proc/self/task").exists(), reason="needs Linux /proc")
def test_a_worker_rank_killed_from_outside_ends_the_job_and_the_rerun_is_identical(tmp_path):
    """SIGKILL to rank 1 alone (not its task process, not mpiexec) while it
    computes: the job ends (MPI takes the other rank down), no task process is
    left behind, and the rerun completes with the numbers of an undisturbed run."""
    import os
    import signal
    import subprocess
    from conftest import BIN, journal_counts, poll_until
    (tmp_path / "slow.toml").write_text(SLOW)
    reference = tmp_path / "ref.h5"
    assert cortex("campaign", "run", tmp_path / "slow.toml", "--store", reference, "--quiet").returncode == 0
    store = tmp_path / "s.h5"
    args = [str(BIN / "cortex"), "campaign", "run", str(tmp_path / "slow.toml"), "--store", str(store), "--quiet"]
    proc = subprocess.Popen([str(BIN / "mpiexec"), "-n", "2", *args], cwd=ROOT, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        poll_until(lambda: os.path.exists(f"{store}.journal") and journal_counts(store)[0] >= 1, 120,
                   "a finished task in the journal", proc=proc)
        rank1 = poll_until(lambda: _worker_rank(proc.pid), 60, "rank 1's process", proc=proc)
        family = [rank1] + _children(rank1)               # the rank and its task process
        assert len(family) == 2, family
        os.kill(rank1, signal.SIGKILL)
        status = proc.wait(timeout=120)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert status != 0
    assert journal_counts(store)[0] < 6                      # killed before the end
    poll_until(lambda: not any(Path(f"/proc/{p}").exists() for p in family), 60, "no process of rank 1 left")
    rerun = cortex("campaign", "run", tmp_path / "slow.toml", "--store", store, "--quiet", mpi=2)
    assert rerun.returncode == 0, rerun.stderr
    frame, ref = read_results(store), read_results(reference)
    assert (frame["state"] == "done").all()
    for key in VALUES:
        np.testing.assert_array_equal(frame[key].to_numpy(), ref[key].to_numpy(), err_msg=key)


def test_the_default_memory_limit_shares_the_node_among_its_ranks(monkeypatch):
    import os
    from campaign.isolation import memory_share_mb
    for key in ("MPI_LOCALNRANKS", "OMPI_COMM_WORLD_LOCAL_SIZE", "SLURM_NTASKS_PER_NODE"):
        monkeypatch.delenv(key, raising=False)
    total_mb = os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE") / 2**20
    assert memory_share_mb() == total_mb
    monkeypatch.setenv("MPI_LOCALNRANKS", "4")               # MPICH's mpiexec, 4 ranks on this node
    assert memory_share_mb() == total_mb / 4
    monkeypatch.delenv("MPI_LOCALNRANKS")
    monkeypatch.setenv("SLURM_NTASKS_PER_NODE", "8")
    assert memory_share_mb() == total_mb / 8
