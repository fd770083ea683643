"""AFM formats: the real JPK text export, HDF5 and CSV round trips."""

from pathlib import Path

import numpy as np
import pytest

from analysis.afm.formats.csvcell import read_csv_cell, write_csv_cell
from analysis.afm.formats.h5 import read_experiment, write_experiment
from analysis.afm.formats.jpk.text import read_jpk
from analysis.afm.synth.cells import generate, law_forward
from studies.synthetic import reference_law

JPK = Path(__file__).resolve().parents[1].parent / "shared/data/jpk/force-save-2020.10.29-12.06.06.196.txt"


def _segs(cell):
    return [(s.kind, s.start, s.stop, round(s.frequency_hz, 9) if s.kind == "oscillation" else None)
            for s in cell.segments]


@pytest.fixture(scope="module")
def cells():
    return generate(3, seed=4, errors=True, forward=law_forward(reference_law()))[0]


@pytest.mark.skipif(not JPK.is_file(), reason=f"real JPK export not found at {JPK} (shared test data)")
def test_jpk_real_export():
    e = read_jpk(JPK)
    assert [s.name for s in e.segments] == ["extend", "pause", "retract"]
    assert [len(s.data) for s in e.segments] == [1000, 2560, 200]
    for s in e.segments:
        assert s.spring_constant_N_per_m == pytest.approx(0.2998197975220132)
        assert s.sensitivity_m_per_V == pytest.approx(1.8452075817757116e-8)
        assert s.units["vDeflection"] == "N"
    first, last = e.segments[0].data.iloc[0], e.segments[2].data.iloc[-1]
    assert first["force_nN"] == pytest.approx(7.829442)          # 7.829442E-9 N
    assert first["height_um"] == pytest.approx(7.0950105)        # 7.0950105E-6 m
    assert first["time_s"] == pytest.approx(2.5e-4)
    assert last["force_nN"] == pytest.approx(7.751453)
    assert last["height_um"] == pytest.approx(6.79027)
    assert e.segments[1].data["series_time_s"].iloc[0] == pytest.approx(0.50097656)


def test_jpk_volts_converted_with_sensitivity_and_spring_constant(tmp_path):
    text = ("# segmentIndex: 0\n# segment: extend\n# columns: height vDeflection time\n# units: m V s\n"
            "# springConstant: 0.5\n# sensitivity: 2.0E-8\n# recorded-num-points: 2\n"
            "1.0E-5 0.1 0.0\n0.9E-5 0.2 0.01\n")
    p = tmp_path / "v.txt"
    p.write_text(text)
    d = read_jpk(p).segments[0].data
    np.testing.assert_allclose(d["force_nN"], [0.1 * 2e-8 * 0.5 * 1e9, 0.2 * 2e-8 * 0.5 * 1e9])
    np.testing.assert_allclose(d["height_um"], [10.0, 9.0])


def test_hdf5_round_trip(tmp_path, cells):
    write_experiment(tmp_path / "e.h5", cells)
    back = read_experiment(tmp_path / "e.h5")
    assert [c.cell_id for c in back] == [c.cell_id for c in cells]
    for a, b in zip(cells, back):
        np.testing.assert_array_equal(a.force_nN, b.force_nN)
        np.testing.assert_array_equal(a.height_um, b.height_um)
        assert _segs(a) == _segs(b) and a.volume_um3 == b.volume_um3


def test_csv_round_trip(tmp_path, cells):
    write_csv_cell(tmp_path / "c.csv", cells[0])
    b = read_csv_cell(tmp_path / "c.csv")
    np.testing.assert_allclose(b.force_nN, cells[0].force_nN, rtol=1e-12)
    assert _segs(b) == _segs(cells[0]) and b.volume_um3 == cells[0].volume_um3
