"""The Bruker NanoScope readers on the real files of ../shared/data/bruker/ (see
its README; `CORTEX_SHARED_DATA` names another data folder): header values and
channels checked against a decoding written here (a regex over the header and
numpy over the data block, not the project's parser), the binary curve against
its NanoScope Analysis text export, gzip-compressed exports, and every bad
file refused with one line and status 2, nothing written."""

import gzip
import os
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from analysis.afm.formats.bruker.nanoscope import read_curve, read_nanoscope
from analysis.afm.formats.bruker.text import read_columns, read_nanoscope_text
from analysis.afm.formats.instruments import read_file, read_recordings
from analysis.afm.formats.reader import ImportOptions, open as open_cells
from conftest import ROOT
from cortex.cli import main
from common.errors import EXIT_BAD_INPUT, EXIT_SOME_FAILED, InputError

SHARED = Path(os.environ.get("CORTEX_SHARED_DATA", ROOT.parent / "shared" / "data"))
DATA = SHARED / "bruker"
BINARY = DATA / "MDA-MB231_Dish2_Cell1.000"
EXPORT = DATA / "MDA-MB231_Dish2_Cell1.000-NanoScope-Analysis.txt"
JPK_TEXT = SHARED / "jpk" / "force-save-2020.10.29-12.06.06.196.txt"
need = pytest.mark.skipif(not DATA.is_dir(), reason=f"shared test data not found at {DATA}")


def _header_value(text, key, n=0):
    """The n-th occurrence of `\\key: value` in the header, as text."""
    return re.findall(rf"^\\{re.escape(key)}: (.*?)\r?$", text, re.M)[n]


def _numbers(s):
    return [float(x) for x in re.findall(r"[-+]?\d*\.?\d+(?:e[-+]?\d+)?", s, re.I)]


def _independent_decode():
    """(k, {channel: (extend, retract) in nm}, n_extend) by the Bruker forum's rule:
    value = raw int16 × (V/LSB of the channel's Z scale) × its Sens. (nm/V); the extend is
    stored last sample first."""
    data = BINARY.read_bytes()
    text = data.split(b"\x1a")[0].decode("latin-1")
    blocks = text.split("\\*Ciao force image list")[1:]
    out = {}
    for b in blocks:
        name = re.search(r"Image Data: S \[(\w+)\]", b).group(1)
        offset, length = int(_header_value(b, "Data offset")), int(_header_value(b, "Data length"))
        n_ramp, n_ext = (int(x) for x in _numbers(_header_value(b, "Samps/line")))
        sens_name, q = re.search(r"@4:Z scale: V \[(Sens\. \w+)\] \(([\d.]+) V/LSB\)", b).groups()
        sens = _numbers(_header_value(text, "@" + sens_name))[0]
        raw = np.frombuffer(data[offset:offset + length], "<i2").astype(float) * float(q) * sens
        out[name] = (raw[:n_ext][::-1], raw[n_ramp:])
    k = float(_header_value(text, "Spring Constant"))
    return k, out, n_ext


@need
def test_header_values_and_channels_as_the_file_states():
    c = read_curve(BINARY, BINARY.read_bytes())
    assert c.version == "0x09010300" and c.date == "2021-05-05T13:21:42"
    assert c.spring_constant_N_per_m == 0.0777945
    assert c.deflection_sensitivity_nm_per_V == 43.38853 and c.z_sensitivity_nm_per_V == 178.0978
    assert c.ramp_size_nm == pytest.approx(16.84468 * 178.0978, rel=1e-12)      # @4:Ramp size V x Zsens
    assert (c.n_ramp, c.n_extend, c.n_retract) == (5632, 5026, 5632)
    assert c.extend_duration_s == pytest.approx(16.84468 / 16.8717)              # ramp size / Forward vel.
    k, channels, n_ext = _independent_decode()
    assert set(c.channels) == set(channels) == {"DeflectionError", "ZSensor"}
    for name, (ext, ret) in channels.items():
        np.testing.assert_allclose(c.channels[name].extend, ext, rtol=1e-14)
        np.testing.assert_allclose(c.channels[name].retract, ret, rtol=1e-14)
        assert c.channels[name].unit == "nm"
    raw = np.frombuffer(BINARY.read_bytes()[40960:40960 + 22528], "<i2")
    assert not raw[n_ext:5632].any() and raw[:n_ext].all()                        # the triggered ramp's padding


@need
def test_recording_in_project_units():
    rec = read_nanoscope(BINARY)
    k, channels, _ = _independent_decode()
    app, ret = rec.segments
    assert (rec.cell_id, app.kind, ret.kind) == ("MDA-MB231_Dish2_Cell1.000", "approach", "retract")
    np.testing.assert_allclose(app.force_nN, k * channels["DeflectionError"][0], rtol=1e-15)   # N/m x nm = nN
    np.testing.assert_allclose(app.height_um, -channels["ZSensor"][0] / 1000, rtol=1e-15)
    # the cantilever falls during the approach, the force grows at contact; retract goes back up
    assert app.height_um[0] - app.height_um[-1] == pytest.approx(2.631, abs=0.001)
    assert np.argmax(app.force_nN) > 0.99 * app.n_samples and ret.height_um[-1] > ret.height_um[0] + 2.9
    dt = (16.84468 / 16.8717) / 5632
    assert np.diff(app.time_s) == pytest.approx(dt) and app.time_s[0] == pytest.approx(dt / 2)
    assert ret.time_s[0] == pytest.approx(5026 * dt + dt / 2)
    assert rec.summary()["spring_constant_N_per_m"] == 0.0777945


@need
def test_binary_and_text_export_agree_within_their_channels():
    """The export's Z is the commanded ramp and its deflection the binary's with
    NanoScope Analysis's baseline (an offset and a tilt in Z) subtracted."""
    c = read_curve(BINARY, BINARY.read_bytes())
    z_nm, d_nm, unit = read_columns(EXPORT)
    assert unit == "nm" and len(z_nm) == c.n_extend
    assert np.max(np.abs(z_nm - c.ramp_nm("extend"))) < 0.2                     # nm; a ramp step is 0.53 nm
    diff = c.channels["DeflectionError"].extend - d_nm
    base = np.polynomial.polynomial.polyfit(z_nm, diff, 1)
    assert np.max(np.abs(diff - np.polynomial.polynomial.polyval(z_nm, base))) < 2e-5   # nm: the export's digits
    assert base[0] == pytest.approx(-104.14, abs=0.01) and base[1] * 1e3 == pytest.approx(-1.359, abs=0.001)
    b, t = read_nanoscope(BINARY).segments[0], read_nanoscope_text(EXPORT).segments[0]
    np.testing.assert_array_equal(b.time_s, t.time_s)
    # heights: the height sensor against the commanded ramp, within a percent in scale
    slope, _ = np.polyfit(t.height_um, b.height_um, 1)
    assert abs(slope - 1) < 0.01
    assert t.force_nN[-1] - t.force_nN[0] == pytest.approx(0.0777945 * (d_nm[-1] - d_nm[0]))


@need
def test_folder_and_gzip_copies_read_the_same(tmp_path):
    recs = read_recordings([DATA])
    assert [r.cell_id for r in recs] == ["MDA-MB231_Dish2_Cell1.000", "MDA-MB231_Dish2_Cell1.000-NanoScope-Analysis"]
    shutil.copy(BINARY, tmp_path / BINARY.name)
    copies = [(EXPORT, tmp_path / (EXPORT.name + ".gz"))]
    if JPK_TEXT.is_file():
        copies.append((JPK_TEXT, tmp_path / (JPK_TEXT.name + ".gz")))
    for src, dst in copies:
        dst.write_bytes(gzip.compress(src.read_bytes()))
        plain, packed = read_file(src)[0], read_file(dst)[0]
        assert packed.cell_id == plain.cell_id and len(packed.segments) == len(plain.segments)
        for a, b in zip(plain.segments, packed.segments):
            np.testing.assert_array_equal(a.force_nN, b.force_nN)
            np.testing.assert_array_equal(a.height_um, b.height_um)
            np.testing.assert_array_equal(a.time_s, b.time_s)


@need
def test_an_export_under_its_original_name_finds_its_binary(tmp_path):
    """NanoScope Analysis names an export `X.000 - NanoScope Analysis.txt`; gzip it, and a
    folder of the two files reads both, the export with the binary's k and times."""
    shutil.copy(BINARY, tmp_path / BINARY.name)
    export = tmp_path / "MDA-MB231_Dish2_Cell1.000 - NanoScope Analysis.txt.gz"
    export.write_bytes(gzip.compress(EXPORT.read_bytes()))
    binary, text = read_recordings([tmp_path])
    assert text.cell_id == "MDA-MB231_Dish2_Cell1.000 - NanoScope Analysis"
    assert text.spring_constant_N_per_m == 0.0777945 and text.date == binary.date
    np.testing.assert_array_equal(text.segments[0].time_s, binary.segments[0].time_s)


@need
def test_an_export_alone_needs_its_spring_constant(tmp_path):
    alone = tmp_path / EXPORT.name
    shutil.copy(EXPORT, alone)
    with pytest.raises(InputError, match="holds no spring constant"):
        read_file(alone)
    rec = read_file(alone, spring_constant_N_per_m=0.1)[0]
    _, d_nm, _ = read_columns(EXPORT)
    np.testing.assert_allclose(rec.segments[0].force_nN, 0.1 * d_nm)
    assert np.isnan(rec.segments[0].time_s).all()                                # no sampling without the binary
    with pytest.raises(InputError, match="sample times unknown"):
        open_cells([alone], ImportOptions(volume_um3=4000.0, dish_um=-5.0, spring_constant_N_per_m=0.1))


def test_an_export_of_force_and_a_retract(tmp_path):
    """A force column is taken as written (pN -> nN); rows of falling Z are a retract."""
    path = tmp_path / "retract.txt"
    path.write_text("nm\tpN\n3000\t50\n2000\t20\n1000\t-10\n", encoding="utf-8")
    seg = read_file(path, spring_constant_N_per_m=0.05)[0].segments[0]
    assert seg.kind == "retract"
    np.testing.assert_allclose(seg.force_nN, [0.05, 0.02, -0.01])
    np.testing.assert_allclose(seg.height_um, [-3.0, -2.0, -1.0])
    assert main(["afm", "import", str(path), "--spring-constant", "-1", "--volume", "4000",
                 "--out", str(tmp_path / "o")]) == EXIT_BAD_INPUT


@need
def test_a_hold_becomes_a_pause_of_its_duration(tmp_path):
    data = BINARY.read_bytes()
    assert data.count(b"\\Reverse delay: 0\r\n") == 1
    held = tmp_path / "held.000"
    held.write_bytes(data.replace(b"\\Reverse delay: 0\r\n", b"\\Reverse delay: 2\r\n"))   # same length
    app, pause, ret = read_nanoscope(held).segments
    assert (pause.kind, pause.duration_s, pause.n_samples) == ("pause", 2.0, 0)
    plain = read_nanoscope(BINARY).segments[1]
    np.testing.assert_allclose(ret.time_s, plain.time_s + 2.0)


def _bad_files(tmp_path):
    data = BINARY.read_bytes()
    end = data.index(b"\\*File list end")
    no_k = data.replace(b"\\Spring Constant:", b"\\Spring Kontrast:")
    files = {"truncated header": data[:end - 100], "header without the spring constant": no_k,
             "data block shorter than stated": data[:80000], "image file": b"\\*File list\r\n" + data[18:]}
    paths = {}
    for what, content in files.items():
        paths[what] = tmp_path / f"{what.replace(' ', '_')}.000"
        paths[what].write_bytes(content)
    for what, content in {"empty export": b"", "export without rows": b"    \xb5m         \tnm\r\n",
                          "export of three columns": b"nm\tnm\tnm\r\n1\t2\t3\r\n4\t5\t6\r\n"}.items():
        paths[what] = tmp_path / f"{what.replace(' ', '_')}.txt"
        paths[what].write_bytes(content)
    return paths


@need
@pytest.mark.parametrize("what,message", [
    ("truncated header", "truncated NanoScope header"),
    ("header without the spring constant", "without '\\\\Spring Constant'"),
    ("data block shorter than stated", "data block shorter than stated"),
    ("image file", "image file, not a force curve"),
    ("empty export", "empty NanoScope Analysis text export"),
    ("export without rows", "0 data row"),
    ("export of three columns", "is not two units"),
])
def test_every_bad_file_is_one_line_and_status_2_nothing_written(tmp_path, capsys, what, message):
    bad = _bad_files(tmp_path)[what]
    with pytest.raises(InputError, match=message):
        read_file(bad, spring_constant_N_per_m=0.1)
    out = tmp_path / "out"
    status = main(["afm", "import", str(BINARY), str(bad), "--volume", "4000", "--spring-constant", "0.1",
                   "--out", str(out)])
    err = capsys.readouterr().err
    assert status == EXIT_BAD_INPUT and not out.exists()
    assert len(err.strip().splitlines()) == 1 and str(bad) in err and "Traceback" not in err


@need
def test_import_and_analyze_take_bruker_files(tmp_path, capsys):
    out = tmp_path / "imp"
    assert main(["afm", "import", str(BINARY), str(EXPORT), "--volume", "4000", "--dish-height-um", "-5",
                 "--out", str(out)]) == 0
    from analysis.afm.formats.h5 import read_experiment
    cells = {c.cell_id: c for c in read_experiment(out / "experiment.h5")}
    assert set(cells) == {"MDA-MB231_Dish2_Cell1.000", "MDA-MB231_Dish2_Cell1.000-NanoScope-Analysis"}
    assert [s.kind for s in cells["MDA-MB231_Dish2_Cell1.000"].segments] == ["approach", "retract"]
    capsys.readouterr()
    status = main(["afm", "analyze", str(BINARY), "--volume", "4000", "--dish-height-um", "-5",
                   "--method", "law", "--out", str(tmp_path / "an")])
    assert status == EXIT_SOME_FAILED                                           # a ramp has no modulation
    assert "not analysed: MDA-MB231_Dish2_Cell1.000" in capsys.readouterr().out
