"""The SLURM batch jobs (jobs/*.sbatch, jobs/submit.sh, jobs/resume.sh) on a
real single-node SLURM.

A session fixture starts munge, slurmctld and slurmd on this machine with
scripts/setup-slurm.sh (installing the Debian packages first; skipped, saying
why, where that cannot be done) and stops them at the end if it started them.
The tests submit the real scripts running the real `cortex campaign run` /
`cortex analysis calibrate`, wait for the jobs (bounded) and check what they
left:

- tests/data/slurm-tiny.toml and its chained analysis: every task of the store
  done exactly once, the analysis started only after the campaign ended
  (afterok) and wrote calibration.json;
- tests/data/slurm-timelimit.toml (Monte-Carlo trial tasks that each sleep
  0.5 s, a [test] knob: at least 70 s on one rank on a machine of any
  speed) in a one-rank job with a one-minute time limit: SLURM's warning
  signal (`--signal=B:USR1@1`, sent 30 to 60 s into each run) reaches the job
  script, which passes SIGTERM on to the ranks; the engine stops cleanly and
  the job requeues itself, as often as it takes, with no one acting: the job
  ends complete, every task done exactly once, the store the same as an
  uninterrupted run's, and the chained analysis runs after it;
- tests/data/slurm-lostnode.toml (trial tasks that sleep 0.5 s) on two ranks:
  once the store shows finished trial tasks, the test kills the campaign's
  step (`scancel --signal=KILL JOB.STEP`, the stand-in for a lost node): the
  job requeues itself and resumes to the uninterrupted run's store, and its
  analysis runs; with CORTEX_MAX_REQUEUES=0 the same job stops instead,
  printing the resume line, its analysis is cancelled, and jobs/resume.sh
  finishes the store;
- tests/data/slurm-failing.toml (one compression raises): the job exits 1
  (not requeued) and its analysis is cancelled; `campaign.sbatch CONFIG STORE
  --retry-failed` retries only that task, and `analysis.sbatch STORE DIR
  --partial` (afterany) analyses the rest;
- jobs/afm-analyze.sbatch on two tasks: the AFM reading's files, the same as one process writes.
"""

import contextlib
import fcntl
import importlib.util
import json
import os
import shutil
import signal
import subprocess
from pathlib import Path

import numpy as np
import pytest
from conftest import BIN, ROOT, poll_until

DATA = Path(__file__).parent / "data"
SETUP = ROOT / "scripts" / "setup-slurm.sh"
SUBMIT = ROOT / "jobs" / "submit.sh"
CONFIGS = (DATA / "slurm-tiny.toml", DATA / "slurm-timelimit.toml", DATA / "slurm-failing.toml",
           DATA / "slurm-lostnode.toml")
pytestmark = [
    pytest.mark.serial,     # alone, after the other tests (docs/testing.md): SLURM's node owns both cores
    pytest.mark.skipif(importlib.util.find_spec("campaign") is None,
                       reason="the campaign engine (package `campaign`) is not in this tree"),
    pytest.mark.skipif(not all(c.exists() for c in CONFIGS),
                       reason="tests/data/slurm-{tiny,timelimit,failing,lostnode}.toml not written yet"),
]
FINAL = {"COMPLETED", "FAILED", "CANCELLED", "TIMEOUT", "NODE_FAIL", "OUT_OF_MEMORY", "PREEMPTED", "BOOT_FAIL", "DEADLINE"}


@pytest.fixture(scope="session")
def slurm():
    """A running single-node SLURM; yields the environment for its client commands.

    Other test sessions (other clones, other users' `make test`) may use the same
    cluster at the same time: each holds a shared lock on sessions.lock in its
    state directory while it runs, and the session that started the cluster
    stops it at the end only if it can then take that lock exclusively."""
    if shutil.which("bash") is None:
        pytest.skip("no bash")
    env = dict(os.environ, SLURM_CONF="/var/lib/cortex-slurm/slurm.conf")
    env.update(line.removeprefix("export ").split("=", 1) for line in _setup("env").stdout.splitlines())
    sessions = _sessions_lock(Path(env["SLURM_CONF"]).parent)
    was_up = _setup("status").returncode == 0
    run = _setup("start")
    if run.returncode == 77:
        pytest.skip(f"no SLURM here: {run.stdout.strip()}")
    assert run.returncode == 0, f"setup-slurm.sh start failed:\n{run.stdout}\n{run.stderr}"
    yield env
    if sessions is not None and not was_up:
        try:
            fcntl.flock(sessions, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            return  # another session is using the cluster: leave it running
        _setup("stop")


def _sessions_lock(state_dir):
    """The shared lock saying "a test session uses this cluster" (None if it cannot be made)."""
    try:
        state_dir.mkdir(parents=True, exist_ok=True)
        lock = open(state_dir / "sessions.lock", "w")
    except OSError:
        return None  # not root: setup-slurm.sh will say why and the tests skip
    fcntl.flock(lock, fcntl.LOCK_SH)
    return lock


def _setup(action):
    return subprocess.run(["bash", str(SETUP), action], capture_output=True, text=True, timeout=900)


def submit(env, cwd, *args, script=SUBMIT):
    """jobs/submit.sh ARGS (or `script`: jobs/resume.sh) in cwd; returns {"campaign": id, "analysis": id}."""
    run = subprocess.run([str(script), *map(str, args)], cwd=cwd, env=env, capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, f"submit.sh failed: {run.stderr}"
    ids = dict(line.split() for line in run.stdout.splitlines())
    assert set(ids) == {"campaign", "analysis"} and all(v.isdigit() for v in ids.values()), run.stdout
    return ids


def sbatch(env, cwd, *args):
    """`sbatch --parsable ARGS` in cwd; returns the job id."""
    run = subprocess.run(["sbatch", "--parsable", *map(str, args)], cwd=cwd, env=env, capture_output=True,
                         text=True, timeout=60)
    assert run.returncode == 0, f"sbatch failed: {run.stderr}"
    return run.stdout.strip().split(";")[0]


def job(env, jobid):
    """scontrol's record of a job as a dict (JobState, ExitCode, StartTime, EndTime, ...)."""
    out = subprocess.run(["scontrol", "show", "job", "-o", jobid], env=env, capture_output=True, text=True, check=True).stdout
    return dict(field.split("=", 1) for field in out.split() if "=" in field)


def wait(env, jobids, timeout_s):
    """Poll until every job is in a final state; returns their records (the
    jobs are cancelled if `timeout_s` pass first)."""
    jobids = list(jobids)

    def finished():
        records = {j: job(env, j) for j in jobids}
        return records if all(r["JobState"] in FINAL for r in records.values()) else None
    try:
        return poll_until(finished, timeout_s, f"jobs {', '.join(jobids)} in a final state", every_s=0.5)
    except BaseException:
        subprocess.run(["scancel", *jobids], env=env)
        raise


def logs(cwd):
    return "\n".join(f"--- {p.name}\n{p.read_text()}" for p in sorted(Path(cwd).glob("cortex-*.out")))


def states(store):
    from campaign.store.reader import read_results

    return read_results(store)


def trial_attempts(store):
    """Attempts of every Monte-Carlo trial cell (journal included)."""
    from campaign.store.reader import read_trials

    return read_trials(store).groupby("trial_id")["attempts"].first().to_numpy()


def trials(store):
    return summary(store)["trials"]


def test_campaign_then_analysis(slurm, tmp_path):
    ids = submit(slurm, tmp_path, CONFIGS[0], "tiny.h5", "analysis")
    rec = wait(slurm, ids.values(), 300)
    camp, ana = rec[ids["campaign"]], rec[ids["analysis"]]
    assert (camp["JobState"], camp["ExitCode"]) == ("COMPLETED", "0:0"), logs(tmp_path)
    assert (ana["JobState"], ana["ExitCode"]) == ("COMPLETED", "0:0"), logs(tmp_path)
    assert f"afterok:{ids['campaign']}" in ana["Dependency"] or ana["Dependency"] == "(null)"
    assert ana["StartTime"] >= camp["EndTime"], (camp["EndTime"], ana["StartTime"])  # ISO times sort as text

    results = states(tmp_path / "tiny.h5")
    assert len(results) == 60 and (results["state"] == "done").all(), results
    assert (results["attempts"] == 1).all() and (trial_attempts(tmp_path / "tiny.h5") == 1).all()
    assert trials(tmp_path / "tiny.h5")["done"] == 2 * 2 * 3 * 12  # nu x modes x studies x cells
    assert np.isfinite(results["modulus_mN_per_m"]).all()
    calibration = json.loads((tmp_path / "analysis" / "calibration.json").read_text())
    assert calibration, "empty calibration.json"


def test_failed_tasks_then_retry_and_partial_analysis(slurm, tmp_path):
    ids = submit(slurm, tmp_path, CONFIGS[2], "f.h5", "analysis")
    rec = wait(slurm, ids.values(), 300)
    camp, ana = rec[ids["campaign"]], rec[ids["analysis"]]
    assert (camp["JobState"], camp["ExitCode"]) == ("FAILED", "1:0"), logs(tmp_path)
    assert ana["JobState"] == "CANCELLED", logs(tmp_path)  # afterok: not on a store with failed tasks
    results = states(tmp_path / "f.h5")
    assert list(results.index[results["state"] == "failed"]) == [3], results
    assert "injected fault" in results.at[3, "error"]

    retry = sbatch(slurm, tmp_path, ROOT / "jobs" / "campaign.sbatch", CONFIGS[2], "f.h5", "--retry-failed")
    partial = sbatch(slurm, tmp_path, f"--dependency=afterany:{retry}", ROOT / "jobs" / "analysis.sbatch",
                     "f.h5", "partial", "--partial")
    rec = wait(slurm, [retry, partial], 300)
    assert (rec[retry]["JobState"], rec[retry]["ExitCode"]) == ("FAILED", "1:0"), logs(tmp_path)
    results = states(tmp_path / "f.h5")
    assert results.at[3, "attempts"] == 2 and (results.drop(index=3)["attempts"] == 1).all()  # only it retried
    assert (rec[partial]["JobState"], rec[partial]["ExitCode"]) == ("COMPLETED", "0:0"), logs(tmp_path)
    assert rec[partial]["StartTime"] >= rec[retry]["EndTime"]
    assert json.loads((tmp_path / "partial" / "calibration.json").read_text())


def steps(env, jobid):
    """The job's running steps other than its batch script (`JOB.0`: mpiexec's
    ranks, which the venv's hydra starts with srun)."""
    out = subprocess.run(["squeue", "-h", "-s", "-j", jobid, "-o", "%i"], env=env, capture_output=True, text=True,
                         check=True).stdout.split()
    return [s for s in out if s.split(".")[-1].isdigit()]


def done_trials(store):
    try:
        return summary(store)["trials"]["done"]
    except Exception:  # the store is still being created
        return 0


def summary(store):
    from campaign.store.reader import summary as read_summary

    return read_summary(store)


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """`reference(config)`: the store of `config` run without interruption on
    one process, here (its [test] trial_sleep_s left out: it changes no number)."""
    made = {}

    def get(config):
        if config not in made:
            folder = tmp_path_factory.mktemp("reference")
            plain = folder / config.name
            plain.write_text("".join(line for line in config.read_text().splitlines(keepends=True)
                                     if not line.startswith("trial_sleep_s")))
            run = subprocess.run([str(BIN / "cortex"), "campaign", "run", str(plain), "--store",
                                  str(folder / "ref.h5"), "--quiet"], capture_output=True, text=True, timeout=300)
            assert run.returncode == 0, run.stderr
            made[config] = folder / "ref.h5"
        return made[config]
    return get


BOOKKEEPING = ["attempts", "rank", "wall_s", "viscous_wall_s"]    # how and when, not what


def assert_same_store(store, ref):
    """Every task's state and numbers in `store` as in `ref`, bitwise (NaN where
    both have it); attempts, ranks and timings may differ."""
    import pandas as pd
    from campaign.store.reader import read_results, read_trials

    got, want = read_results(store), read_results(ref)
    drop = [c for c in BOOKKEEPING if c in want]
    pd.testing.assert_frame_equal(got.drop(columns=drop), want.drop(columns=drop), check_exact=True)
    got, want = read_trials(store), read_trials(ref)
    pd.testing.assert_frame_equal(got.drop(columns=["attempts"]), want.drop(columns=["attempts"]), check_exact=True)


def restarts(env, jobid):
    return int(job(env, jobid)["Restarts"])


@pytest.mark.slow  # about 2 minutes: 70 s of sleeping tasks in runs of at most a minute, requeued between
def test_time_limit_requeues_until_complete(slurm, tmp_path, reference):
    config, store = CONFIGS[1], tmp_path / "cut.h5"
    ids = submit(slurm, tmp_path, config, "cut.h5", "analysis", "--", "--ntasks=1", "--time=1",
                 "--signal=B:USR1@1")
    poll_until(lambda: restarts(slurm, ids["campaign"]) >= 1, 300, "the campaign job requeued")
    partial = summary(store)["trials"]       # the first run's (the next waits at least 10 s to start)
    assert 0 < partial["done"] < partial["trials"] and partial["running"] == 0, f"{partial}\n{logs(tmp_path)}"

    rec = wait(slurm, ids.values(), 600)
    camp, ana = rec[ids["campaign"]], rec[ids["analysis"]]
    out = logs(tmp_path)
    assert (camp["JobState"], camp["ExitCode"]) == ("COMPLETED", "0:0"), out
    assert out.count("SIGUSR1 (time limit near)") >= int(camp["Restarts"]) >= 1, out
    assert "stopped before the time limit (mpiexec status 3); requeueing job" in out, out
    assert (ana["JobState"], ana["ExitCode"]) == ("COMPLETED", "0:0"), out
    assert ana["StartTime"] >= camp["EndTime"], (camp["EndTime"], ana["StartTime"])
    assert json.loads((tmp_path / "analysis" / "calibration.json").read_text())
    results = states(store)
    assert (results["state"] == "done").all() and (results["attempts"] == 1).all()
    assert (trial_attempts(store) == 1).all()  # every task done exactly once over all the runs
    assert_same_store(store, reference(config))


def kill_step_when_started(env, jobid, store, done_before=0):
    """Once the store shows more finished trials than `done_before`, SIGKILL to
    the job's campaign step (as if its node were lost); returns that count."""
    def started():
        n = done_trials(store)
        return n > done_before and steps(env, jobid) and n
    done = poll_until(started, 300, "finished trial tasks in the store while the campaign step runs", every_s=0.2)
    for step in steps(env, jobid):
        # the step's processes killed here, not by `scancel --signal=KILL`: under load scancel can
        # resend its request after the step died, and the step of the requeued job has the same id
        listed = subprocess.run(["scontrol", "listpids", step], env=env, capture_output=True, text=True,
                                check=True).stdout.split("\n")[1:]
        for pid in (int(line.split()[0]) for line in listed if line.split()):
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)
    return done


def test_lost_step_requeues_and_resumes(slurm, tmp_path, reference):
    config, store = CONFIGS[3], tmp_path / "lost.h5"
    ids = submit(slurm, tmp_path, config, "lost.h5", "analysis")
    kill_step_when_started(slurm, ids["campaign"], store)
    poll_until(lambda: restarts(slurm, ids["campaign"]) >= 1, 120, "the campaign job requeued")
    partial = summary(store)["trials"]
    assert 0 < partial["done"] < partial["trials"], f"{partial}\n{logs(tmp_path)}"

    rec = wait(slurm, ids.values(), 600)
    camp, ana = rec[ids["campaign"]], rec[ids["analysis"]]
    out = logs(tmp_path)
    assert (camp["JobState"], camp["ExitCode"], camp["Restarts"]) == ("COMPLETED", "0:0", "1"), out
    assert "the campaign's step ended abnormally" in out and "requeueing job" in out, out
    assert (ana["JobState"], ana["ExitCode"]) == ("COMPLETED", "0:0"), out
    assert ana["StartTime"] >= camp["EndTime"], (camp["EndTime"], ana["StartTime"])
    results = states(store)
    assert (results["state"] == "done").all() and (results["attempts"] == 1).all()  # done before the kill
    assert (trial_attempts(store) <= 2).all()  # those in flight at the kill were redone, once
    assert_same_store(store, reference(config))


def test_no_requeue_left_then_resume(slurm, tmp_path, reference):
    config, store = CONFIGS[3], tmp_path / "last.h5"
    ids = submit(dict(slurm, CORTEX_MAX_REQUEUES="0"), tmp_path, config, "last.h5", "analysis")
    kill_step_when_started(slurm, ids["campaign"], store)
    rec = wait(slurm, ids.values(), 300)
    camp, ana = rec[ids["campaign"]], rec[ids["analysis"]]
    out = logs(tmp_path)
    assert camp["JobState"] == "FAILED" and camp["Restarts"] == "0", out
    assert "no requeue left (CORTEX_MAX_REQUEUES=0)" in out and f"jobs/resume.sh {config} last.h5" in out, out
    assert ana["JobState"] == "CANCELLED", out  # afterok never satisfied
    partial = summary(store)["trials"]
    assert 0 < partial["done"] < partial["trials"], partial

    again = submit(slurm, tmp_path, config, "last.h5", "analysis", script=ROOT / "jobs" / "resume.sh")
    rec = wait(slurm, again.values(), 600)
    assert all((r["JobState"], r["ExitCode"]) == ("COMPLETED", "0:0") for r in rec.values()), logs(tmp_path)
    assert json.loads((tmp_path / "analysis" / "calibration.json").read_text())
    assert_same_store(store, reference(config))


def test_the_afm_reading_job_writes_what_one_process_writes(slurm, tmp_path):
    """jobs/afm-analyze.sbatch submitted with two tasks (`mpiexec -n 2 cortex afm analyze DATA --out
    DIR` on the job's tasks, the repository found from the submitted script) writes the cells.csv
    and rheology.csv the reading in one process writes, of a two-cell synthetic experiment."""
    from cortex.cli import main

    assert main(["afm", "synth", "--cells", "2", "--seed", "3", "--out", str(tmp_path / "exp")]) == 0
    jobid = sbatch(slurm, tmp_path, "--ntasks=2", ROOT / "jobs" / "afm-analyze.sbatch", "exp", "ranks")
    rec = wait(slurm, [jobid], 300)[jobid]
    assert (rec["JobState"], rec["ExitCode"]) == ("COMPLETED", "0:0"), logs(tmp_path)
    assert f"mpiexec -n 2 {ROOT / '.venv' / 'bin' / 'cortex'} afm analyze exp --out ranks" in logs(tmp_path)
    assert main(["afm", "analyze", str(tmp_path / "exp"), "--out", str(tmp_path / "one")]) in (0, 1)
    for name in ("cells.csv", "rheology.csv"):
        assert (tmp_path / "ranks" / name).read_bytes() == (tmp_path / "one" / name).read_bytes(), name
