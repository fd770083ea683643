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
  0.5 s, a [test] knob: at least 100 s on one rank on a machine of any
  speed) in a one-rank job with a one-minute time limit: SLURM's warning
  signal (`--signal=B:TERM@1`, sent 30 to 60 s into the job) reaches the job script,
  which passes SIGTERM on to the ranks; the engine stops cleanly, the job
  exits 3 (the engine's "stopped, rerun to resume"), its chained analysis is
  cancelled, the store keeps the finished tasks; jobs/resume.sh submits it
  again, the store ends complete with every task done exactly once and the
  new analysis runs;
- tests/data/slurm-failing.toml (one compression raises): the job exits 1
  and its analysis is cancelled; `campaign.sbatch CONFIG STORE
  --retry-failed` retries only that task, and `analysis.sbatch STORE DIR
  --partial` (afterany) analyses the rest.
"""

import fcntl
import importlib.util
import json
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from conftest import ROOT, poll_until

DATA = Path(__file__).parent / "data"
SETUP = ROOT / "scripts" / "setup-slurm.sh"
SUBMIT = ROOT / "jobs" / "submit.sh"
CONFIGS = (DATA / "slurm-tiny.toml", DATA / "slurm-timelimit.toml", DATA / "slurm-failing.toml")
pytestmark = [
    pytest.mark.serial,     # alone, after the other tests (docs/testing.md): SLURM's node owns both cores
    pytest.mark.skipif(importlib.util.find_spec("campaign") is None,
                       reason="the campaign engine (package `campaign`) is not in this tree"),
    pytest.mark.skipif(not all(c.exists() for c in CONFIGS),
                       reason="tests/data/slurm-{tiny,timelimit,failing}.toml not written yet"),
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


def submit(env, cwd, *args):
    """jobs/submit.sh ARGS in cwd; returns {"campaign": id, "analysis": id}."""
    run = subprocess.run([str(SUBMIT), *map(str, args)], cwd=cwd, env=env, capture_output=True, text=True, timeout=60)
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
    from campaign.store.reader import summary

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


@pytest.mark.slow  # about 2 minutes: a one-minute time limit, then the rest (sleeping tasks)
def test_time_limit_then_resume(slurm, tmp_path):
    config, store = CONFIGS[1], tmp_path / "cut.h5"
    first = submit(slurm, tmp_path, config, "cut.h5", "analysis", "--", "--ntasks=1", "--time=1",
                   "--signal=B:TERM@1")
    rec = wait(slurm, first.values(), 600)
    camp, ana = rec[first["campaign"]], rec[first["analysis"]]
    out = logs(tmp_path)
    assert (camp["JobState"], camp["ExitCode"]) == ("FAILED", "3:0"), out  # stopped cleanly, before the limit
    assert "asking the campaign to stop cleanly" in out and "rerun the same command to resume" in out, out
    assert f"jobs/resume.sh {config} cut.h5" in out, out
    assert ana["JobState"] == "CANCELLED", out  # afterok never satisfied
    assert not (tmp_path / "analysis").exists()
    assert (states(store)["state"] == "done").all()  # the compressions come first, and take no time
    partial = trials(store)
    assert 0 < partial["done"] < partial["trials"], f"{partial}\n{out}"
    assert partial["running"] == 0 and (trial_attempts(store) <= 1).all()

    resume = subprocess.run([str(ROOT / "jobs" / "resume.sh"), str(config), "cut.h5", "analysis"], cwd=tmp_path,
                            env=slurm, capture_output=True, text=True, timeout=60)
    assert resume.returncode == 0, resume.stderr
    assert f"{partial['trials']} trials: {partial['done']} done" in resume.stderr, resume.stderr
    second = dict(line.split() for line in resume.stdout.splitlines())
    rec = wait(slurm, second.values(), 600)
    assert all((r["JobState"], r["ExitCode"]) == ("COMPLETED", "0:0") for r in rec.values()), logs(tmp_path)
    results = states(store)
    assert (results["state"] == "done").all() and (results["attempts"] == 1).all()
    final = trials(store)
    assert final["done"] == final["trials"] == partial["trials"]
    assert (trial_attempts(store) == 1).all()  # every task done exactly once over the two jobs
    assert json.loads((tmp_path / "analysis" / "calibration.json").read_text())
    for f in tmp_path.glob("cut.h5*"):  # store and journal: do not keep them around
        f.unlink()
