"""The calibration bundle (`analysis.calibration.file`): a file holds what it embeds and what its
manifest names, nothing from the shipped bundle behind its back; one part replaced changes only
what depends on it; the manifest round-trips; `Settings()` is `cortex afm analyze`'s defaults."""

import json
import shutil

import numpy as np
import pytest

from analysis.calibration.file import POWERLAW_TABLE_NAME, RAMP_TABLE_NAME, TABLE_NAME, load_calibration, shipped_path
from analysis.calibration.law import Calibration
from bundles import bundle_copy
from common.errors import InputError
from studies.synthetic import reference_law

POINT = dict(h_tilde=0.6, ks_tilde=1.0, gamma_tilde=0.1, volume_um3=4300.0)


@pytest.fixture
def law_only(tmp_path):
    return Calibration({"standard": reference_law("standard")}).save(tmp_path / "law.json")


def _bundle(folder, table_doc=None):
    """A copy of the shipped bundle in `folder`, with `table_doc` as its viscoelastic table if given."""
    return bundle_copy(folder, None if table_doc is None else {TABLE_NAME: table_doc})


def test_a_law_only_file_borrows_nothing_unless_its_manifest_says_so(law_only, tmp_path):
    """Without a manifest: the law alone (no emulator, default method law); the viscoelastic reading
    and the ramp table refuse in one line naming the manifest entry that would borrow them. With
    "shipped" entries: the shipped emulator and table, and `sources` says so."""
    file = load_calibration(law_only)
    assert file.emulator is None and file.default_method == "law"
    assert file.sources == {"law": str(law_only)}
    for read in (lambda: file.viscoelastic, lambda: file.shell_ramp):
        with pytest.raises(InputError, match='does not name.*"shipped"') as err:
            read()
        assert "\n" not in str(err.value)
    borrowing = Calibration({"standard": reference_law("standard")}).save(tmp_path / "b.json",
                                                                            borrow=("emulator", "viscoelastic_table"))
    file = load_calibration(borrowing)
    assert file.sources == {"law": str(borrowing), "emulator": "shipped", "viscoelastic_table": "shipped"}
    assert file.default_method == "emulator"
    shipped = load_calibration(None)
    assert file.viscoelastic.emulator.ratio(**POINT) == shipped.emulator.ratio(**POINT)
    with pytest.raises(InputError, match="ramp_table"):
        file.shell_ramp


def test_the_shipped_bundle_says_shipped_for_every_part():
    assert load_calibration(None).sources == {p: "shipped" for p in ("law", "emulator", "viscoelastic_table",
                                                                         "ramp_table", "powerlaw_table")}


def test_replacing_the_viscoelastic_table_changes_only_the_complex_factor(tmp_path):
    """A modified copy of the complex table (ln C + 0.1 δ_B): ln C moves by exactly 0.1 δ_B, the
    emulator's K/K_B and the ramp table's forces do not move, and `sources` names the copy."""
    doc = json.loads(shipped_path(TABLE_NAME).read_text())
    ln_c = np.asarray(doc["ln_c_real"], float)
    ln_c[..., [tuple(t) for t in doc["terms"]].index((1, 0))] += 0.1          # ln C + 0.1 δ_B
    doc["ln_c_real"] = ln_c.tolist()
    mine = load_calibration(_bundle(tmp_path, doc))
    shipped = load_calibration(None)
    args = (0.6, 1.0, 0.1, 0.1, 0.3, 4300.0)
    moved = mine.viscoelastic.table.log_factor(*args) - shipped.viscoelastic.table.log_factor(*args)
    assert np.real(moved) == pytest.approx(0.1 * 0.1, abs=1e-9) and np.imag(moved) == pytest.approx(0.0, abs=1e-12)
    assert mine.viscoelastic.emulator.ratio(**POINT) == shipped.emulator.ratio(**POINT)
    d = np.linspace(0.01, 0.2, 5)
    np.testing.assert_array_equal(mine.shell_ramp.elastic(d, 0.01, 1.0, 8.0),
                                  shipped.shell_ramp.elastic(d, 0.01, 1.0, 8.0))
    assert mine.sources["viscoelastic_table"] == str(tmp_path / TABLE_NAME)


def test_a_missing_or_corrupt_part_is_one_line(tmp_path):
    cal = _bundle(tmp_path)
    (tmp_path / TABLE_NAME).write_text("{")
    with pytest.raises(InputError, match="cannot read the viscoelastic table") as err:
        load_calibration(cal).viscoelastic
    (tmp_path / TABLE_NAME).unlink()
    with pytest.raises(InputError, match="viscoelastic table it names.*is missing") as err:
        load_calibration(cal)
    assert "\n" not in str(err.value)
    doc = json.loads(cal.read_text())
    for parts, message in (({"correction": "x.json"}, "unknown part"), ({"ramp_table": "embedded"}, "does not hold it"),
                           ({"emulator": 3}, "must map")):
        cal.write_text(json.dumps({**doc, "parts": parts}))
        with pytest.raises(InputError, match=message):
            load_calibration(cal)


def test_the_manifest_round_trips(tmp_path):
    """The manifest as read, written back as `parts`, reads as the same bundle."""
    cal = _bundle(tmp_path)
    first = load_calibration(cal)
    assert first.manifest == {"law": "embedded", "emulator": "embedded", "viscoelastic_table": TABLE_NAME,
                              "ramp_table": RAMP_TABLE_NAME, "powerlaw_table": POWERLAW_TABLE_NAME}
    again = tmp_path / "again.json"
    again.write_text(json.dumps({**json.loads(cal.read_text()), "parts": first.manifest}))
    second = load_calibration(again)
    assert second.manifest == first.manifest and second.files == first.files
    assert second.sources == {**first.sources, "law": str(again), "emulator": str(again)}


def test_settings_defaults_are_the_commands(tmp_path):
    """`Settings()` equals what `cortex afm analyze` parses with no option given (the command
    only parses): the viscoelastic reading on, the jobs and the method left to their fall-backs."""
    from analysis.afm.analyze import TENSION_TOLERANCE
    from analysis.afm.analyze_pipeline import Settings
    from cortex.commands.afm import phase_settings, wait_setting
    from cortex.cli import build_parser
    args = build_parser().parse_args(["afm", "analyze", "x.h5", "--out", str(tmp_path)])
    phase, lags, lag_source = phase_settings(args)
    as_made, wait = wait_setting(args.wait_s, phase)
    defaults = Settings()
    assert (defaults.phase, defaults.lags, defaults.lag_source) == (phase, lags, lag_source)
    assert (defaults.as_made, defaults.wait_s) == (as_made, wait)
    assert (defaults.method, defaults.jobs, defaults.bending) == (args.method, args.jobs, args.bending)
    assert defaults.tension_tolerance == TENSION_TOLERANCE and args.tension_tolerance is None


def test_a_built_bundle_names_the_tables_beside_it_or_borrows_the_shipped_ones(tmp_path):
    from analysis.calibration.file import _table_parts
    assert _table_parts(tmp_path) == {"viscoelastic_table": "shipped", "ramp_table": "shipped",
                                      "powerlaw_table": "shipped"}
    shutil.copy(shipped_path(TABLE_NAME), tmp_path / TABLE_NAME)
    assert _table_parts(tmp_path) == {"viscoelastic_table": TABLE_NAME, "ramp_table": "shipped",
                                      "powerlaw_table": "shipped"}
    assert _table_parts(shipped_path().parent) == {"viscoelastic_table": TABLE_NAME, "ramp_table": RAMP_TABLE_NAME,
                                                   "powerlaw_table": POWERLAW_TABLE_NAME}
