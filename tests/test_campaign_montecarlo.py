"""The Monte-Carlo stage of the campaign engine: [montecarlo] validation,
trials after their compressions, determinism over ranks and resumes, the
drawn errors' SDs, zero errors reproduce the compressions, and the analysis
reads the trials."""

import json
import os
import subprocess

import h5py
import numpy as np
import pandas as pd
import pytest

from campaign import config
from campaign.store.reader import read_results, read_trials
from campaign.store.schema import TRIAL_COLUMNS
from campaign.trials import Study, draws, grid_shear, run_study
from conftest import BIN, ROOT, cortex, journal_counts, poll_until

# fake_law: every compression returns at once the force of a smooth made-up law
FAKE = """
[campaign]
name = "mc"
[grid]
h0_um = [15.0, 14.0, 13.0, 12.0, 11.0]
bulk_mN_per_m = 25.0
shear_mN_per_m = [8.33, 15.0, 25.0]
tension_mN_per_m = [0.5, 1.5, 2.5, 3.0]
[montecarlo]
nu = [0.5, 0.25]
cells = 12
studies = 3
volume_error_rel_sd = 0.075
height_error_sd_um = 0.5
height_error_mode = ["per_cell", "per_height"]
seed = 7
[test]
fake_law = true
"""
TRIAL_VALUES = ["volume_used_um3", "h0_used_um", "h1_used_um", "h_tilde", "modulus_mN_per_m",
                "gamma_eff_mN_per_m", "tension_seen_mN_per_m", "tension_mN_per_m"]


def run(tmp, text, name="s.h5", mpi=0, env=None, extra=()):
    (tmp / "c.toml").write_text(text)
    return cortex("campaign", "run", str(tmp / "c.toml"), "--store", str(tmp / name), "--quiet", *extra,
                  env=env, mpi=mpi)


@pytest.fixture(scope="module")
def fake_store(tmp_path_factory):
    d = tmp_path_factory.mktemp("mc")
    out = run(d, FAKE)
    assert out.returncode == 0, out.stderr
    return d / "s.h5"


def test_trials_table_has_every_trial_and_height(fake_store):
    trials = read_trials(fake_store)
    assert list(trials.columns[:len(TRIAL_COLUMNS)]) == list(TRIAL_COLUMNS)
    n = 2 * 2 * 3 * 12                                   # nu x modes x studies x cells
    assert trials["trial_id"].nunique() == n and len(trials) == n * 5
    assert (trials["state"] == "done").all()
    assert np.isfinite(trials[TRIAL_VALUES]).all().all()
    assert sorted(trials["nu_true"].unique()) == pytest.approx([0.25, (25 - 8.33) / (25 + 8.33)])
    assert set(trials["tension_mN_per_m"]) <= {0.5, 1.5, 2.5, 3.0}
    assert set(trials["height_error_mode"]) == {"per_cell", "per_height"}
    # per_cell: one offset for all heights of a cell; per_height: independent offsets
    offset = (trials["h0_used_um"] - trials["h0_true_um"]).groupby(
        [trials["height_error_mode"], trials["trial_id"]]).std()
    assert offset["per_cell"].max() < 1e-12 and offset["per_height"].min() > 1e-6
    assert np.allclose(trials["h0_used_um"] - trials["h1_used_um"], 0.5)
    status = cortex("campaign", "status", str(fake_store), "--json")
    info = json.loads(status.stdout)
    assert info["done"] == 60 and info["trials"]["trials"] == n and info["trials"]["done"] == n


def test_two_and_three_ranks_and_a_resumed_run_give_the_same_trials(fake_store, tmp_path):
    ref = read_trials(fake_store)
    for ranks in (2, 3):
        out = run(tmp_path, FAKE, f"r{ranks}.h5", mpi=ranks)
        assert out.returncode == 0, out.stderr
        pd.testing.assert_frame_equal(ref, read_trials(tmp_path / f"r{ranks}.h5"))
    # killed right after a trial task's rows were written (before the journal mark), then resumed
    killed = run(tmp_path, FAKE, "k.h5", env={"CORTEX_TEST_KILL_MID_WRITE": "task5"})
    assert killed.returncode == -9
    partial = read_trials(tmp_path / "k.h5")
    assert 0 < (partial["state"] == "done").sum() < len(partial)
    rerun = run(tmp_path, FAKE, "k.h5", mpi=2)
    assert rerun.returncode == 0, rerun.stderr
    pd.testing.assert_frame_equal(ref, read_trials(tmp_path / "k.h5"))
    with h5py.File(tmp_path / "k.h5", "r") as f:
        assert (f["trials/attempts"][:] == 1).all()        # no trial done twice


def test_sigkill_under_two_ranks_then_rerun_gives_the_same_trials(fake_store, tmp_path):
    """SIGKILL once the journal holds a finished trial task; each of the 12
    first sleeps 1 s (a [test] knob), so some are surely still to come."""
    (tmp_path / "c.toml").write_text(FAKE + "trial_sleep_s = 1.0\n")
    store = tmp_path / "s.h5"
    proc = subprocess.Popen([str(BIN / "mpiexec"), "-n", "2", str(BIN / "cortex"), "campaign", "run",
                             str(tmp_path / "c.toml"), "--store", str(store), "--quiet"], cwd=ROOT,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        poll_until(lambda: journal_counts(store)[1] > 0, 120, "a trial task in the journal", proc=proc)
    finally:
        os.killpg(proc.pid, 9)
        proc.wait()
    assert 0 < journal_counts(store)[1] < 12
    rerun = run(tmp_path, FAKE)
    assert rerun.returncode == 0, rerun.stderr
    pd.testing.assert_frame_equal(read_trials(fake_store), read_trials(store))


def test_trials_are_added_to_a_store_made_without_them(fake_store, tmp_path):
    """The grid first, the [montecarlo] section later: the compressions are kept
    (attempts 1), the trials equal those of a store made in one go; other
    trials on that store are refused."""
    grid_only = FAKE.split("[montecarlo]")[0] + "[test]\nfake_law = true\n"
    assert run(tmp_path, grid_only).returncode == 0
    assert len(read_trials(tmp_path / "s.h5")) == 0
    out = run(tmp_path, FAKE)
    assert out.returncode == 0, out.stderr
    assert (read_results(tmp_path / "s.h5")["attempts"] == 1).all()
    pd.testing.assert_frame_equal(read_trials(fake_store), read_trials(tmp_path / "s.h5"))
    other = run(tmp_path, FAKE.replace("seed = 7", "seed = 9"))
    assert other.returncode == 2 and "different [montecarlo]" in other.stderr
    assert run(tmp_path, grid_only).returncode == 2     # trials the file does not define


REAL = """
[campaign]
name = "mc-real"
[grid]
h0_um = [12.0, 11.0]
bulk_mN_per_m = 25.0
shear_mN_per_m = 8.33
tension_mN_per_m = [1.0, 2.0]
[solver]
timeout_s = 120.0
[montecarlo]
nu = 0.5
cells = 4
studies = 2
volume_error_rel_sd = 0.0
height_error_sd_um = 0.0
"""


def test_trials_after_their_compressions_and_without_errors_reproduce_them(tmp_path):
    """Real solves under two ranks: every trial starts after the compressions it
    uses have finished; with zero errors its K, h~ and tension are the
    compressions' own, bit for bit."""
    out = run(tmp_path, REAL, mpi=2)
    assert out.returncode == 0, out.stderr
    comps = read_results(tmp_path / "s.h5")
    assert (comps["state"] == "done").all()
    with h5py.File(tmp_path / "s.h5", "r") as f:
        started = f["trials/started_unix_s"][:]
        comp_started = f["started_unix_s"][:]
    assert started.min() >= (comp_started + comps["wall_s"].to_numpy()).max() - 1e-3
    trials = read_trials(tmp_path / "s.h5")
    assert len(trials) == 2 * 2 * 4 * 2 and (trials["state"] == "done").all()
    merged = trials.merge(comps, left_on=["tension_mN_per_m", "h0_true_um"],
                          right_on=["tension_mN_per_m", "h0_um"], suffixes=("", "_sim"))
    assert len(merged) == len(trials)
    for col in ("modulus_mN_per_m", "h_tilde", "gamma_eff_mN_per_m"):
        assert (merged[col] == merged[f"{col}_sim"]).all(), col
    assert (merged["tension_seen_mN_per_m"] == merged["tension_mN_per_m"]).all()
    assert (merged["volume_used_um3"] == 4300.0).all()


def test_a_trial_whose_compression_failed_is_failed_with_its_message(tmp_path):
    text = FAKE.replace("cells = 12", "cells = 30").replace("fake_law = true", "fake_law = true\nraise_task = [1]")
    out = run(tmp_path, text)
    assert out.returncode == 1 and "tasks failed" in out.stderr
    trials = read_trials(tmp_path / "s.h5").drop_duplicates("trial_id")
    # grid row 1 is h0 = 15, K_S = 8.33, gamma_a = 1.5: nu = 0.5 cells drawing 1.5 mN/m fail
    bad = (trials["nu_true"] > 0.4) & (trials["tension_mN_per_m"] == 1.5)
    assert bad.any() and (~bad).any()
    assert (trials.loc[bad, "state"] == "failed").all() and (trials.loc[~bad, "state"] == "done").all()
    assert trials.loc[bad, "error"].str.contains("h0 = 15 um, gamma_a = 1.5 mN/m) failed: "
                                                 "RuntimeError: injected fault", regex=False).all()
    assert trials.loc[bad, "modulus_mN_per_m"].isna().all()
    status = cortex("campaign", "status", str(tmp_path / "s.h5"))
    assert "failed trials: compression 1" in status.stdout


def _study(mode, n_cells=4000, sd_v=0.075, sd_h=0.5, seed=0):
    return Study(bending="standard", nu_true=0.5, height_error_mode=mode, study=0, n_cells=n_cells,
                 volume_um3=4300.0, dh_um=0.5, bulk_mN_per_m=25.0, shear_mN_per_m=8.33,
                 heights_um=(15.0, 14.0, 13.0, 12.0, 11.0, 10.0), tensions_mN_per_m=(0.5, 1.0, 2.0),
                 volume_error_rel_sd=sd_v, height_error_sd_um=sd_h, seed=seed,
                 rows=tuple(tuple(range(6 * i, 6 * i + 6)) for i in range(3)))


@pytest.mark.parametrize("mode", ["per_cell", "per_height"])
def test_drawn_errors_have_the_configured_sds(mode):
    """Over 4000 cells: the volume's relative error has SD 0.075 and the height
    error SD 0.5 um (within 4 standard errors), means near 0, per_height
    offsets uncorrelated across heights, per_cell identical; γ_a uniform."""
    study = _study(mode)
    n = study.n_cells
    forces = np.linspace(40.0, 80.0, 18).reshape(3, 6)
    out = run_study(study, forces, [""] * 3)
    rel = out["volume_used_um3"] / 4300.0 - 1.0
    dh = out["h0_used_um"] - np.array(study.heights_um)
    se = 4.0 / np.sqrt(2 * n)                  # relative standard error of an SD, 4x
    assert abs(rel.std(ddof=1) / 0.075 - 1.0) < se
    assert abs(rel.mean()) < 4 * 0.075 / np.sqrt(n)
    assert abs(dh[:, 0].std(ddof=1) / 0.5 - 1.0) < se
    assert abs(dh.mean()) < 4 * 0.5 / np.sqrt(n)
    corr = np.corrcoef(dh[:, 0], dh[:, 3])[0, 1]
    if mode == "per_cell":
        assert np.allclose(dh, dh[:, :1], rtol=0, atol=1e-12)
    else:
        assert abs(corr) < 4.0 / np.sqrt(n)
        assert all(abs(dh[:, j].std(ddof=1) / 0.5 - 1.0) < se for j in range(6))
    assert abs(np.corrcoef(rel, dh[:, 0])[0, 1]) < 4.0 / np.sqrt(n)
    counts = np.bincount(np.searchsorted([0.5, 1.0, 2.0], out["tension_mN_per_m"]), minlength=3)
    assert np.all(np.abs(counts - n / 3) < 4 * np.sqrt(n * (1 / 3) * (2 / 3)))
    assert np.isfinite(out["modulus_mN_per_m"]).all()


def test_draws_are_keyed_by_the_trial_and_not_by_the_batch():
    """A cell's draws come from its own id: the same on every call, different
    between cells and seeds; the ids are stable hashes of the parameters."""
    a, b = draws(_study("per_height", n_cells=50)), draws(_study("per_height", n_cells=50))
    for x, y in zip(a, b):
        assert np.array_equal(x, y)
    c = draws(_study("per_height", n_cells=50, seed=1))
    assert not np.array_equal(a[1], c[1])
    assert len(set(a[1])) == 50
    ids = _study("per_cell", n_cells=3).trial_ids()
    assert ids == _study("per_cell", n_cells=3).trial_ids() and len(set(ids)) == 3
    assert ids != _study("per_cell", n_cells=3, seed=1).trial_ids()


def test_nu_maps_to_the_closest_grid_shear_modulus():
    shears = [8.33, 10.0, 15.0, 20.0, 25.0]
    assert grid_shear(0.5, 25.0, shears)[0] == 8.33
    assert grid_shear(0.43, 25.0, shears) == (10.0, pytest.approx(15 / 35))
    assert grid_shear(0.25, 25.0, shears) == (15.0, 0.25)
    assert grid_shear(0.35, 25.0, shears) is None


def test_paper_and_demo_campaigns_hold_the_trials():
    paper = config.load(ROOT / "campaigns/paper.toml")
    assert len(paper.shells) == 540 and paper.trial_cells == 55
    nus = sorted({round(s.nu_true, 2) for s in paper.studies})
    assert nus == [0.25, 0.43, 0.5]
    assert {s.height_error_mode for s in paper.studies} == {"per_cell", "per_height"}
    assert {s.volume_error_rel_sd for s in paper.studies} == {0.075}
    assert {s.height_error_sd_um for s in paper.studies} == {0.5}
    demo = config.load(ROOT / "campaigns/demo.toml")
    assert demo.studies and len(demo.studies) * demo.trial_cells <= 1000


BAD = {
    "unknown key": FAKE.replace("seed = 7", "seed = 7\nsigma = 1"),
    "nu without grid K_S": FAKE.replace("nu = [0.5, 0.25]", "nu = [0.5, 0.35]"),
    "two nu, one K_S": FAKE.replace("nu = [0.5, 0.25]", "nu = [0.5, 0.497]"),
    "nu out of range": FAKE.replace("nu = [0.5, 0.25]", "nu = 1.5"),
    "no nu": FAKE.replace("nu = [0.5, 0.25]\n", ""),
    "zero cells": FAKE.replace("cells = 12", "cells = 0"),
    "fractional studies": FAKE.replace("studies = 3", "studies = 2.5"),
    "negative volume SD": FAKE.replace("volume_error_rel_sd = 0.075", "volume_error_rel_sd = -0.1"),
    "height SD as text": FAKE.replace("height_error_sd_um = 0.5", "height_error_sd_um = \"half\""),
    "height SD above the heights": FAKE.replace("height_error_sd_um = 0.5", "height_error_sd_um = 20.0"),
    "bad mode": FAKE.replace('["per_cell", "per_height"]', '"per_wedge"'),
    "tension not in grid": FAKE.replace("seed = 7", "seed = 7\ntension_mN_per_m = [1.0]"),
    "bending not in grid": FAKE.replace("seed = 7", "seed = 7\nbending = \"double\""),
    "two volumes": FAKE.replace("h0_um = [15.0", "volume_um3 = [4300.0, 4000.0]\nh0_um = [15.0"),
    "negative seed": FAKE.replace("seed = 7", "seed = -1"),
    "not a table": FAKE.replace("[montecarlo]", "montecarlo = 3\n[montecarlo2]"),
    "fake_law not bool": FAKE.replace("fake_law = true", "fake_law = 1"),
    "negative task sleep": FAKE.replace("fake_law = true", "fake_law = true\ntrial_sleep_s = -0.5"),
    "other trials": FAKE.replace("seed = 7", "seed = 8"),
}


@pytest.mark.parametrize("kind", sorted(BAD))
def test_bad_montecarlo_section_one_line_exit_2_store_untouched(fake_store, tmp_path, kind):
    (tmp_path / "bad.toml").write_text(BAD[kind])
    before = {p: (p.read_bytes(), p.stat().st_mtime_ns) for p in fake_store.parent.glob("s.h5*")}
    out = cortex("campaign", "run", str(tmp_path / "bad.toml"), "--store", str(fake_store))
    assert out.returncode == 2, (kind, out.stderr)
    assert len(out.stderr.strip().splitlines()) == 1, out.stderr
    assert "Traceback" not in out.stderr
    assert {p: (p.read_bytes(), p.stat().st_mtime_ns) for p in fake_store.parent.glob("s.h5*")} == before


def test_analysis_writes_the_montecarlo_table_from_a_store(fake_store, tmp_path):
    out = cortex("analysis", "calibrate", str(fake_store), "--out", str(tmp_path / "a"))
    assert out.returncode == 0, out.stderr
    records = json.loads((tmp_path / "a" / "montecarlo.json").read_text())
    assert len(records) == 4                             # 2 nu x 2 modes
    for r in records:
        assert {"nu_true", "height_error_mode", "n_cells", "median", "iqr", "median_p05", "median_p95",
                "iqr_p05", "iqr_p95"} <= set(r)
        assert r["n_cells"] == 12 and r["n_studies"] == 3
        assert r["median_p05"] <= r["median"] <= r["median_p95"]
        assert 0.0 < r["iqr"] < 1.0 and 0.0 <= r["excluded_fraction"] < 1.0
        if r["height_error_mode"] == "per_cell":     # a common offset keeps the curve's shape
            assert abs(r["median"] - r["nu_true"]) < 0.1


def test_zero_error_trials_invert_to_their_true_nu(tmp_path):
    """The fake law is exactly of the calibration's form, so with zero errors
    every trial's curve inverts to its model cell's ν (the whole chain:
    compressions -> trials -> store -> calibration -> inversion)."""
    from analysis.calibration.law import calibrate
    from analysis.calibration.command.montecarlo import montecarlo
    text = FAKE.replace("volume_error_rel_sd = 0.075", "volume_error_rel_sd = 0.0") \
        .replace("height_error_sd_um = 0.5", "height_error_sd_um = 0.0")
    assert run(tmp_path, text).returncode == 0
    cal, _, _ = calibrate(read_results(tmp_path / "s.h5"))
    records, _, cells = montecarlo(read_trials(tmp_path / "s.h5"), cal)
    assert cells["excluded_reason"].isna().all()
    for r in records:
        assert r["median"] == pytest.approx(r["nu_true"], abs=1e-6) and r["iqr"] < 1e-6
