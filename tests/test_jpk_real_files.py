"""The JPK readers on real instrument files (../shared/data/jpk/, see its
README): segment kinds, counts, durations, spring constants, and samples
checked against a decoding written here from the files' own properties (a
line split and numpy, not the project's parser or conversion code)."""

import json
import zipfile

import numpy as np
import pytest

from analysis.afm.formats.jpk.text import read_jpk_recording
from analysis.afm.formats.jpk.archive import read_archive
from analysis.afm.formats.instruments import wedge_height_um
from conftest import ROOT
from cortex.cli import main

DATA = ROOT.parent / "shared" / "data" / "jpk"
TEXT = DATA / "force-save-2020.10.29-12.06.06.196.txt"
BRAIN = DATA / "fmt-jpk-cc_pr14-brain-2021.06.30.jpk-force"
JPKFILE = DATA / "force-save-2016.06.15-13.17.08.jpk-force"
need = pytest.mark.skipif(not DATA.is_dir(), reason=f"shared test data not found at {DATA}")


def _props(z, name):
    """key -> value of a properties member (plain split at the first '=')."""
    lines = z.read(name).decode("iso-8859-1").splitlines()
    return dict(line.split("=", 1) for line in lines if "=" in line and not line.startswith("#"))


def _linear(p, prefix):
    return float(p[prefix + ".offset"]), float(p[prefix + ".multiplier"])


def _decode_inline(z, seg, name, dtype, slots):
    """An inline channel (2016 file): encoder then the named conversion slots in order."""
    p = _props(z, f"segments/{seg}/segment-header.properties")
    c = f"channel.{name}"
    x = np.frombuffer(z.read(f"segments/{seg}/channels/{name}.dat"), dtype).astype(float)
    off, mult = _linear(p, c + ".data.encoder.scaling")
    x = off + mult * x
    for slot in slots:
        off, mult = _linear(p, f"{c}.conversion-set.conversion.{slot}.scaling")
        x = off + mult * x
    return x, p


def _decode_shared(z, seg, name, slots):
    """A channel described by shared-data lcd-info (2021 file), int32 counts."""
    p = _props(z, f"segments/{seg}/segment-header.properties")
    shared = _props(z, "shared-data/header.properties")
    lcd = f"lcd-info.{p[f'channel.{name}.lcd-info.*']}"
    assert shared[lcd + ".channel.name"] == name and shared[lcd + ".encoder.type"] == "signedinteger"
    x = np.frombuffer(z.read(f"segments/{seg}/channels/{name}.dat"), ">i4").astype(float)
    off, mult = _linear(shared, lcd + ".encoder.scaling")
    x = off + mult * x
    for slot in slots:
        off, mult = _linear(shared, f"{lcd}.conversion-set.conversion.{slot}.scaling")
        x = off + mult * x
    return x, shared, lcd


SAMPLES = [0, 1, 777, -1]


@need
def test_afmformats_test_file_segments_and_samples():
    rec, = read_archive(BRAIN)
    assert [s.kind for s in rec.segments] == ["approach", "pause", "retract"]
    assert [s.n_samples for s in rec.segments] == [3000] * 3
    assert [s.duration_s for s in rec.segments] == [3.0] * 3
    with zipfile.ZipFile(BRAIN) as z:
        for j, seg in enumerate(rec.segments):
            f, shared, lcd = _decode_shared(z, j, "vDeflection", ["distance", "force"])
            h, _, _ = _decode_shared(z, j, "measuredHeight", ["nominal"])
            np.testing.assert_allclose(seg.force_nN[SAMPLES], f[SAMPLES] * 1e9, rtol=1e-12)
            np.testing.assert_allclose(seg.height_um[SAMPLES], h[SAMPLES] * 1e6, rtol=1e-12)
        k = float(shared[lcd + ".conversion-set.conversion.force.scaling.multiplier"])
    assert rec.spring_constant_N_per_m == k
    # the first sample as afmformats decodes it (its test data): 11.2304654 nN at 47.4033462 um
    assert rec.segments[0].force_nN[0] == pytest.approx(11.2304654, abs=1e-6)
    assert rec.segments[0].height_um[0] == pytest.approx(47.4033462, abs=1e-6)


@need
def test_jpkfile_example_segments_and_samples():
    rec, = read_archive(JPKFILE)
    assert [s.kind for s in rec.segments] == ["approach", "pause", "retract", "pause"]
    assert [s.n_samples for s in rec.segments] == [60000, 30000, 60000, 2]
    assert [s.duration_s for s in rec.segments] == [10.0, 5.0, 10.0, 5.0]
    with zipfile.ZipFile(JPKFILE) as z:
        for j, seg in enumerate(rec.segments):
            f, p = _decode_inline(z, j, "vDeflection", ">i2", ["distance", "force"])
            # strainGaugeHeight: encoder (V), then absolute and nominal (its default) heights in m
            h, _ = _decode_inline(z, j, "strainGaugeHeight", ">i2", ["absolute", "nominal"])
            idx = SAMPLES if seg.n_samples > 2 else [0, -1]
            np.testing.assert_allclose(seg.force_nN[idx], f[idx] * 1e9, rtol=1e-12)
            np.testing.assert_allclose(seg.height_um[idx], h[idx] * 1e6, rtol=1e-12)
            k = float(p["channel.vDeflection.conversion-set.conversion.force.scaling.multiplier"])
            assert rec.spring_constant_N_per_m == k
    # times: mid-sample, durations summed (segment 3 holds two samples over 5 s)
    np.testing.assert_allclose(rec.segments[3].time_s, [25.0 + 1.25, 25.0 + 3.75])


@need
def test_text_export_as_recording():
    rec = read_jpk_recording(TEXT)
    lines = TEXT.read_text().splitlines()
    k = float(next(line for line in lines if line.startswith("# springConstant:")).split(":")[1])
    assert rec.spring_constant_N_per_m == k
    assert [s.kind for s in rec.segments] == ["approach", "pause", "retract"]
    assert [s.n_samples for s in rec.segments] == [1000, 2560, 200]
    np.testing.assert_allclose([s.duration_s for s in rec.segments], [0.5, 5.0, 0.1], rtol=1e-12)
    first = [float(v) for v in lines[86].split()]        # smoothedMeasuredHeight vDeflection ... seriesTime time
    assert rec.segments[0].force_nN[0] == pytest.approx(first[1] * 1e9, rel=1e-12)
    assert rec.segments[0].height_um[0] == pytest.approx(first[0] * 1e6, rel=1e-12)
    # JPK writes mid-sample times, as the binary reader computes them: t_i = (i + 1/2) T / n
    np.testing.assert_allclose(rec.segments[0].time_s, (np.arange(1000) + 0.5) * 0.5 / 1000, rtol=1e-6)
    np.testing.assert_allclose(rec.segments[1].time_s[0], 0.5 + 0.5 * 5.0 / 2560, rtol=1e-7)


@need
@pytest.mark.parametrize("path", [TEXT, BRAIN, JPKFILE], ids=lambda p: p.suffix)
def test_force_rises_as_the_height_falls_on_approach(path):
    """The sign convention of the cell height, h = z + F/k - Z: on approach the
    cantilever descends (z falls) while the force rises, and the deflection's
    correction F/k is far smaller than the descent, so h falls too."""
    rec = read_archive(path)[0] if path.suffix == ".jpk-force" else read_jpk_recording(path)
    app = rec.segments[0]
    assert app.kind == "approach"
    n = app.n_samples // 10
    dz = app.height_um[-n:].mean() - app.height_um[:n].mean()
    dF = app.force_nN[-n:].mean() - app.force_nN[:n].mean()
    assert dz < 0 < dF
    w = wedge_height_um(app, rec.spring_constant_N_per_m)
    assert w[-n:].mean() - w[:n].mean() < 0
    assert np.corrcoef(app.force_nN, app.height_um)[0, 1] < 0


@need
def test_import_json_summary_of_each_real_file(tmp_path, capsys):
    for i, path in enumerate([TEXT, BRAIN, JPKFILE]):
        capsys.readouterr()
        assert main(["afm", "import", str(path), "--volume", "4000", "--out", str(tmp_path / f"{i}"),
                     "--json"]) == 0
        obj, = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
        assert obj["cell_id"] == path.stem
        assert obj["spring_constant_N_per_m"] > 0
        for s in obj["segments"]:
            assert set(s) == {"kind", "duration_s", "n_samples", "frequency_hz", "amplitude_um"}
            assert s["kind"] in ("approach", "pause", "retract") and s["frequency_hz"] is None


@need
def test_analyze_lists_recordings_without_modulation(tmp_path, capsys):
    from analysis.calibration.law import Calibration
    from studies.synthetic import reference_law
    cal = tmp_path / "cal.json"
    Calibration({b: reference_law(b) for b in ("standard", "double", "none")}).save(
        cal, borrow=("emulator", "viscoelastic_table"))      # the shipped emulator and table, named
    capsys.readouterr()
    status = main(["afm", "analyze", str(DATA), "--volume", "4000", "--calibration", str(cal),
                   "--out", str(tmp_path / "out")])
    assert status == 1
    report = (tmp_path / "out" / "report.md").read_text()
    for path in (TEXT, BRAIN, JPKFILE):
        assert f"| {path.stem} | no modulation (oscillation) segment |" in report
