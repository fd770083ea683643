"""`cortex afm tension --calibration`: the bundle's shell ramp table replaces the shipped one, its
emulator and viscoelastic table read the oscillations, and the rows say which they read
(`shell_table_source`, `shell_table_sha256`, `prior_calibration_source`); a bundle that names
none of them (a law-only file) leaves the shipped ones in use and says so; a bad bundle is one
line and exit status 2, nothing written."""

import json

import numpy as np
import pytest

from analysis.afm.formats.csvcell import write_csv_cell
from analysis.afm.formats.instruments import to_cell
from analysis.afm.tension import shell_ramp
from analysis.calibration.file import RAMP_TABLE_NAME
from analysis.calibration.law import Calibration
from bundles import bundle_copy, shipped_part
from cortex.cli import main
from solver.geometry import cell_radius
from studies.synthetic import reference_law
from studies.tension_synth import droplet_recording

VOLUME = 3000.0
TENSION, BULK, SHEAR = 0.5, 5.0, 1.0 / 3.0          # mN/m, mN/m, K_S/K_B


@pytest.fixture(scope="module")
def elastic_csv(tmp_path_factory):
    """A single-cell CSV: an approach ramp onto an elastic cell (the shell ramp model with the
    shipped table, γ_a 0.5 mN/m, K_B 5 mN/m, K_S/K_B 1/3) 1.5 µm deep, its pause and retract."""
    radius = float(cell_radius(VOLUME))
    cell = to_cell(droplet_recording(VOLUME, TENSION, 1.5, cell_id="e", noise_nN=0.02, seed=1), VOLUME, "synthetic")
    approach = next(s for s in cell.segments if s.kind == "approach")
    part = slice(approach.start, approach.stop)
    noise = np.random.default_rng(2).normal(0.0, 0.02, approach.stop - approach.start)
    cell.force_nN[part] = shell_ramp.force_nN(2.0 * radius - cell.height_um[part], radius, TENSION, BULK, SHEAR) + noise
    return write_csv_cell(tmp_path_factory.mktemp("cell") / "e.csv", cell)


def _ramp(capsys, csv, *argv):
    """The approach row of `afm tension` on `csv` (the shell at K_S/K_B 1/3)."""
    status = main(["afm", "tension", str(csv), "--shear-ratio", str(SHEAR), "--json", "--no-power-law", *map(str, argv)])
    doc = json.loads(capsys.readouterr().out)
    assert status == 0
    return next(r for r in doc["rows"] if r["part"] == "approach")


def _bundle(folder, scale=None):
    """A copy of the shipped bundle in `folder`, its shell ramp table's forces times `scale` if given."""
    if scale is None:
        return bundle_copy(folder)
    doc = shipped_part(RAMP_TABLE_NAME)
    doc["force_over_kb_r"] = (scale * np.asarray(doc["force_over_kb_r"])).tolist()
    return bundle_copy(folder, {RAMP_TABLE_NAME: doc})


def test_the_bundles_ramp_table_replaces_the_shipped_one(tmp_path, capsys, elastic_csv):
    """The cell made with the shipped table reads back its truth with it. A bundle whose table's
    F/(K_B R) is 1.5 times the shipped one's makes the same force with γ_a and K_B both 1/1.5 of
    theirs at the same γ̃_a (F = γ_a R ĝ + K_B R (f - γ̃_a ĝ) = K_B R f), which the reading
    returns; the row names that table's file and hash."""
    shipped = _ramp(capsys, elastic_csv)
    assert (shipped["shell_table_source"], shipped["prior_calibration_source"]) == ("shipped", "shipped")
    assert (shipped["tension_mN_per_m"], shipped["bulk_modulus_mN_per_m"]) == pytest.approx((TENSION, BULK), rel=0.05)
    mine = _bundle(tmp_path, scale=1.5)
    row = _ramp(capsys, elastic_csv, "--calibration", mine)
    assert (row["shell_table_source"], row["prior_calibration_source"]) == (str(tmp_path / RAMP_TABLE_NAME), str(mine))
    assert row["shell_table_sha256"] != shipped["shell_table_sha256"] and len(row["shell_table_sha256"]) == 16
    for key in ("tension_mN_per_m", "bulk_modulus_mN_per_m"):
        assert row[key] == pytest.approx(shipped[key] / 1.5, rel=0.01)
    (tmp_path / "copy").mkdir()
    same = _ramp(capsys, elastic_csv, "--calibration", _bundle(tmp_path / "copy"))
    assert same["shell_table_sha256"] == shipped["shell_table_sha256"]          # an unchanged copy: the same table
    assert same["tension_mN_per_m"] == pytest.approx(shipped["tension_mN_per_m"], rel=1e-9)


def test_a_law_only_bundle_leaves_the_shipped_table_and_says_so(tmp_path, capsys, elastic_csv):
    law = Calibration({"standard": reference_law("standard")}).save(tmp_path / "law.json")
    shipped = _ramp(capsys, elastic_csv)
    out = tmp_path / "out"
    row = _ramp(capsys, elastic_csv, "--calibration", law, "--out", out)
    assert (row["shell_table_source"], row["shell_table_sha256"]) == ("shipped", shipped["shell_table_sha256"])
    assert row["prior_calibration_source"] == "shipped"          # no emulator: the shipped one reads the oscillations
    assert row["tension_mN_per_m"] == pytest.approx(shipped["tension_mN_per_m"], rel=1e-9)
    assert "Shell ramp table: shipped (SHA-256" in (out / "report.md").read_text()


def _bad(tmp_path, capsys, csv, calibration):
    out = tmp_path / "never"
    status = main(["afm", "tension", str(csv), "--calibration", str(calibration), "--no-power-law", "--out", str(out)])
    err = capsys.readouterr().err.strip()
    assert status == 2 and len(err.splitlines()) == 1 and not out.exists()
    return err


def test_a_bad_calibration_is_one_line_and_exit_2(tmp_path, capsys, elastic_csv):
    assert "missing.json" in _bad(tmp_path, capsys, elastic_csv, tmp_path / "missing.json")
    (tmp_path / "corrupt.json").write_text("{not json")
    assert "corrupt.json" in _bad(tmp_path, capsys, elastic_csv, tmp_path / "corrupt.json")
    assert str(tmp_path) in _bad(tmp_path, capsys, elastic_csv, tmp_path)                 # a folder
    (tmp_path / "other.json").write_text(json.dumps({"format": "something else"}))
    assert "other.json" in _bad(tmp_path, capsys, elastic_csv, tmp_path / "other.json")
    for name, table in (("keyless", {"format": "cortex-shell-ramp-table"}), ("holes", None)):
        folder = tmp_path / name
        folder.mkdir()
        cal = _bundle(folder)
        doc = json.loads((folder / RAMP_TABLE_NAME).read_text())
        if table is None:
            doc["force_over_kb_r"][0][0][0][0] = None
            table = doc
        (folder / RAMP_TABLE_NAME).write_text(json.dumps(table))
        assert RAMP_TABLE_NAME in _bad(tmp_path, capsys, elastic_csv, cal)
