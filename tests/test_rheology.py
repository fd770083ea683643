"""The viscoelastic reading of AFM recordings (SPEC 10): round trip through the solver's
complex forward model, the instrument phase, the paired test, the command's outputs."""

import numpy as np
import pandas as pd
import pytest

from analysis.afm import rheology
from analysis.afm.analyze import analyze_cells
from analysis.invert.method import choose
from analysis.afm.cell import Cell, Segment
from analysis.afm.synth.cells import generate
from analysis.afm.synth.rheology import ViscoelasticForward, solver_complex
from analysis.invert.measurement_errors import MeasurementErrors
from analysis.calibration.file import load_calibration
from conftest import cortex
from common.errors import InputError


@pytest.fixture(scope="module")
def solver_round_trip():
    """Three cells (two at 0.1, 1 and 10 Hz, one at 0.02 Hz only) made by the solver's complex
    response (K_sec from the compression, C from the linear response), errors off."""
    cells, truth = generate(3, seed=4, errors=False,
                            forward=ViscoelasticForward(0.1, 0.3, solver_complex(), seed=4))
    model = load_calibration(None).viscoelastic
    table, segs = analyze_cells(cells, choose("emulator", None, model.emulator), "standard", MeasurementErrors(draws=20))
    return truth, rheology.analyze(table, segs, model, "standard", MeasurementErrors(draws=20))


def test_round_trip_through_the_solver_recovers_exponents_and_loss_angles(solver_round_trip):
    truth, (table, rheo, summ) = solver_round_trip
    cells = {c["cell_id"]: c for c in truth["cells"]}
    assert len(rheo) == 2
    for _, r in rheo.iterrows():
        for name in ("bulk", "shear"):
            assert abs(r[f"{name}_exponent"] - cells[r["cell_id"]][f"{name}_exponent"]) < 0.01
            assert r[f"{name}_exponent_lo95"] <= r[f"{name}_exponent"] <= r[f"{name}_exponent_hi95"]
    fitted = table[table["bulk_loss_angle_rad"].notna()]
    assert len(fitted) >= 6
    for _, r in fitted.iterrows():
        true = cells[r["cell_id"]]["frequencies"][r["frequency_hz"]]
        assert abs(r["bulk_loss_angle_rad"] - true["bulk_loss_angle_rad"]) < 0.01
        assert abs(r["shear_loss_angle_rad"] - true["shear_loss_angle_rad"]) < 0.01
        kb, ks = true["bulk_mN_per_m"], true["shear_mN_per_m"]
        assert r["viscoelastic_bulk_mN_per_m"] == pytest.approx(kb, rel=0.02)
        assert r["viscoelastic_shear_mN_per_m"] == pytest.approx(ks, rel=0.03)
    assert summ["instrument_phase"] == rheology.NO_LAG


def _dish(lag_rad, freqs=(1.0, 10.0)):
    """A bare-dish recording: the force follows the compression -h(t) late by `lag_rad`."""
    t_all, h_all, f_all, segs, n0 = [], [], [], [], 0
    for f in freqs:
        t = np.arange(0.0, 5.0 / f, 0.01 / f)
        w = 2 * np.pi * f
        h_all.append(5.0 - 0.25 * np.sin(w * t))
        f_all.append(40.0 + 30.0 * np.sin(w * t - lag_rad))
        t_all.append(t + (t_all[-1][-1] + 1.0 if t_all else 0.0))
        segs.append(Segment("oscillation", n0, n0 + t.size, f))
        n0 += t.size
    return Cell("dish", 1.0, np.concatenate(t_all), np.concatenate(f_all), np.concatenate(h_all), segs)


def test_instrument_lag_from_a_bare_dish_and_from_numbers():
    lags = rheology.reference_lags([_dish(0.2)])
    assert lags == pytest.approx({1.0: 0.2, 10.0: 0.2}, abs=1e-6)
    assert rheology.parse_lags("1=0.05, 10=0.3") == {1.0: 0.05, 10.0: 0.3}
    assert rheology.instrument_lags(None, [1.0]) == {1.0: 0.0}
    for bad in ("1:0.05", "x=1", "-1=0.1", ""):
        with pytest.raises(InputError):
            rheology.parse_lags(bad)
    with pytest.raises(InputError, match="no lag for 0.1 Hz"):
        rheology.instrument_lags({1.0: 0.1}, [0.1, 1.0])


def test_paired_test_sees_a_real_difference_and_not_a_null_one():
    rng = np.random.default_rng(0)
    b = 0.1 + 0.03 * rng.standard_normal(40)

    def frame(s):
        return pd.DataFrame({"bulk_exponent": b, "shear_exponent": s})
    yes = rheology.paired_test(frame(b + 0.2 + 0.03 * rng.standard_normal(40)))
    no = rheology.paired_test(frame(b + 0.03 * rng.standard_normal(40)))
    assert yes["shear_exponent_greater"] and yes["p_value_greater"] < 1e-6
    assert not no["shear_exponent_greater"] and no["p_value_two_sided"] > 0.05


def test_the_command_writes_rheology_and_no_phase_gives_todays_analysis(tmp_path):
    r = cortex("afm", "synth", "--cells", "4", "--seed", "2", "--no-errors", "--solver", "emulator",
               "--bulk-exponent", "0.1", "--shear-exponent", "0.3", "--out", tmp_path / "cells")
    assert r.returncode == 0, r.stderr
    on, off = tmp_path / "on", tmp_path / "off"
    assert cortex("afm", "analyze", tmp_path / "cells", "--out", on, "--draws", "20").returncode == 0
    assert cortex("afm", "analyze", tmp_path / "cells", "--out", off, "--draws", "20", "--no-phase").returncode == 0
    rheo = pd.read_csv(on / "rheology.csv")
    assert list(rheo.columns[:9]) == list(rheology.RHEOLOGY_COLUMNS) and len(rheo) >= 1
    assert not (off / "rheology.csv").exists()
    cells_on, cells_off = pd.read_csv(on / "cells.csv"), pd.read_csv(off / "cells.csv")
    assert {"bulk_loss_angle_rad", "shear_loss_angle_lo95_rad"} <= set(cells_on.columns)
    pd.testing.assert_frame_equal(cells_on[cells_off.columns], cells_off)
    assert "instrument phase: none given" in (on / "report.md").read_text().lower()
    bad = cortex("afm", "analyze", tmp_path / "cells", "--out", tmp_path / "x", "--phase-lag-rad", "1=0.1")
    assert bad.returncode == 2 and "no lag for" in bad.stderr
