"""The power-law ramp and hold table (`powerlaw_grid`, `powerlaw_tabled`): its nodes, the shipped
table against the simulator off its nodes, the fit that reads it without simulating, and the table
built by the campaign engine from a small sub-grid (`cortex analysis build-powerlaw-table`)."""

import json

import numpy as np
import pytest

from analysis.afm.tension import powerlaw_fit, powerlaw_simulated, powerlaw_tabled
from analysis.afm.tension.powerlaw_grid import HOLD_TAUS, RAMP_DEPTHS, node_curves
from analysis.afm.tension.powerlaw_simulated import START_UM, RampHold
from counting import counted
from studies.powerlaw_ramps import Cell, recording
from tests.conftest import cortex

OFF_NODES = Cell(radius_um=6.1, tension_mN_per_m=0.7, bulk_1s_mN_per_m=15.0, shear_tilde=0.6, beta=0.22,
                 speed_um_per_s=1.3, depth_um=0.16 * 6.1, hold_s=15.0)


def test_a_node_relaxes_from_its_ramps_end_and_not_without_memory():
    q0, r0 = node_curves(4.0, 0.05, 0.5, 0.0, 0.05)
    q3, r3 = node_curves(4.0, 0.05, 0.5, 0.3, 0.05)
    reach = RAMP_DEPTHS <= 0.05 - START_UM / 4.0           # e, from the stress-free start
    assert np.all(np.isnan(q3[~reach])) and np.all(q3[reach][1:] > 0)
    assert r3[0] == pytest.approx(1.0) and r3.max() < 1.005      # the contact line settles in the first step
    assert np.all(np.diff(r3[HOLD_TAUS >= 0.01]) < 0)
    assert r3[-1] < 0.4                                   # 150 ramp times on: the power law has shed most
    assert np.max(np.abs(r0 - 1.0)) < 0.02                # elastic: the hold keeps its force
    # K_eff is K_B at the age 1/ρ_0 (3.3 s); this ramp lasts 0.17 s, when the cortex is stiffer
    assert np.all(q3[reach][1:] > 1.5 * q0[reach][1:])


def test_the_shipped_table_is_the_simulator_off_its_nodes():
    """A cell between every axis's nodes, at a speed other than the table's (K_eff and R_b
    scaling), ramp and constant-height hold: within 1 % of its peak force."""
    made = recording(OFF_NODES)
    history = RampHold(made.time_s, made.x_um, made.ramp_samples)
    q = np.array([2 * OFF_NODES.radius_um, 0.7, 15.0, 0.22])
    sim = powerlaw_simulated.force_nN(history, q[0], OFF_NODES.radius_um, 0.7, 15.0, 0.22, 0.6)
    tab = powerlaw_tabled.TabledForce(history, OFF_NODES.radius_um, 0.6, powerlaw_tabled.resolve(None))(q)
    peak = np.max(np.abs(sim))
    assert np.max(np.abs(tab - sim)[:made.ramp_samples]) < 0.01 * peak
    assert np.max(np.abs(tab - sim)[made.ramp_samples:]) < 0.01 * peak
    assert np.max(np.abs(tab - sim)) > 1e-6 * peak       # two computations, not one


def test_a_recording_the_table_holds_is_read_with_one_simulation(monkeypatch):
    """The tabled fit, polished by POLISH_SIMULATIONS simulations (1), each counted."""
    made = recording(OFF_NODES, seed=3)
    calls = counted(monkeypatch, powerlaw_simulated, "simulated")
    fit = powerlaw_fit.fit_ramp_hold(made.time_s, made.x_um, made.force_nN, made.ramp_samples, 6.1, 0.6)
    lo, hi = fit.tension_interval_mN_per_m
    assert fit.tabled and fit.simulations == len(calls) == powerlaw_fit.POLISH_SIMULATIONS == 1
    assert lo <= 0.7 <= hi and hi - lo < 0.2 and abs(fit.beta - 0.22) < 0.03


def test_a_constant_force_hold_is_not_read_from_the_table():
    made = recording(OFF_NODES, seed=3)
    s, _ = powerlaw_fit.prepare(made.time_s, made.x_um, made.force_nN, made.ramp_samples, 6.1, "force")
    assert powerlaw_fit.tabled_fit(s, 6.1, 0.6, np.array([12.2, 0.7, 15.0, 0.22])) is None


SUBGRID = """[campaign]
task = "analysis.afm.tension.powerlaw_grid:powerlaw_table"

[grid]
volume_um3 = 268.082573106329
h_tilde = 0.5
bulk_mN_per_m = 10.0
ks_tilde = 0.5
gamma_tilde = [0.05, 0.2]

[params]
beta = 0.3
depth_over_radius = [0.03, 0.05]
"""


def test_the_campaign_builds_the_table_of_its_nodes(tmp_path):
    (tmp_path / "c.toml").write_text(SUBGRID)
    done = cortex("campaign", "run", tmp_path / "c.toml", "--store", tmp_path / "s.h5", "--quiet")
    assert done.returncode == 0, done.stderr
    built = cortex("analysis", "build-powerlaw-table", tmp_path / "s.h5", "--out", tmp_path / "t", "--json")
    assert built.returncode == 0, built.stderr
    assert json.loads(built.stdout)["nodes"] == 4 and json.loads(built.stdout)["failed"] == 0
    doc = json.loads((tmp_path / "t" / "powerlaw_table.json").read_text())
    q, r = np.array(doc["ramp_q"], dtype=float), np.array(doc["hold_ratio"], dtype=float)
    assert q.shape == (1, 2, 1, 1, RAMP_DEPTHS.size) and r.shape == (1, 2, 1, 1, 2, HOLD_TAUS.size)
    direct_q, direct_r = node_curves(4.0, 0.2, 0.5, 0.3, 0.05)
    assert np.allclose(r[0, 1, 0, 0, 1], direct_r, rtol=1e-5)
    reach = RAMP_DEPTHS <= 0.05 - START_UM / 4.0
    assert np.allclose(q[0, 1, 0, 0][reach], direct_q[reach], rtol=1e-5)
    again = cortex("analysis", "build-powerlaw-table", tmp_path / "c.toml", "--out", tmp_path / "u")
    assert again.returncode == 2 and len(again.stderr.strip().splitlines()) == 1


def test_a_bundles_powerlaw_table_replaces_the_shipped_one(tmp_path):
    """A bundle naming its own power-law table: the reading's tabled simulator reads that one, the
    row names its file and hash; a malformed one is refused in one line."""
    from analysis.afm.tension.calibration_parts import tension_calibration
    from analysis.calibration.file import POWERLAW_TABLE_NAME, load_calibration
    from common.errors import InputError
    from tests.bundles import bundle_copy, shipped_part
    doc = shipped_part(POWERLAW_TABLE_NAME)
    doc["ramp_q"] = (2.0 * np.array(doc["ramp_q"], dtype=float)).tolist()
    mine = tension_calibration(load_calibration(bundle_copy(tmp_path, {POWERLAW_TABLE_NAME: doc})))
    shipped = tension_calibration(None)
    assert np.allclose(mine.powerlaw.q, 2.0 * shipped.powerlaw.q, equal_nan=True)
    columns = mine.columns()
    assert columns["powerlaw_table_source"] == str(tmp_path / POWERLAW_TABLE_NAME)
    assert columns["powerlaw_table_sha256"] != shipped.columns()["powerlaw_table_sha256"]
    del doc["hold_ratio"]
    broken = tmp_path / "broken"
    broken.mkdir()
    with pytest.raises(InputError, match="not a power-law ramp and hold table"):
        tension_calibration(load_calibration(bundle_copy(broken, {POWERLAW_TABLE_NAME: doc})))
