"""The viscoelastic table as a campaign (`[campaign] task = "analysis.calibration.viscoelastic_table:viscoelastic_table"`):
its file's checks, a small sub-grid run on 1 and 2 ranks, and the table built
from the store (`cortex analysis build-viscoelastic-table`) against the
one-process node computation and the solver itself."""

import json

import h5py
import numpy as np
import pytest

from analysis.calibration.viscoelastic_table import ANGLES, TERMS
from campaign.config import load
from campaign.store.reader import read_results
from analysis.calibration.viscoelastic_table import TABLE_RESULTS
from tests.conftest import in_one_thread, on_one_and_two_ranks

SUBGRID = """[campaign]
task = "analysis.calibration.viscoelastic_table:viscoelastic_table"

[grid]
volume_um3 = [3000.0, 6500.0]
h_tilde = [0.43, 0.835]
bulk_mN_per_m = 25.0
ks_tilde = 5.12
gamma_tilde = 0.256
"""
NODES = [(v, h, 5.12, 0.256) for v in (3000.0, 6500.0) for h in (0.43, 0.835)]


def write(tmp_path, text, name="c.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def one_process(nodes):
    """`node_coefficients` at `nodes` in a fresh process on one BLAS thread, as a
    campaign rank computes (`cortex campaign run` sets OPENBLAS_NUM_THREADS=1)."""
    code = ("import json, sys; from analysis.calibration.viscoelastic_table import node_coefficients as f; "
            "c = [f(*n) for n in json.loads(sys.argv[1])]; "
            "print(json.dumps([[x.real for x in a] + [x.imag for x in a] for a in c]))")
    return np.array(in_one_thread(code, json.dumps(nodes)))


def test_the_task_is_checked_and_changes_the_fingerprint(tmp_path, cortex):
    table = load(write(tmp_path, SUBGRID))
    plain = load(write(tmp_path, SUBGRID.replace('task = "analysis.calibration.viscoelastic_table:viscoelastic_table"', ""), "p.toml"))
    assert table.task == "viscoelastic_table" and plain.task == "compression"
    assert len(table.shells) == len(NODES) and table.fingerprint != plain.fingerprint
    for old, new in (('task = "analysis.calibration.viscoelastic_table:viscoelastic_table"', 'task = "relax"'),
                     ("[grid]", '[solver]\nmethod = "explicit"\n[grid]'),
                     ("[grid]", "[grid]\nviscosity_Pa_s = 1.0\nfrequency_hz = 1.0")):
        path = write(tmp_path, SUBGRID.replace(old, new), "bad.toml")
        done = cortex("campaign", "run", path, "--store", tmp_path / "bad.h5")
        assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1, done.stderr
        assert "task" in done.stderr and not (tmp_path / "bad.h5").exists()


@pytest.fixture(scope="module")
def stores(tmp_path_factory):
    """The sub-grid run on 1 rank and on 2 ranks: {ranks: store}."""
    tmp = tmp_path_factory.mktemp("ve")
    return on_one_and_two_ranks(tmp, write(tmp, SUBGRID), "ve")


def test_rows_hold_the_coefficients_whatever_the_ranks(stores):
    one, two = (read_results(stores[r]) for r in (1, 2))
    assert list(one["state"]) == ["done"] * len(NODES)
    assert set(TABLE_RESULTS) <= set(one.columns) and len(TABLE_RESULTS) == 2 * len(TERMS)
    assert one["force_nN"].isna().all() and (one["wall_s"] > 0).all()     # a node, not a compression
    np.testing.assert_array_equal(one[list(TABLE_RESULTS)].to_numpy(), two[list(TABLE_RESULTS)].to_numpy())
    assert (two["rank"] > 0).any()


def test_table_from_the_store_is_the_one_process_table(stores, tmp_path, cortex):
    out = tmp_path / "table"
    done = cortex("analysis", "build-viscoelastic-table", stores[2], "--out", out, "--json")
    assert done.returncode == 0, done.stderr
    doc = json.loads((out / "viscoelastic_table.json").read_text())
    assert (doc["volume_um3"], doc["h_tilde"], doc["ks_tilde"]) == ([3000.0, 6500.0], [0.43, 0.835], [5.12])
    coef = np.concatenate([np.array(doc["ln_c_real"]), np.array(doc["ln_c_imag"])], axis=-1).reshape(-1, 28)
    np.testing.assert_allclose(coef, one_process(NODES), rtol=0, atol=1e-12)
    # the polynomial at a node against the solver's C at an angle pair of the fit's grid (fit error ~2e-5)
    from solver.model import Shell
    from solver.viscoelastic import correction, hessian_parts
    shell = load(write(tmp_path, SUBGRID)).shells[0]
    assert isinstance(shell, Shell)
    c = np.log(correction(hessian_parts(shell), ANGLES[3], ANGLES[6], 1.0))
    ln_c = (np.array(doc["ln_c_real"][0][0][0][0]) + 1j * np.array(doc["ln_c_imag"][0][0][0][0]))
    series = sum(a * ANGLES[3] ** i * ANGLES[6] ** j for a, (i, j) in zip(ln_c, TERMS))
    assert abs(series - c) < 1e-4 and abs(c) > 1e-2


def test_unfinished_or_foreign_store_is_refused_and_a_rerun_finishes_it(stores, tmp_path, cortex):
    elastic = tmp_path / "e.h5"
    text = SUBGRID.replace('task = "analysis.calibration.viscoelastic_table:viscoelastic_table"', "").replace("[0.43, 0.835]", "0.835")
    text = text.replace("[3000.0, 6500.0]", "4300.0")
    assert cortex("campaign", "run", write(tmp_path, text, "e.toml"), "--store", elastic, "--quiet").returncode == 0
    with h5py.File(elastic, "r") as f:          # a compression store keeps its layout: no table columns
        assert "force_nN" in f and not set(TABLE_RESULTS) & set(f)
    done = cortex("analysis", "build-viscoelastic-table", elastic, "--out", tmp_path / "t")
    assert done.returncode == 2 and "not a store of a viscoelastic-table campaign" in done.stderr
    assert not (tmp_path / "t").exists()
    failed = tmp_path / "f.h5"        # every node out of time: failed, the table refused
    path = write(tmp_path, SUBGRID + "[solver]\ntimeout_s = 0.001\n", "f.toml")
    assert cortex("campaign", "run", path, "--store", failed, "--quiet").returncode == 1
    done = cortex("analysis", "build-viscoelastic-table", failed, "--out", tmp_path / "t")
    assert done.returncode == 2 and "4 of 4 nodes not done" in done.stderr, done.stderr
    # the same store resumed with time enough: its failed nodes redone, the table as from a clean run
    done = cortex("campaign", "run", write(tmp_path, SUBGRID, "g.toml"), "--store", failed, "--retry-failed", "--quiet")
    assert done.returncode == 0, done.stderr
    np.testing.assert_array_equal(read_results(failed)[list(TABLE_RESULTS)].to_numpy(),
                                  read_results(stores[1])[list(TABLE_RESULTS)].to_numpy())
