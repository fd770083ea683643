"""The shell ramp table as a campaign (`[campaign] task = "analysis.afm.tension.shell_table:ramp_table"`): a
small sub-grid run on 1 and 2 ranks, the table built from the store
(`cortex analysis build-ramp-table`) against the nodes computed directly
(`shell_table.unit_forces`), its refusals, and the shipped campaign file's grid
being the table's."""

import json

import h5py
import numpy as np
import pytest

from analysis.afm.tension.shell_table import DEPTHS, GAMMAS, RADII_UM, SHEARS
from campaign.config import load
from campaign.store.reader import read_results
from analysis.afm.tension.shell_table import RAMP_RESULTS
from analysis.calibration.viscoelastic_table import TABLE_RESULTS
from tests.conftest import ROOT, in_one_thread, on_one_and_two_ranks

VOLUMES = [float(4.0 * np.pi * r ** 3 / 3.0) for r in RADII_UM[[0, 3]]]
SUBGRID = f"""[campaign]
task = "analysis.afm.tension.shell_table:ramp_table"

[grid]
volume_um3 = {VOLUMES!r}
h_tilde = 0.5
bulk_mN_per_m = 10.0
ks_tilde = {float(SHEARS[4])!r}
gamma_tilde = [{float(GAMMAS[0])!r}, {float(GAMMAS[8])!r}]

[solver]
resolution = 2.0
"""
NODES = [(float(g), float(SHEARS[4]), float(r)) for g in GAMMAS[[0, 8]] for r in RADII_UM[[0, 3]]]


def write(tmp_path, text, name="c.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def one_process(nodes):
    """`unit_forces` at `nodes` (γ̃_a, K̃_S, R) in a fresh process on one BLAS thread, as a rank computes."""
    code = ("import json, sys; from analysis.afm.tension.shell_table import unit_forces as f; "
            "print(json.dumps([f(g, s, radius_um=r).tolist() for g, s, r in json.loads(sys.argv[1])]))")
    return np.array(in_one_thread(code, json.dumps(nodes)))


@pytest.fixture(scope="module")
def stores(tmp_path_factory):
    """The sub-grid run on 1 rank and on 2 ranks: {ranks: store}."""
    tmp = tmp_path_factory.mktemp("ramp")
    return on_one_and_two_ranks(tmp, write(tmp, SUBGRID), "ramp")


def test_rows_hold_the_forces_whatever_the_ranks(stores):
    one, two = (read_results(stores[r]) for r in (1, 2))
    assert list(one["state"]) == ["done"] * len(NODES) and len(RAMP_RESULTS) == DEPTHS.size + 1
    assert one["force_nN"].isna().all() and (one["wall_s"] > 0).all()     # a node, not a compression
    np.testing.assert_array_equal(one[list(RAMP_RESULTS)].to_numpy(), two[list(RAMP_RESULTS)].to_numpy())
    assert (two["rank"] > 0).any()
    with h5py.File(stores[1], "r") as f:          # its task's columns, not the viscoelastic table's
        assert set(RAMP_RESULTS) <= set(f) and not set(TABLE_RESULTS) & set(f)


def test_table_from_the_store_is_the_nodes_computed_directly(stores, tmp_path, cortex):
    out = tmp_path / "table"
    done = cortex("analysis", "build-ramp-table", stores[2], "--out", out, "--json")
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout)["nodes"] == len(NODES)
    doc = json.loads((out / "shell_ramp_table.json").read_text())
    assert doc["radius_um"] == RADII_UM[[0, 3]].tolist() and doc["depth_over_radius"] == DEPTHS.tolist()
    assert doc["gamma_tilde"] == GAMMAS[[0, 8]].tolist() and doc["shear_tilde"] == [float(SHEARS[4])]
    f = np.array(doc["force_over_kb_r"])                    # [depth][gamma][shear][radius]
    direct = one_process(NODES).reshape(2, 2, DEPTHS.size)  # [gamma][radius][depth]
    assert doc["filled"] == 0 and np.isfinite(direct).all()
    np.testing.assert_array_equal(f[:, :, 0, :], direct.transpose(2, 0, 1))
    # physics: the force grows with depth and with the active tension
    assert (np.diff(f, axis=0) > 0).all() and (f[:, 1] > f[:, 0]).all()


def test_unfinished_or_foreign_store_is_refused(tmp_path, cortex):
    elastic = tmp_path / "e.h5"
    text = SUBGRID.replace('task = "analysis.afm.tension.shell_table:ramp_table"', "").replace(f"{VOLUMES!r}", "4300.0")
    text = text.replace(f"[{float(GAMMAS[0])!r}, {float(GAMMAS[8])!r}]", "0.1")
    assert cortex("campaign", "run", write(tmp_path, text, "e.toml"), "--store", elastic, "--quiet").returncode == 0
    with h5py.File(elastic, "r") as f:          # a compression store keeps its layout: no table columns
        assert "force_nN" in f and not set(RAMP_RESULTS) & set(f)
    done = cortex("analysis", "build-ramp-table", elastic, "--out", tmp_path / "t")
    assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1
    assert "not a store of a ramp-table campaign" in done.stderr and not (tmp_path / "t").exists()
    failed = tmp_path / "f.h5"        # every node out of time: failed, the table refused
    path = write(tmp_path, SUBGRID + "timeout_s = 0.001\n", "f.toml")
    assert cortex("campaign", "run", path, "--store", failed, "--quiet").returncode == 1
    done = cortex("analysis", "build-ramp-table", failed, "--out", tmp_path / "t")
    assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1
    assert "4 of 4 nodes not done" in done.stderr, done.stderr


def test_the_campaign_file_is_the_tables_grid():
    campaign = load(ROOT / "campaigns" / "ramp.toml")
    assert campaign.task == "ramp_table" and len(campaign.shells) == RADII_UM.size * GAMMAS.size * SHEARS.size
    radii = {round(float(np.cbrt(3.0 * s.volume_um3 / (4.0 * np.pi))), 9) for s in campaign.shells}
    np.testing.assert_allclose(sorted(radii), RADII_UM, rtol=1e-9)     # to the rounding that merges equal radii
    assert {s.tension_mN_per_m for s in campaign.shells} == set((GAMMAS * 10.0).tolist())
    assert {s.shear_mN_per_m for s in campaign.shells} == set((SHEARS * 10.0).tolist())
    assert {s.bending for s in campaign.shells} == {"standard"}


def test_a_stalled_depth_is_filled_from_its_node_along_depth(stores):
    """`fill`: depths knocked out of a solved node come back within 2 % (the elastic
    share, linear between its solved neighbours: 1.3 % near the sphere, 0.2 % further
    on); the solved ones stay exactly as they were."""
    from analysis.afm.tension.shell_table import fill
    row = read_results(stores[1]).iloc[-1]
    f = row[list(RAMP_RESULTS[:-1])].to_numpy(float)
    holes = f.copy()
    holes[[5, 20, 21, 40]] = np.nan
    filled, count = fill(holes, row["tension_mN_per_m"] / row["bulk_mN_per_m"])
    assert count == 4 and np.array_equal(filled[np.isfinite(holes)], f[np.isfinite(holes)])
    np.testing.assert_allclose(filled, f, rtol=2e-2)
    np.testing.assert_allclose(filled[20:22], f[20:22], rtol=3e-3)
    assert fill(f, 0.1)[1] == 0 and fill(f, 0.1)[0] is f
