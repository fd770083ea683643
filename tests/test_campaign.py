"""The campaign engine: config validation, resume, kill safety, ranks."""

import os
import subprocess

import numpy as np
import pandas as pd
import pytest

from campaign.store.reader import read_results, summary
from conftest import BIN, ROOT, cortex, journal_counts, poll_until

TINY = """
[campaign]
name = "tiny"
[grid]
h0_um = [12.0, 11.0]
bulk_mN_per_m = 0.0
shear_mN_per_m = 0.0
tension_mN_per_m = [1.0, 2.0]
bending = "none"
[solver]
timeout_s = 120.0
"""
RESULT_COLUMNS = ["force_nN", "modulus_mN_per_m", "h_tilde", "volume_error"]


@pytest.fixture(scope="module")
def reference_store(tmp_path_factory):
    d = tmp_path_factory.mktemp("ref")
    (d / "tiny.toml").write_text(TINY)
    out = cortex("campaign", "run", str(d / "tiny.toml"), "--store", str(d / "s.h5"), "--quiet")
    assert out.returncode == 0, out.stderr
    return d / "s.h5"


def test_runs_every_task_once_and_status_reads_it(reference_store):
    frame = read_results(reference_store)
    assert list(frame["state"]) == ["done"] * 4
    assert (frame["attempts"] == 1).all()
    assert np.isfinite(frame["force_nN"]).all()
    out = cortex("campaign", "status", str(reference_store))
    assert "4 done" in out.stdout


def test_status_of_a_finished_campaign_keeps_its_throughput(reference_store):
    """The rate of a finished campaign is over its own span, not up to now:
    with the status's clock a day later it is the same."""
    import json
    import time
    first = json.loads(cortex("campaign", "status", str(reference_store), "--json").stdout)
    second = summary(reference_store, now=lambda: time.time() + 86400.0)
    assert first["tasks_per_s"] > 0 and first["eta_s"] == 0
    assert second["tasks_per_s"] == first["tasks_per_s"]


def test_rerun_resumes_without_redoing(reference_store, tmp_path):
    before = read_results(reference_store)
    out = cortex("campaign", "run", str(reference_store.parent / "tiny.toml"), "--store",
                 str(reference_store), "--quiet")
    assert out.returncode == 0
    after = read_results(reference_store)
    assert (after["attempts"] == 1).all()
    pd.testing.assert_frame_equal(before[RESULT_COLUMNS], after[RESULT_COLUMNS])


def test_two_ranks_give_the_same_results(reference_store, tmp_path):
    (tmp_path / "tiny.toml").write_text(TINY)
    out = cortex("campaign", "run", str(tmp_path / "tiny.toml"), "--store", str(tmp_path / "s.h5"),
                 "--quiet", mpi=2)
    assert out.returncode == 0, out.stderr
    two = read_results(tmp_path / "s.h5")
    assert set(two["rank"]) <= {0, 1}
    pd.testing.assert_frame_equal(read_results(reference_store)[RESULT_COLUMNS], two[RESULT_COLUMNS])


@pytest.mark.parametrize("row", [0, 2])
def test_killed_mid_write_then_rerun_completes(reference_store, tmp_path, row):
    (tmp_path / "tiny.toml").write_text(TINY)
    store = tmp_path / "s.h5"
    args = ("campaign", "run", str(tmp_path / "tiny.toml"), "--store", str(store), "--quiet")
    killed = cortex(*args, env={"CORTEX_TEST_KILL_MID_WRITE": str(row)})
    assert killed.returncode == -9
    rerun = cortex(*args)
    assert rerun.returncode == 0, rerun.stderr
    frame = read_results(store)
    assert list(frame["state"]) == ["done"] * 4
    assert (frame["attempts"] == 1).all()          # the journalled task is not redone
    pd.testing.assert_frame_equal(read_results(reference_store)[RESULT_COLUMNS], frame[RESULT_COLUMNS])


BAD = {
    "not toml": "[grid\nh0_um = 12",
    "unknown section": TINY + "\n[extra]\nx = 1\n",
    "unknown key": TINY.replace("bending = \"none\"", "bending = \"none\"\nfoo = 1"),
    "wrong type": TINY.replace("bulk_mN_per_m = 0.0", "bulk_mN_per_m = \"soft\""),
    "negative modulus": TINY.replace("shear_mN_per_m = 0.0", "shear_mN_per_m = -1.0"),
    "dh >= h0": TINY.replace("[solver]", "[solver]").replace("h0_um = [12.0, 11.0]", "h0_um = [12.0, 11.0]\ndh_um = 12.0"),
    "h0 above the sphere": TINY.replace("h0_um = [12.0, 11.0]", "h0_um = [25.0]"),
    "empty grid": TINY.replace("tension_mN_per_m = [1.0, 2.0]", "tension_mN_per_m = []"),
    "bad bending": TINY.replace("bending = \"none\"", "bending = \"floppy\""),
    "bad method": TINY.replace("timeout_s = 120.0", "timeout_s = 120.0\nmethod = \"magic\""),
    "negative timeout": TINY.replace("timeout_s = 120.0", "timeout_s = -1.0"),
    "no grid": "[campaign]\nname = \"x\"\n",
    "missing tension": TINY.replace("tension_mN_per_m = [1.0, 2.0]\n", ""),
    "other campaign": TINY.replace("tension_mN_per_m = [1.0, 2.0]", "tension_mN_per_m = [1.0, 3.0]"),
}


@pytest.mark.parametrize("kind", sorted(BAD))
def test_bad_campaign_file_one_line_exit_2_store_untouched(reference_store, tmp_path, kind):
    (tmp_path / "bad.toml").write_text(BAD[kind])
    before = (reference_store.read_bytes(), reference_store.stat().st_mtime_ns)
    out = cortex("campaign", "run", str(tmp_path / "bad.toml"), "--store", str(reference_store))
    assert out.returncode == 2, (kind, out.stderr)
    assert len(out.stderr.strip().splitlines()) == 1, out.stderr
    assert (reference_store.read_bytes(), reference_store.stat().st_mtime_ns) == before



def test_a_folder_as_campaign_file_is_one_line_exit_2(reference_store, tmp_path):
    before = reference_store.read_bytes()
    out = cortex("campaign", "run", str(tmp_path), "--store", str(reference_store))
    assert out.returncode == 2 and "is a folder" in out.stderr, out.stderr
    assert len(out.stderr.strip().splitlines()) == 1, out.stderr
    assert reference_store.read_bytes() == before

def test_injected_faults_are_recorded_and_the_rest_completes(tmp_path):
    """A task that raises, one that hangs past its timeout and one that returns
    NaN are each failed with their message; the fourth is done; exit status 1.
    The fourth is [test] fake_law (a made-up law's force at once, on K_B > 0):
    a real solve could itself outlast the short timeout on a slow machine."""
    text = TINY.replace("timeout_s = 120.0", "timeout_s = 2.0") \
        .replace("bulk_mN_per_m = 0.0", "bulk_mN_per_m = 25.0") \
        .replace("shear_mN_per_m = 0.0", "shear_mN_per_m = 8.33") + \
        "[test]\nfake_law = true\nraise_task = [0]\nhang_task = [1]\nnan_task = [2]\n"
    (tmp_path / "f.toml").write_text(text)
    store = tmp_path / "f.h5"
    out = cortex("campaign", "run", str(tmp_path / "f.toml"), "--store", str(store), "--quiet")
    assert out.returncode == 1, out.stderr
    assert "3 tasks failed" in out.stderr
    frame = read_results(store)
    assert list(frame["state"]) == ["failed", "failed", "failed", "done"]
    assert "injected fault" in frame["error"][0]
    assert "timed out after 2 s" in frame["error"][1]
    assert "non-finite" in frame["error"][2]
    assert np.isnan(frame["force_nN"][:3]).all() and np.isfinite(frame["force_nN"][3])
    status = cortex("campaign", "status", str(store))
    assert "3 failed" in status.stdout and "injected fault" in status.stdout
    # a plain rerun leaves the failed three alone and still says so: exit status 1, nothing rerun
    out = cortex("campaign", "run", str(tmp_path / "f.toml"), "--store", str(store), "--quiet")
    assert out.returncode == 1 and "3 tasks failed" in out.stderr, out.stderr
    assert list(read_results(store)["attempts"]) == [1, 1, 1, 1]
    # --retry-failed runs the three again (still faulty): attempts become 2, the done one stays 1
    out = cortex("campaign", "run", str(tmp_path / "f.toml"), "--store", str(store), "--quiet",
                 "--retry-failed")
    assert out.returncode == 1
    assert list(read_results(store)["attempts"]) == [2, 2, 2, 1]


# every compression first sleeps 1.5 s (a [test] knob): the four take 6 s on the
# one worker that holds them, so the run is surely still going at each kill
SLOW = TINY + "[test]\ncompression_sleep_s = 1.5\n"
MOMENTS = {   # what the test waits to see before the kill
    "start-up": None,                                             # nothing: at once
    "store creation": lambda store: store.exists(),
    "while solving": lambda store: os.path.exists(f"{store}.journal") and journal_counts(store) == (0, 0),
    "between writes": lambda store: 0 < journal_counts(store)[0] < 4,
}


@pytest.mark.parametrize("moment", list(MOMENTS))
def test_sigkill_at_a_moment_then_rerun_completes(reference_store, tmp_path, moment):
    """SIGKILL from outside at several moments (start-up, store creation, while
    solving, between writes; with the two mid-write kills above: six moments),
    under two ranks, each moment seen in the store or its journal; the rerun
    finishes, every task recorded once, same results."""
    (tmp_path / "tiny.toml").write_text(SLOW)
    store = tmp_path / "s.h5"
    args = ("campaign", "run", str(tmp_path / "tiny.toml"), "--store", str(store), "--quiet")
    proc = subprocess.Popen([str(BIN / "mpiexec"), "-n", "2", str(BIN / "cortex"), *args], cwd=ROOT,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        if MOMENTS[moment] is not None:
            poll_until(lambda: MOMENTS[moment](store), 120, moment, proc=proc)
    finally:
        os.killpg(proc.pid, 9)
        proc.wait()
    assert journal_counts(store)[0] < 4                     # killed before the end
    rerun = cortex(*args)
    assert rerun.returncode == 0, rerun.stderr
    frame = read_results(store)
    assert list(frame["state"]) == ["done"] * 4
    assert (frame["attempts"] == 1).all()
    pd.testing.assert_frame_equal(read_results(reference_store)[RESULT_COLUMNS], frame[RESULT_COLUMNS])


def test_three_ranks_give_the_same_results(reference_store, tmp_path):
    (tmp_path / "tiny.toml").write_text(TINY)
    out = cortex("campaign", "run", str(tmp_path / "tiny.toml"), "--store", str(tmp_path / "s.h5"),
                 "--quiet", mpi=3)
    assert out.returncode == 0, out.stderr
    three = read_results(tmp_path / "s.h5")
    pd.testing.assert_frame_equal(read_results(reference_store)[RESULT_COLUMNS], three[RESULT_COLUMNS])


@pytest.mark.parametrize("given, expected", [(None, "1"), ("3", "3")])
def test_a_run_gives_openblas_one_thread_unless_told_otherwise(tmp_path, given, expected):
    """Set before numpy is imported (the command's first imports do not load it), the user's value kept."""
    (tmp_path / "one.toml").write_text('[grid]\nh0_um = 12.0\nbulk_mN_per_m = 25.0\nshear_mN_per_m = 8.0\n'
                                       'tension_mN_per_m = 1.0\n[test]\nnoop = true\n')
    code = ("import os, sys; from cortex.cli import main; loaded = 'numpy' in sys.modules; "
            "status = main(sys.argv[1:]); print(status, loaded, os.environ['OPENBLAS_NUM_THREADS'])")
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    out = subprocess.run([str(BIN / "python"), "-c", code, "campaign", "run", str(tmp_path / "one.toml"),
                          "--store", str(tmp_path / "s.h5"), "--quiet"], capture_output=True, text=True,
                         env=env | ({"OPENBLAS_NUM_THREADS": given} if given else {}), cwd=ROOT, timeout=300)
    assert out.stdout.split()[-3:] == ["0", "False", expected], out.stderr
