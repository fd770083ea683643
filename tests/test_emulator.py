"""The emulator (SPEC 9): the campaign grid's dimensionless axes, the shipped
calibration rebuilt in part from a fresh campaign, the interpolant against
off-grid solver runs, and the inversion by the emulator of noise-free solver
curves (K_B and K̃_S recovered; ν inside its 95 % interval), and the intervals of
cells whose heights are recorded with an offset (the truth still inside)."""

import subprocess

import numpy as np
import pandas as pd
import pytest

from analysis.afm.synth.cells import solver_forward
from analysis.calibration.emulator import AXES
from analysis.invert import intervals
from analysis.invert.emulator_fit import invert_curves_emulator
from analysis.invert.measurement_errors import MeasurementErrors
from analysis.invert.method import invert_rows
from analysis.calibration.file import TABLE_NAME, load_calibration, shipped_path
from campaign.config import load as load_campaign
from campaign.store.reader import read_results
from conftest import BIN, ROOT
from common.errors import InputError
from solver.geometry import cell_radius, droplet
from solver.modulus import effective_modulus

GRID = """
[campaign]
name = "part"
[grid]
volume_um3 = {volume}
h_tilde = {h}
dh_um = 0.5
bulk_mN_per_m = 25.0
ks_tilde = {ks}
gamma_tilde = {g}
bending = "{bending}"
"""


@pytest.fixture(scope="module")
def shipped():
    file = load_calibration()
    return file.calibration, file.emulator, file.provenance


def test_ratio_axes_give_the_absolute_grid(tmp_path):
    path = tmp_path / "c.toml"
    path.write_text(GRID.format(volume=3000.0, h=[0.5, 0.7], ks=[0.5], g=[0.04], bending="double"))
    shells = load_campaign(path).shells
    two_r = 2 * float(cell_radius(3000.0))
    assert [s.h0_um for s in shells] == pytest.approx([0.5 * two_r + 0.25, 0.7 * two_r + 0.25], rel=1e-14)
    assert {(s.shear_mN_per_m, s.tension_mN_per_m, s.bending) for s in shells} == {(12.5, 1.0, "double")}


@pytest.mark.parametrize("extra, message", [
    ("h0_um = [12.0]\n", "exactly one of h0_um and h_tilde"),
    ("[montecarlo]\nnu = [0.5]\n", "needs the absolute [grid] axes"),
])
def test_ratio_axes_refused_when_ambiguous(tmp_path, extra, message):
    text = GRID.format(volume=4300.0, h=[0.6], ks=[0.5], g=[0.04], bending="standard")
    text = text.replace("dh_um", extra + "dh_um") if extra.startswith("h0") else text + extra
    path = tmp_path / "c.toml"
    path.write_text(text)
    with pytest.raises(InputError, match=message.replace("[", r"\[").replace("]", r"\]")):
        load_campaign(path)


def test_shipped_file_has_both_parts_and_provenance(shipped):
    cal, emu, prov = shipped
    assert set(emu.tables) == set(cal.laws) == {"standard", "double", "none"}
    assert "[grid]" in prov["emulator"]["campaign_text"] and prov["emulator"]["code_version"]
    assert "[montecarlo]" in prov["law"]["campaign_text"] and prov["built"]["date"]
    box = emu.domain("standard")
    assert box["h_tilde"][0] <= 0.45 and box["h_tilde"][1] >= 0.82
    assert box["ks_tilde"][0] <= 0.05 and box["ks_tilde"][1] >= 5.0
    assert box["gamma_tilde"][0] <= 0.01 and box["gamma_tilde"][1] >= 0.25


def test_a_small_part_rebuilt_matches_the_shipped_table(tmp_path, shipped):
    """A fresh campaign over 2 x 2 x 2 of the grid's own points (V = 4300, standard
    bending) gives the shipped K/K_B to solver round-off."""
    table = shipped[1]["standard"]
    ax = table.axes
    pick = {"h_tilde": [1, 6], "ks_tilde": [2, 6], "gamma_tilde": [0, 4]}
    text = GRID.format(volume=4300.0, h=[ax["h_tilde"][i] for i in pick["h_tilde"]],
                       ks=[ax["ks_tilde"][i] for i in pick["ks_tilde"]],
                       g=[ax["gamma_tilde"][i] for i in pick["gamma_tilde"]], bending="standard")
    (tmp_path / "part.toml").write_text(text)
    run = subprocess.run([str(BIN / "cortex"), "campaign", "run", str(tmp_path / "part.toml"), "--store",
                          str(tmp_path / "part.h5"), "--quiet"], capture_output=True, text=True, cwd=ROOT,
                         timeout=300)
    assert run.returncode == 0, run.stderr
    res = read_results(tmp_path / "part.h5")
    assert (res["state"] == "done").all() and len(res) == 8
    iv = ax["volume_um3"].index(4300.0)
    for r in res.itertuples():
        i = [int(np.argmin(np.abs(np.asarray(ax[a]) - v))) for a, v in
             zip(AXES[1:], (r.h_tilde, r.shear_mN_per_m / 25.0, r.tension_mN_per_m / 25.0))]
        shipped_value = table.ratio[(iv, *i)]
        assert r.modulus_mN_per_m / 25.0 == pytest.approx(shipped_value, rel=1e-9)


@pytest.mark.parametrize("bending, h, ks, g, volume, bulk", [
    ("standard", 0.731, 0.21, 0.047, 5200.0, 18.0),
    ("double", 0.552, 3.3, 0.19, 3500.0, 33.0),
    ("none", 0.80, 0.066, 0.012, 6100.0, 25.0),
])
def test_interpolation_error_off_grid_is_below_0_2_percent(shipped, bending, h, ks, g, volume, bulk):
    from solver.compression import compress
    from solver.model import Shell
    emu = shipped[1]
    h0 = h * 2 * float(cell_radius(volume)) + 0.25
    K = compress(Shell(volume_um3=volume, h0_um=h0, dh_um=0.5, bulk_mN_per_m=bulk, shear_mN_per_m=ks * bulk,
                       tension_mN_per_m=g * bulk, bending=bending)).to_dict()["modulus_mN_per_m"]
    assert emu.inside(h, ks, g, volume, bending)
    assert float(emu.modulus(h, bulk, ks, g * bulk, volume, bending)) == pytest.approx(K, rel=0.002)


@pytest.fixture(scope="module")
def solver_curves():
    """Three noise-free cells from the solver: (rows, truth)."""
    forward = solver_forward("standard")
    heights_tilde = np.linspace(0.745, 0.5, 6)
    rows, truth = [], {}
    for cid, (ks, bulk, tension, volume) in {"a": (0.08, 20.0, 0.6, 3600.0), "b": (0.6, 31.0, 2.4, 5500.0),
                                             "c": (2.5, 24.0, 1.2, 4300.0)}.items():
        K = forward(volume, heights_tilde * 2 * float(cell_radius(volume)), bulk, ks * bulk, tension)
        truth[cid] = (ks, bulk)
        rows += [{"cell_id": cid, "h_tilde": h, "modulus_mN_per_m": k, "tension_mN_per_m": tension,
                  "volume_um3": volume} for h, k in zip(heights_tilde, K)]
    return pd.DataFrame(rows), truth


def test_emulator_inversion_recovers_solver_cells(shipped, solver_curves):
    rows, truth = solver_curves
    cal, emu, _ = shipped
    out = invert_rows(rows, "emulator", cal, emu, "standard", MeasurementErrors(draws=60)).set_index("cell_id")
    law = invert_rows(rows, "law", cal, emu, "standard").set_index("cell_id")
    for cid, (ks, bulk) in truth.items():
        nu = (1 - ks) / (1 + ks)
        r = out.loc[cid]
        assert r.excluded_reason is None or r.excluded_reason != r.excluded_reason  # None or NaN: included
        assert abs(r.nu - nu) <= 0.005 and r.bulk_mN_per_m == pytest.approx(bulk, rel=0.005)
        assert r.nu_lo95 < nu < r.nu_hi95 and r.ks_lo95 < ks < r.ks_hi95
        assert np.isnan(law.loc[cid, "nu_lo95"]) and np.isfinite(law.loc[cid, "nu"])
    # the law is off outside its grid (K_S/K_B = 0.08 is far below its 1/3): the emulator is not
    assert abs(law.loc["a", "nu"] - (1 - 0.08) / 1.08) > 5 * abs(out.loc["a", "nu"] - (1 - 0.08) / 1.08)


def test_intervals_widen_with_the_errors(shipped, solver_curves):
    rows, _ = solver_curves
    cal, emu, _ = shipped
    small = invert_rows(rows, "emulator", cal, emu, "standard", MeasurementErrors(volume_rel_sd=0.01, height_sd_um=0.05,
                                                                      draws=60))
    large = invert_rows(rows, "emulator", cal, emu, "standard", MeasurementErrors(draws=60))
    assert np.all((large["nu_hi95"] - large["nu_lo95"]) > 2 * (small["nu_hi95"] - small["nu_lo95"]))
    # the standard error of ln K̃_S is the same draws' RMS deviation from the fit: it widens alike, and
    # is at least the SD of a normal error with the percentile interval's width (the draws the protocol
    # admits are centred off the fit of a cell recorded at the window's top, h~ = 0.745)
    assert np.all(large["ln_ks_se"] > 2 * small["ln_ks_se"])
    ratio = 2 * 1.96 * large["ln_ks_se"] / np.log(large["ks_hi95"] / large["ks_lo95"])
    assert np.all((ratio > 0.85) & (ratio < 2.0)), ratio.to_numpy()


def _recorded_with_offset(emu, cid, ks, bulk, tension, offset_um, volume=4300.0, dh=0.5, top=0.73):
    """Rows of a noise-free cell (emulator moduli at its true heights, h~ from `top` down to 0.5)
    whose heights are recorded `offset_um` too high, read as the analysis reads them (SPEC 3): the
    force at the true gap, the resting force taken as a tension and K from both at the recorded gaps."""
    h_true = np.linspace(top, 0.5, 8) * 2 * float(cell_radius(volume))
    h_rec = h_true + offset_um
    K = emu.modulus(h_true / (2 * float(cell_radius(volume))), bulk, ks, tension, volume)
    d0, d1 = droplet(volume, h_true + dh / 2), droplet(volume, h_true - dh / 2)
    strain = (d1.surface_area_um2 - d0.surface_area_um2) / d0.surface_area_um2
    force = (tension + K * strain) * d1.force_per_tension_um
    seen = tension * d0.force_per_tension_um / droplet(volume, h_rec + dh / 2).force_per_tension_um
    em = effective_modulus(volume, h_rec + dh / 2, h_rec - dh / 2, seen, force)
    return [{"cell_id": cid, "h_tilde": a, "modulus_mN_per_m": k, "tension_mN_per_m": t, "volume_um3": volume}
            for a, k, t in zip(em["h_tilde"], em["modulus_mN_per_m"], seen)]


def test_intervals_hold_the_truth_of_cells_with_a_height_offset(shipped):
    """Heights recorded 0.8 µm (1.6 SD) too high or too low bias K̃_S by a factor ~2; the
    95 % interval (default errors) must still hold the true K̃_S and ν of every included
    cell whose protocol put its highest height at h~ = 0.73 (recorded at 0.77 and 0.69). (The
    basic bootstrap interval held none of the five recorded too high.)"""
    emu = shipped[1]
    cells = [(0.1, 20.0, 0.8), (0.3, 25.0, 1.5), (0.6, 30.0, 2.4), (1.5, 22.0, 1.0), (3.0, 28.0, 3.0)]
    rows, truth = [], {}
    for offset in (0.8, -0.8):
        for i, (ks, bulk, tension) in enumerate(cells):
            cid = f"{offset:+}-{i}"
            rows += _recorded_with_offset(emu, cid, ks, bulk, tension, offset)
            truth[cid] = ks
    out = invert_rows(pd.DataFrame(rows), "emulator", shipped[0], emu, "standard", MeasurementErrors()).set_index("cell_id")
    included = out[out["excluded_reason"].isna()]
    assert len(included) >= 8
    biased = [cid for cid in included.index if abs(np.log(included.loc[cid, "ks_tilde"] / truth[cid])) > 0.3]
    assert len(biased) >= 6                                   # the offset matters: the fits are off
    for cid, r in included.iterrows():
        ks = truth[cid]
        assert r.ks_lo95 <= ks <= r.ks_hi95 and r.nu_lo95 <= (1 - ks) / (1 + ks) <= r.nu_hi95, cid


def test_fit_at_the_bound_is_excluded(shipped):
    """A curve flatter than any tabulated K̃_S (K = K_B everywhere) is excluded, with ν reported."""
    emu = shipped[1]
    h = np.linspace(0.5, 0.745, 6)[None]
    out = invert_curves_emulator(h, np.full_like(h, 25.0), [1.0], [4300.0], emu)
    assert "limit of the fit" in out["excluded_reason"][0] and out["nu"][0] > 0.9


def test_shipped_files_are_inside_the_package():
    for path in (shipped_path(), shipped_path(TABLE_NAME)):
        assert path.is_file() and path.parent.parent.name == "calibration"
        assert path.parent.parent.parent.name == "analysis"


def test_the_draws_keep_the_truths_the_protocol_admits():
    """A cell recorded at h~ 0.72 down to 0.595 (R_cell 10 µm) and drawn truths whose heights lie
    -1, -0.5, 0, 0.5, 1 µm from the recorded ones: their highest h~ is 0.67, 0.695, 0.72, 0.745,
    0.77, and only those inside the published window (0.68, 0.75] are kept."""
    h = np.array([[0.72, 0.695, 0.67, 0.645, 0.62, 0.595]])
    radius = np.full((1, 1, 1), 10.0)
    heights = (h * 2 * 10.0)[:, None, :]
    h_true = heights + np.array([-1.0, -0.5, 0.0, 0.5, 1.0])[None, :, None]
    kept = intervals._in_window(h, np.ones_like(h), radius, np.full((1, 5, 1), 10.0), h_true, heights)
    assert kept.tolist() == [[False, True, True, True, False]]
    # and at least four heights in use at the truth: recorded at 0.745, 0.72, 0.695, 0.51, a truth 0.5 µm
    # lower has its last below 0.5 (0.485), only three in use
    h = np.array([[0.745, 0.72, 0.695, 0.51]])
    heights = (h * 2 * 10.0)[:, None, :]
    h_true = heights + np.array([0.0, -0.5])[None, :, None]
    kept = intervals._in_window(h, np.ones_like(h), radius, np.full((1, 2, 1), 10.0), h_true, heights)
    assert kept.tolist() == [[True, False]]
