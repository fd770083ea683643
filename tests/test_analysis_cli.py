"""`cortex analysis calibrate`: the whole run on a store whose tables are made
by the laws, refusals of unfinished stores and corrupt files (one line, exit
status 2, nothing written)."""

import json
import sys
import types

import numpy as np
import pytest

import analysis.calibration.command.pipeline as report
from analysis.calibration.file import load_calibration
from studies.synthetic import reference_law, results_table, trials_table
from cortex.cli import main

LAWS = {b: reference_law(b) for b in ("standard", "double", "none")}


@pytest.fixture(scope="module")
def tables():
    results = results_table(LAWS, noise=0.002, rng=2)
    trials = trials_table(LAWS["standard"], nu_values=(0.5, 0.25), n_cells=20, n_studies=4, seed=3)
    return results, trials


@pytest.fixture
def store(tmp_path, monkeypatch, tables):
    """A store path whose reading returns (copies of) the tables."""
    path = tmp_path / "store.h5"
    path.write_bytes(b"stand-in")
    state = {"results": tables[0].copy(), "trials": tables[1].copy()}
    monkeypatch.setattr(report, "read_store", lambda p: (state["results"], state["trials"]))
    return path, state


def _one_line_error(capsys):
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("cortex analysis calibrate: error:")
    return err[0]


def test_full_run_writes_everything(store, tmp_path, capsys):
    path, _ = store
    out = tmp_path / "out"
    assert main(["analysis", "calibrate", str(path), "--out", str(out)]) == 0
    for name in ("calibration.json", "calibration_fits.csv", "calibration_log_law.csv", "reconstruction.csv",
                 "montecarlo.json", "montecarlo_studies.csv", "montecarlo_cells.csv", "report.md"):
        assert (out / name).stat().st_size > 0, name
    for fig in ("modulus_vs_height", "alpha_vs_shear", "reconstruction", "equator_shear_ratio", "montecarlo"):
        assert (out / f"{fig}.png").exists() and (out / f"{fig}.pdf").exists()
    cal = load_calibration(out / "calibration.json").calibration
    assert cal is not None
    assert set(cal.laws) == set(LAWS)
    for name, law in cal.laws.items():
        assert law.lam == pytest.approx(LAWS[name].lam, rel=0.01)
    mc = json.loads((out / "montecarlo.json").read_text())
    assert len(mc) == 2 * 2
    for rec in mc:
        assert set(rec) >= {"nu_true", "height_error_mode", "n_cells", "median", "iqr", "median_p05",
                            "median_p95", "iqr_p05", "iqr_p95"}
        assert rec["n_cells"] == 20
        assert rec["median_p05"] <= rec["median"] <= rec["median_p95"]
        assert rec["iqr_p05"] <= rec["iqr"] <= rec["iqr_p95"]
    text = (out / "report.md").read_text()
    assert "## Reconstruction check" in text and "## Monte-Carlo error study" in text
    assert "![montecarlo](montecarlo.png)" in text and "Partial" not in text
    streams = capsys.readouterr()
    assert "report:" in streams.out and "[analysis" in streams.err    # progress lines


def test_unfinished_store_is_refused_in_one_line(store, tmp_path, capsys):
    path, state = store
    res = state["results"]
    res.loc[res.index[:7], "state"] = "pending"
    res.loc[res.index[7:9], "state"] = "failed"
    res.loc[res.index[:9], "modulus_mN_per_m"] = np.nan
    out = tmp_path / "out"
    assert main(["analysis", "calibrate", str(path), "--out", str(out)]) == 2
    line = _one_line_error(capsys)
    assert "9 of 540 compression tasks not done (7 pending, 2 failed)" in line and "--partial" in line
    assert not out.exists()                                           # nothing written


def test_partial_run_says_what_it_left_out(store, tmp_path, capsys):
    path, state = store
    res = state["results"]
    res.loc[res.index[:7], "state"] = "running"
    res.loc[res.index[:7], "modulus_mN_per_m"] = np.nan
    out = tmp_path / "out"
    assert main(["analysis", "calibrate", str(path), "--out", str(out), "--partial"]) == 0
    text = (out / "report.md").read_text()
    assert "Partial analysis" in text and "7 of 540 compression tasks not done (7 running)" in text
    assert "partial:" in capsys.readouterr().err


def test_existing_outputs_survive_a_refusal(store, tmp_path, capsys):
    path, state = store
    out = tmp_path / "out"
    out.mkdir()
    (out / "calibration.json").write_text("keep me")
    state["results"].loc[state["results"].index[0], "state"] = "pending"
    assert main(["analysis", "calibrate", str(path), "--out", str(out)]) == 2
    assert (out / "calibration.json").read_text() == "keep me"
    _one_line_error(capsys)


def test_missing_store_and_bad_out(tmp_path, capsys):
    assert main(["analysis", "calibrate", str(tmp_path / "nope.h5"), "--out", str(tmp_path / "o")]) == 2
    assert "no such store" in _one_line_error(capsys)
    store = tmp_path / "s.h5"
    store.write_bytes(b"x")
    (tmp_path / "file").write_text("")
    assert main(["analysis", "calibrate", str(store), "--out", str(tmp_path / "file")]) == 2
    assert "not a directory" in _one_line_error(capsys)


def test_reader_failure_becomes_one_line(tmp_path, monkeypatch, capsys):
    """What h5py raises on a damaged file (OSError) becomes one clear line."""
    fake = types.ModuleType("campaign.store.reader")

    def broken(path):
        raise OSError("Unable to synchronously open file (file signature not found)")
    fake.read_results = fake.read_trials = broken
    pkg, store = types.ModuleType("campaign"), types.ModuleType("campaign.store")
    pkg.store, store.reader = store, fake
    monkeypatch.setitem(sys.modules, "campaign", pkg)
    monkeypatch.setitem(sys.modules, "campaign.store", store)
    monkeypatch.setitem(sys.modules, "campaign.store.reader", fake)
    path = tmp_path / "corrupt.h5"
    path.write_bytes(b"\x00garbage" * 100)
    assert main(["analysis", "calibrate", str(path), "--out", str(tmp_path / "o")]) == 2
    line = _one_line_error(capsys)
    assert "not a readable campaign store" in line and "file signature not found" in line
    assert not (tmp_path / "o").exists()


def test_corrupt_file_with_the_real_reader(tmp_path, capsys):
    pytest.importorskip("campaign.store.reader", reason="the campaign store reader is not in this checkout yet")
    path = tmp_path / "corrupt.h5"
    path.write_bytes(b"\x89HDF\r\n\x1a\n" + b"\x00" * 64 + b"garbage" * 50)
    assert main(["analysis", "calibrate", str(path), "--out", str(tmp_path / "o")]) == 2
    _one_line_error(capsys)
    assert not (tmp_path / "o").exists()
