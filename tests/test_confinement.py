"""Whether a recording looks like plate confinement (`analysis.afm.confinement`): a plate
recording of a rounded cell passes; tip microrheology's cantilever, amplitude and frequency and a
free cell far from its volume's sphere each warn in one line; a recording that starts in contact
has no free-cell height to judge."""

import numpy as np
import pytest

from analysis.afm.cell import Cell, Segment
from analysis.afm.confinement import contact_height_um, warning
from solver.geometry import cell_radius

V = 4300.0                              # µm³: 2R = 20.2 µm


def _recording(free_um=19.5, k=0.5, amplitude_um=0.25, f=1.0, start_um=30.0):
    """An approach from start_um (force 0 until the plate meets the cell at free_um, then
    1 nN/µm) to 0.8 of free_um, then 5 periods at f of amplitude_um."""
    h_in = 0.8 * free_um
    ha = np.linspace(start_um, h_in, 200)
    fa = np.clip(free_um - ha, 0.0, None)
    ts = np.arange(0.0, 5 / f, 0.01 / f)
    h = np.concatenate([ha, h_in - amplitude_um * np.sin(2 * np.pi * f * ts)])
    t = np.concatenate([np.arange(200.0), 200.0 + ts])
    force = np.concatenate([fa, np.full(ts.size, fa[-1])])
    segs = [Segment("approach", 0, 200), Segment("oscillation", 200, t.size, f)]
    return Cell("c", V, t, force, h, segs, spring_constant_N_per_m=k)


def test_a_plate_recording_of_a_rounded_cell_does_not_warn():
    cell = _recording()
    assert contact_height_um(cell) == pytest.approx(19.5 - 0.05 * 0.2 * 19.5, abs=0.05)   # 5 % of the rise
    assert warning(cell) is None


@pytest.mark.parametrize("change, said", [
    ({"k": 0.01}, "spring constant 0.01 N/m < 0.05"),
    ({"amplitude_um": 0.02}, "oscillation amplitude 20 nm < 50"),
    ({"f": 200.0}, "frequency 200 Hz > 100"),
    ({"free_um": 6.0}, "free-cell height 5.9"),
    ({"free_um": 29.0, "start_um": 45.0}, "free-cell height 28."),
])
def test_each_sign_of_tip_microrheology_warns_in_one_line(change, said):
    line = warning(_recording(**change))
    assert line is not None and "\n" not in line and said in line and "plate confinement" in line


def test_a_recording_that_starts_in_contact_has_no_free_height():
    cell = _recording(start_um=16.0)                        # already 3.5 µm into the cell
    assert np.isnan(contact_height_um(cell)) and warning(cell) is None
    assert 2 * float(cell_radius(V)) == pytest.approx(20.2, abs=0.05)
