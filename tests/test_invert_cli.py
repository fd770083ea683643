"""`cortex analysis invert` and `cortex afm analyze` with the shipped calibration:
the JSON and cells.csv of the specification, bad tables refused with one line
and exit status 2 (nothing written), a law-only calibration with the emulator
method refused."""

import json

import numpy as np
import pandas as pd
import pytest

from analysis.calibration.file import load_calibration
from conftest import cortex

KEYS = ["cell_id", "frequency_hz", "nu", "nu_lo95", "nu_hi95", "ks_tilde", "bulk_mN_per_m", "r2", "method",
        "excluded_reason"]


@pytest.fixture(scope="module")
def table(tmp_path_factory):
    """Two cells at two frequencies from the shipped emulator itself (K_B 22 and 30 mN/m)."""
    emu = load_calibration().emulator
    h = np.linspace(0.745, 0.5, 6)
    rows = []
    for cid, ks, bulk, tension, volume in (("x", 0.3, 22.0, 1.1, 4800.0), ("y", 1.5, 30.0, 2.0, 3900.0)):
        for f, scale in ((0.1, 1.0), (10.0, 0.8)):
            K = emu.modulus(h, bulk, ks * scale, tension, volume)
            rows += [{"cell_id": cid, "frequency_hz": f, "h_tilde": a, "modulus_mN_per_m": k,
                      "tension_mN_per_m": tension, "volume_um3": volume} for a, k in zip(h, K)]
    path = tmp_path_factory.mktemp("t") / "table.csv"
    pd.DataFrame(rows).to_csv(path, index=False)
    return path


def test_invert_json_and_cells_csv(table, tmp_path):
    run = cortex("analysis", "invert", table, "--out", tmp_path / "out", "--json", "--draws", 40)
    assert run.returncode == 0, run.stderr
    records = json.loads(run.stdout)
    assert len(records) == 4 and all(list(r) == KEYS for r in records)
    by = {(r["cell_id"], r["frequency_hz"]): r for r in records}
    for (cid, f), ks in ((("x", 0.1), 0.3), (("x", 10.0), 0.24), (("y", 0.1), 1.5), (("y", 10.0), 1.2)):
        r = by[(cid, f)]
        assert r["method"] == "emulator" and r["excluded_reason"] is None
        assert r["ks_tilde"] == pytest.approx(ks, rel=1e-4)
        assert r["nu_lo95"] < (1 - ks) / (1 + ks) < r["nu_hi95"]
    cells = pd.read_csv(tmp_path / "out" / "cells.csv")
    assert set(KEYS) <= set(cells.columns) and len(cells) == 4


def test_invert_law_method(table, tmp_path):
    run = cortex("analysis", "invert", table, "--out", tmp_path / "law", "--method", "law", "--json")
    assert run.returncode == 0, run.stderr
    records = json.loads(run.stdout)
    assert {r["method"] for r in records} == {"law"} and all(r["nu_lo95"] is None for r in records)


@pytest.mark.parametrize("content, words", [
    ("cell_id,h_tilde,modulus_mN_per_m\na,0.6,30\n", "missing column(s) tension_mN_per_m"),
    ("cell_id,h_tilde,modulus_mN_per_m,tension_mN_per_m\na,0.6,30,1\na,0.7,abc,1\n", "line 3: modulus_mN_per_m"),
    ("cell_id,h_tilde,modulus_mN_per_m,tension_mN_per_m\na,1.6,30,1\n", "line 2: h_tilde must be a number in (0, 1)"),
    ("cell_id,h_tilde,modulus_mN_per_m,tension_mN_per_m,volume_um3\na,0.6,30,1,-5\n", "volume_um3 must be"),
    ("\x00\x01\x02binary", "not a text (CSV) file"),
])
def test_invert_refuses_a_malformed_table(tmp_path, content, words):
    path = tmp_path / "bad.csv"
    path.write_bytes(content.encode("latin-1"))
    run = cortex("analysis", "invert", path, "--out", tmp_path / "out")
    assert run.returncode == 2
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in run.stderr and words in lines[0], run.stderr
    assert not (tmp_path / "out").exists()


def test_invert_refuses_a_folder_and_a_law_only_calibration(tmp_path, table):
    run = cortex("analysis", "invert", tmp_path, "--out", tmp_path / "out")
    assert run.returncode == 2 and "is a directory" in run.stderr
    cal = load_calibration().calibration
    law_only = tmp_path / "law.json"
    cal.save(law_only)
    run = cortex("analysis", "invert", table, "--out", tmp_path / "out", "--calibration", law_only,
                 "--method", "emulator")
    assert run.returncode == 2 and "no emulator tables" in run.stderr and len(run.stderr.splitlines()) == 1
    run = cortex("analysis", "invert", table, "--out", tmp_path / "out2", "--calibration", law_only, "--json")
    assert run.returncode == 0, run.stderr
    assert {r["method"] for r in json.loads(run.stdout)} == {"law"}       # a law-only file: the law
    run = cortex("analysis", "invert", table, "--out", tmp_path / "out3", "--bending", "triple")
    assert run.returncode == 2 and "bending" in run.stderr and "'triple'" in run.stderr  # checked by argparse now


def test_afm_analyze_needs_no_calibration(tmp_path):
    """A small synthetic experiment (the shipped law as forward model, errors off) analysed
    with the shipped emulator: intervals per cell, medians with intervals, the figure."""
    exp = tmp_path / "exp"
    shipped = str(__import__("analysis.calibration.file", fromlist=["x"]).shipped_path())
    run = cortex("afm", "synth", "--cells", 8, "--seed", 2, "--no-errors", "--solver", "law",
                 "--calibration", shipped, "--out", exp)
    assert run.returncode == 0, run.stderr
    run = cortex("afm", "analyze", exp, "--out", tmp_path / "an", "--draws", 30)
    assert run.returncode == 0, run.stderr
    cells = pd.read_csv(tmp_path / "an" / "cells.csv")
    ok = cells[cells["excluded_reason"].isna()]
    assert len(ok) >= 5 and (ok["nu_lo95"] <= ok["nu"]).all() and (ok["nu"] <= ok["nu_hi95"]).all()
    summary = json.loads((tmp_path / "an" / "summary.json").read_text())
    assert summary["method"] == "emulator"
    assert all("median_nu_lo95" in r for r in summary["frequencies"])
    assert (tmp_path / "an" / "nu_intervals.png").stat().st_size > 0
    assert "bootstrap 95 % interval" in (tmp_path / "an" / "report.md").read_text()


def test_help_of_every_new_command_renders():
    for args in (("analysis", "--help"), ("analysis", "invert", "--help"), ("analysis", "build-calibration", "--help"),
                 ("afm", "--help"), ("afm", "analyze", "--help")):
        run = cortex(*args)
        assert run.returncode == 0 and "exit status" in run.stdout, (args, run.stderr)
    assert "95 % intervals" in cortex("afm", "analyze", "--help").stdout


def test_a_table_without_volumes_needs_one_volume_given_and_there_is_no_default(tmp_path):
    """The table reader is where a cell's volume is checked; a table without volumes needs
    --volume (one line and status 2 without it), and below the reader the volume is required."""
    from analysis.invert.table_input import read_table
    path = tmp_path / "t.csv"
    path.write_text("cell_id,h_tilde,modulus_mN_per_m,tension_mN_per_m\na,0.6,30,1\na,0.7,40,1\n")
    assert read_table(path, 5100.0)["volume_um3"].tolist() == [5100.0, 5100.0]
    run = cortex("analysis", "invert", str(path), "--out", str(tmp_path / "out"))
    assert run.returncode == 2 and run.stderr.count("\n") == 1
    assert "no volume_um3 column" in run.stderr and "--volume" in run.stderr
    run = cortex("analysis", "invert", str(path), "--volume", "-3", "--out", str(tmp_path / "out"))
    assert run.returncode == 2 and "--volume must be a number > 0" in run.stderr
    file = load_calibration()
    emu = file.emulator
    with pytest.raises(TypeError):
        emu.ratio(0.6, 0.5, 0.04)          # no default volume below the reader
