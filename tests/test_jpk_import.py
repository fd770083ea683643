"""`cortex afm import` and `analyze` on JPK archives with modulation segments of
known truth (written by tests/jpk_writer.py from synthetic cells), the native
round trip, the dish reference, and bad files (one line, status 2, nothing
written)."""

import zipfile

import numpy as np
import pandas as pd
import pytest

from analysis.afm.cell import Cell, Segment
from analysis.afm.formats.h5 import read_experiment, read_provenance
from analysis.afm.formats.reader import ImportOptions, open as open_cells
from analysis.afm.provenance import FREQUENCY_DOMAIN, MEASURED
from analysis.afm.synth.cells import generate, law_forward
from analysis.calibration.law import Calibration
from studies.synthetic import reference_law
from cortex.cli import main
from jpk_writer import write_force, write_map

BORROW = ("emulator", "viscoelastic_table")      # a law-only file that borrows the shipped emulator and table

FORCE_NN, HEIGHT_UM = 1e-6, 1e-6        # the writer's quantisation is far below these


@pytest.fixture(scope="module")
def exp(tmp_path_factory):
    d = tmp_path_factory.mktemp("jpk")
    cells, _ = generate(3, seed=2, errors=True, forward=law_forward(reference_law()))
    folder = d / "force"
    folder.mkdir()
    for c in cells:
        write_force(folder / f"{c.cell_id}.jpk-force", c, dish_um=3.0)
    vol = d / "volumes.csv"
    pd.DataFrame({"cell_id": [c.cell_id for c in cells], "volume_um3": [c.volume_um3 for c in cells],
                  "volume_source": "confocal"}).to_csv(vol, index=False)
    cal = d / "cal.json"
    Calibration({b: reference_law(b) for b in ("standard", "double", "none")}).save(cal, borrow=BORROW)
    return d, cells, folder, vol, cal


def _same_cell(got, want):
    assert got.cell_id.endswith(want.cell_id) or got.cell_id.startswith("map")
    assert [(s.kind, s.start, s.stop) for s in got.segments] == [(s.kind, s.start, s.stop) for s in want.segments]
    osc = [(s.frequency_hz, s.amplitude_um) for s in got.segments if s.kind == "oscillation"]
    assert osc == [(s.frequency_hz, pytest.approx(0.25)) for s in want.segments if s.kind == "oscillation"]
    np.testing.assert_allclose(got.force_nN, want.force_nN, atol=FORCE_NN)
    np.testing.assert_allclose(got.height_um, want.height_um, atol=HEIGHT_UM)
    for s in got.segments:       # times within a segment as recorded, shifted by half a sample
        t, t0 = got.time_s[s.start:s.stop], want.time_s[s.start:s.stop]
        dt = np.diff(t0).mean() if s.stop - s.start > 1 else 0.0
        np.testing.assert_allclose(t - t0, dt / 2, atol=1e-9)


def test_written_force_archives_import_to_the_cells(exp):
    d, cells, folder, vol, _ = exp
    got = open_cells([folder], ImportOptions(volumes_csv=str(vol), dish_um=3.0))
    assert [g.cell_id for g in got] == [c.cell_id for c in cells]
    for g, c in zip(got, cells):
        _same_cell(g, c)
        assert g.volume_um3 == c.volume_um3 and g.volume_source == "confocal"
        assert g.recorded is not None and g.recorded["spring_constant_N_per_m"] == c.spring_constant_N_per_m
        mods = [s for s in g.recorded["segments"] if s["kind"] == "modulation"]
        assert mods and all(s["amplitude_um"] == pytest.approx(0.25) for s in mods)


@pytest.mark.parametrize("at_top, suffix", [(False, ".jpk-force-map"), (True, ".jpk-force-map"),
                                            (True, ".jpk-qi-data")], ids=["shared-info", "top-level", "qi"])
def test_written_map_pixels_import_to_the_cells(exp, tmp_path, at_top, suffix):
    _, cells, *_ = exp
    same = [cells[0]] * 2 if at_top else cells      # top-level settings: one segment plan for all pixels
    scan = "quantitative-imaging-map" if suffix == ".jpk-qi-data" else "force-scan-map"
    path = write_map(tmp_path / f"map{suffix}", same, settings_at_top=at_top, scan_type=scan)
    got = open_cells([path], ImportOptions(volume_um3=4000.0))
    assert [g.cell_id for g in got] == [f"map-px{i}" for i in range(len(same))]
    for g, c in zip(got, same):
        _same_cell(g, c)
        assert g.spring_constant_N_per_m == same[0].spring_constant_N_per_m


def test_native_round_trip(exp, tmp_path, capsys):
    _, cells, folder, vol, _ = exp
    out = tmp_path / "e"
    assert main(["afm", "import", str(folder), "--volumes", str(vol), "--dish-height-um", "3", "--out",
                 str(out)]) == 0
    back = read_experiment(out / "experiment.h5")
    assert read_provenance(out / "experiment.h5") == MEASURED           # imported: measured
    direct = open_cells([folder], ImportOptions(volumes_csv=str(vol), dish_um=3.0))
    def plan(cell):
        return [(s.kind, s.start, s.stop, *np.nan_to_num([s.frequency_hz, s.amplitude_um], nan=-1.0))
                for s in cell.segments]
    for b, c in zip(back, direct):
        assert plan(b) == plan(c)
        for name in ("time_s", "force_nN", "height_um"):
            np.testing.assert_array_equal(getattr(b, name), getattr(c, name))
        assert (b.volume_um3, b.spring_constant_N_per_m) == (c.volume_um3, c.spring_constant_N_per_m)


def test_modulation_archives_analyse_like_the_native_experiment(exp, tmp_path):
    """The JPK files of synthetic cells are measured ones to `afm analyze` (protocol-aware by
    default), so they are read in the relaxed state given (--wait-s inf): what the native experiment
    of the same cells, recorded as frequency-domain synthetic, is read with by default."""
    d, cells, folder, vol, cal = exp
    from analysis.afm.formats.h5 import write_experiment
    native = write_experiment(tmp_path / "native.h5", cells, FREQUENCY_DOMAIN)
    assert main(["afm", "analyze", str(native), "--calibration", str(cal), "--out", str(tmp_path / "a")]) == 0
    assert main(["afm", "analyze", str(folder), "--volumes", str(vol), "--dish-height-um", "3",
                 "--calibration", str(cal), "--out", str(tmp_path / "b"), "--wait-s", "inf"]) == 0
    import json
    said = {x: json.loads((tmp_path / x / "summary.json").read_text()) for x in ("a", "b")}
    assert said["a"]["reading"] == "relaxed (synthetic, frequency-domain)"
    assert said["b"]["reading"] == "relaxed (--wait-s inf; the experiment: measured)"
    assert said["b"]["provenance"] == {"kind": "measured", "recorded": True}
    a, b = (pd.read_csv(tmp_path / x / "cells.csv") for x in ("a", "b"))
    assert len(a) == len(b) > 3 and a["nu"].notna().sum() > 3
    pd.testing.assert_series_equal(a["cell_id"], b["cell_id"])
    for col in ("nu", "ks_tilde", "tension_mN_per_m", "loss_angle_rad"):
        np.testing.assert_allclose(b[col], a[col], rtol=1e-6, atol=1e-6, err_msg=col)
    assert (a["excluded_reason"].fillna("") == b["excluded_reason"].fillna("")).all()


def test_dish_curve_sets_the_height_reference(exp, tmp_path):
    """A curve pressed onto the bare dish: the wedge (z + F/k) stops at the dish
    while the force climbs; importing with it recovers the cells' heights."""
    _, cells, *_ = exp
    n, k = 400, 0.4
    h = np.r_[np.linspace(2.0, 0.0, n // 2), np.zeros(n // 2)]          # the wedge on the dish: h = 0
    force = np.r_[np.zeros(n // 2), np.linspace(0.0, 80.0, n // 2)]
    dish = Cell("dish", 1.0, np.arange(n) * 0.01, force, h, [Segment("approach", 0, n)], spring_constant_N_per_m=k)
    write_force(tmp_path / "dish.jpk-force", dish, dish_um=7.5)
    write_force(tmp_path / "c.jpk-force", cells[0], dish_um=7.5)
    got, = open_cells([tmp_path / "c.jpk-force"], ImportOptions(volume_um3=cells[0].volume_um3,
                                                                 dish_curve=str(tmp_path / "dish.jpk-force")))
    np.testing.assert_allclose(got.height_um, cells[0].height_um, atol=HEIGHT_UM)


def _rewrite(src, dst, edit):
    """Copy a zip, `edit(name, data)` returning new data or None to leave the member out."""
    with zipfile.ZipFile(src) as a, zipfile.ZipFile(dst, "w") as b:
        for name in a.namelist():
            data = edit(name, a.read(name))
            if data is not None:
                b.writestr(name, data)
    return dst


def _flip(data, at):
    data = bytearray(data)
    data[at] ^= 0xFF
    return bytes(data)


def _sub(old, new, member="segments/0/segment-header.properties"):
    return lambda name, data: data.replace(old, new) if name == member else data


def _without(suffix):
    return lambda name, data: None if name.endswith(suffix) else data


ZIP_EDITS = {                   # case: an edit of the archive's members
    "no header.properties": lambda name, data: None if name == "header.properties" else data,
    "no segment header": _without("segments/1/segment-header.properties"),
    "missing channel file": _without("segments/0/channels/vDeflection.dat"),
    "truncated channel": lambda name, data: data[:-4] if name.endswith("0/channels/measuredHeight.dat") else data,
    "unknown unit": _sub(b"unit.unit=N", b"unit.unit=lbf"),
    "unknown encoder": _sub(b"encoder.type=signedinteger", b"encoder.type=zigzag"),
    "channel without conversion": _sub(b"conversion.force.defined=true", b"conversion.force.defined=false"),
    "unknown segment style": _sub(b"style=extend", b"style=wobble"),
    "modulation without frequency": _sub(b"segment-settings.frequency=", b"segment-settings.freq=",
                                         "segments/1/segment-header.properties"),
}
BYTE_EDITS = {                  # case: an edit of the archive's bytes
    "not a zip": lambda data: b"hello",
    "truncated": lambda data: data[:5000],
    "empty file": lambda data: b"",
    "corrupt member": lambda data: _flip(data, 3000),
}


def _bad_archive(case, src, d, cell):
    if case in ZIP_EDITS:
        return _rewrite(src, d / "bad.jpk-force", ZIP_EDITS[case])
    if case in BYTE_EDITS:
        (d / "bad.jpk-force").write_bytes(BYTE_EDITS[case](src.read_bytes()))
        return d / "bad.jpk-force"
    assert case == "missing shared header"
    return _rewrite(write_map(d / "m0.jpk-force-map", [cell]), d / "bad.jpk-force-map",
                    lambda name, data: None if name.startswith("shared-data/") else data)


BAD = sorted(ZIP_EDITS) + sorted(BYTE_EDITS) + ["missing shared header"]


@pytest.mark.parametrize("case", BAD + ["volume missing for a cell", "volume table malformed",
                                                   "dish above the cell"])
def test_bad_files_one_line_status_2_nothing_written(exp, tmp_path, capsys, case):
    _, cells, folder, vol, cal = exp
    src = folder / f"{cells[0].cell_id}.jpk-force"
    args = ["--volume", "4000"]
    if case == "volume missing for a cell":
        path = folder
        (tmp_path / "v.csv").write_text(vol.read_text().splitlines()[0] + "\n" + vol.read_text().splitlines()[1] + "\n")
        args = ["--volumes", str(tmp_path / "v.csv")]
    elif case == "dish above the cell":
        path = src
        args += ["--dish-height-um", "50"]
    elif case == "volume table malformed":
        path = src
        (tmp_path / "v.csv").write_text("cell,vol\nx,1\n")
        args = ["--volumes", str(tmp_path / "v.csv")]
    else:
        path = _bad_archive(case, src, tmp_path, cells[0])
    for cmd in (["afm", "import", str(path), "--out", str(tmp_path / "out")],
                ["afm", "analyze", str(path), "--calibration", str(cal), "--out", str(tmp_path / "o")]):
        capsys.readouterr()
        status = main(cmd + args)
        err = capsys.readouterr().err
        assert status == 2, err
        assert len(err.strip().splitlines()) == 1 and "error" in err and "Traceback" not in err
    assert not (tmp_path / "out").exists() and not (tmp_path / "o").exists()


def test_analyze_reports_a_recording_without_modulation_and_exits_1(exp, tmp_path, capsys):
    _, cells, folder, vol, cal = exp
    mixed = tmp_path / "mixed"
    mixed.mkdir()
    for f in folder.iterdir():
        (mixed / f.name).write_bytes(f.read_bytes())
    c = cells[0]
    first = c.segments[0]                    # its first approach segment only, as a curve of its own
    lone = Cell("approach-only", c.volume_um3, c.time_s[:first.stop], c.force_nN[:first.stop],
                c.height_um[:first.stop], [first], spring_constant_N_per_m=c.spring_constant_N_per_m)
    write_force(mixed / "approach-only.jpk-force", lone, dish_um=3.0)
    table = tmp_path / "v.csv"
    table.write_text(vol.read_text() + f"approach-only,{c.volume_um3},confocal\n")
    capsys.readouterr()
    assert main(["afm", "analyze", str(mixed), "--volumes", str(table), "--dish-height-um", "3",
                 "--calibration", str(cal), "--out", str(tmp_path / "o"), "--no-phase"]) == 1
    assert "not analysed: approach-only: no modulation (oscillation) segment" in capsys.readouterr().out
    report = (tmp_path / "o" / "report.md").read_text()
    assert "| approach-only | no modulation (oscillation) segment |" in report
    done = pd.read_csv(tmp_path / "o" / "cells.csv")
    assert set(done["cell_id"]) == {x.cell_id for x in cells} and done["nu"].notna().any()


def test_import_options_refused_for_the_native_format(exp, tmp_path, capsys):
    _, cells, _, _, cal = exp
    from analysis.afm.formats.h5 import write_experiment
    native = write_experiment(tmp_path / "n.h5", cells)
    capsys.readouterr()
    assert main(["afm", "analyze", str(native), "--volume", "4000", "--calibration", str(cal),
                 "--out", str(tmp_path / "o")]) == 2
    assert "apply to instrument files only" in capsys.readouterr().err and not (tmp_path / "o").exists()


def _text_export(path, modulation):
    """A two-segment JPK-style text export: extend, then a 1 Hz modulation (or its settings missing)."""
    t = (np.arange(200) + 0.5) * 0.01
    head = ["# force-settings.segment.0.style: extend", "# force-settings.segment.0.duration: 2.0",
            "# force-settings.segment.1.style: modulation", "# force-settings.segment.1.duration: 2.0"]
    if modulation:
        head += ["# force-settings.segment.1.frequency: 1.0", "# force-settings.segment.1.amplitude: 2.5E-7"]
    lines = head
    for i, name in enumerate(("extend", "modulation")):
        z = 12e-6 - 1e-6 * t / 2 if i == 0 else 11e-6 - 2.5e-7 * np.sin(2 * np.pi * t)
        lines += [f"# segmentIndex: {i}", f"# segment: {name}", "# columns: height vDeflection seriesTime time",
                  "# units: m N s s", "# springConstant: 0.5", "# sensitivity: 2E-8"]
        lines += [f"{a:.17g} {b:.17g} {c:.17g} {d:.17g}" for a, b, c, d in zip(z, 20e-9 + 0 * t, t + 2.0 * i, t)]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_text_export_modulation_segment(tmp_path, capsys):
    from analysis.afm.formats.jpk.text import read_jpk_recording
    rec = read_jpk_recording(_text_export(tmp_path / "m.txt", True))
    assert [s.kind for s in rec.segments] == ["approach", "modulation"]
    mod = rec.segments[1]
    assert (mod.frequency_hz, mod.amplitude_um, mod.duration_s, mod.n_samples) == (1.0, pytest.approx(0.25), 2.0, 200)
    np.testing.assert_allclose(mod.time_s[[0, -1]], [2.005, 3.995])
    cell, = open_cells([tmp_path / "m.txt"], ImportOptions(volume_um3=4000.0))
    osc, = cell.oscillations()
    np.testing.assert_allclose(cell.height_um[osc.start:osc.stop], mod.height_um + 20.0 * 1e-3 / 0.5)
    capsys.readouterr()
    assert main(["afm", "import", str(_text_export(tmp_path / "bad.txt", False)), "--volume", "4000",
                 "--out", str(tmp_path / "o")]) == 2
    assert "modulation without" in capsys.readouterr().err and not (tmp_path / "o").exists()
