"""The protocol's bias map as a campaign (`[campaign] task = "analysis.afm.synth.protocol_bias:protocol_bias"`, SPEC 12): a
two-node grid run on 1 and 2 ranks, the map built from the store (`cortex analysis
build-protocol-map`), its refusals, and the shipped campaign file's grid covering the issue's
ranges."""

import json

import numpy as np
import pytest

from campaign.config import load
from campaign.store.reader import read_results
from analysis.afm.synth.protocol_bias import PROTOCOL_RESULTS
from campaign.protocol_grid import PROTOCOL_PARAMS
from solver.protocol_simulation import FINE
from tests.conftest import ROOT, on_one_and_two_ranks

# V = 4300 µm³, h̃ = 0.6, K_B(1 s) = 25, K_S(1 s) = 8.33, γ_a = 1.5 mN/m; an elastic cortex and
# β_B = 0.1, β_S = 0.3; waited 30 s, oscillated at 1 Hz
SUBGRID = """[campaign]
task = "analysis.afm.synth.protocol_bias:protocol_bias"

[grid]
volume_um3 = 4300.0
h_tilde = 0.6
bulk_mN_per_m = 25.0
ks_tilde = 0.3332
gamma_tilde = 0.06
bending = "none"

[protocol]
exponents = [[0.0, 0.0], [0.1, 0.3]]
wait_s = 30.0
frequency_hz = 1.0
"""


def write(tmp_path, text, name="c.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def stores(tmp_path_factory):
    """The two nodes run on 1 rank and on 2 ranks: {ranks: store}."""
    tmp = tmp_path_factory.mktemp("protocol")
    return on_one_and_two_ranks(tmp, write(tmp, SUBGRID), "protocol")


def test_rows_hold_the_bias_whatever_the_ranks(stores):
    one, two = (read_results(stores[r]) for r in (1, 2))
    assert list(one["state"]) == ["done"] * 2 and (two["rank"] > 0).any()
    columns = list(PROTOCOL_PARAMS + tuple(PROTOCOL_RESULTS)) + ["modulus_mN_per_m", "loss_angle_rad", "gamma_eff_mN_per_m"]
    np.testing.assert_allclose(one[columns].to_numpy(), two[columns].to_numpy(), rtol=1e-9, atol=1e-12)
    assert one["bulk_exponent"].tolist() == [0.0, 0.1] and one["shear_exponent"].tolist() == [0.0, 0.3]
    assert (one["protocol_frequency_hz"] == 1.0).all() and one["frequency_hz"].isna().all()


def test_an_elastic_cortex_has_no_bias_and_a_power_law_its_loss_angles(stores):
    elastic, power = (row for _, row in read_results(stores[1]).iterrows())
    # β = 0: no loss anywhere; the oscillation's |K*| (the tangent about h_m) a little above the
    # model's secant K_sec of h0 -> h_m, the floor of the map (0.35-0.8 %, docs/studies/protocol-bias.md)
    assert elastic["model_loss_angle_rad"] == 0.0 and abs(elastic["loss_angle_rad"]) < 1e-4
    assert 1.0 < elastic["modulus_ratio"] < 1.01
    # the series' own loss angles are the power law's βπ/2 (to 0.03 rad at 1 Hz and β = 0.4, docs)
    assert power["bulk_loss_angle_rad"] == pytest.approx(0.05 * np.pi, abs=0.01)
    assert power["shear_loss_angle_rad"] == pytest.approx(0.15 * np.pi, abs=0.02)
    assert 0.157 < power["model_loss_angle_rad"] < 0.471             # between δ_B and δ_S
    assert power["modulus_ratio"] == pytest.approx(1.0, abs=0.02)
    assert abs(power["loss_angle_error_rad"]) < 0.01
    assert power["loss_angle_error_rad"] == pytest.approx(power["loss_angle_rad"] - power["model_loss_angle_rad"])
    # the step's unrelaxed stress shows in the mean tension, above γ_a = 1.5 mN/m
    assert 1.5 < power["gamma_eff_mN_per_m"] < 2.0
    assert power["solves"] > 5 * FINE.steps_per_period + 13        # the 5 cycles and the ramp, then the wait


def test_map_from_the_store_is_its_rows(stores, tmp_path, cortex):
    out = tmp_path / "map"
    done = cortex("analysis", "build-protocol-map", stores[2], "--out", out, "--json")
    assert done.returncode == 0, done.stderr
    said = json.loads(done.stdout)
    doc = json.loads((out / "protocol_map.json").read_text())
    rows = read_results(stores[2])
    assert doc["axes"]["exponents"] == [[0.0, 0.0], [0.1, 0.3]] and doc["axes"]["h_tilde"] == [0.6]
    assert doc["axes"]["ks_tilde"] == [0.3332] and doc["axes"]["gamma_tilde"] == [0.06]
    assert [n["modulus_ratio"] for n in doc["nodes"]] == rows["modulus_ratio"].tolist()
    s = doc["summary"]
    assert s == said["summary"] and s["nodes"] == 2
    assert s["largest_abs_loss_angle_error_rad"] == rows["loss_angle_error_rad"].abs().max()
    assert s["largest_abs_modulus_error"] == (rows["modulus_ratio"] - 1).abs().max()
    for name in ("protocol_map_loss_angle", "protocol_map_modulus"):
        assert (out / f"{name}.png").stat().st_size > 1000 and (out / f"{name}.pdf").is_file()


def _refused(done, text):
    assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1, done.stderr
    assert text in done.stderr, done.stderr


def test_unfinished_or_foreign_store_is_refused(tmp_path, cortex):
    elastic = tmp_path / "e.h5"
    text = SUBGRID.replace('task = "analysis.afm.synth.protocol_bias:protocol_bias"', "").split("[protocol]")[0]
    assert cortex("campaign", "run", write(tmp_path, text, "e.toml"), "--store", elastic, "--quiet").returncode == 0
    _refused(cortex("analysis", "build-protocol-map", elastic, "--out", tmp_path / "m"),
             "not a store of a protocol-bias campaign")
    assert not (tmp_path / "m").exists()
    failed = tmp_path / "f.h5"        # every node out of time: failed, the map refused
    path = write(tmp_path, SUBGRID + "\n[solver]\ntimeout_s = 0.001\n", "f.toml")
    assert cortex("campaign", "run", path, "--store", failed, "--quiet").returncode == 1
    _refused(cortex("analysis", "build-protocol-map", failed, "--out", tmp_path / "m"), "2 of 2 nodes not done")


@pytest.mark.parametrize("change, message", [
    (("exponents = [[0.0, 0.0], [0.1, 0.3]]", "exponents = [0.1, 0.3]"), "exponents must be a list of pairs"),
    (("exponents = [[0.0, 0.0], [0.1, 0.3]]", "exponents = [[0.1, 1.2]]"), "each in [0, 1)"),
    (("frequency_hz = 1.0", "frequency_hz = 0.0"), "frequency_hz must be a number > 0"),
    (("wait_s = 30.0\n", ""), "[protocol] needs wait_s"),
    (('task = "analysis.afm.synth.protocol_bias:protocol_bias"', ""), "a [protocol] section go together"),
])
def test_bad_protocol_section_is_one_line(tmp_path, cortex, change, message):
    path = write(tmp_path, SUBGRID.replace(*change))
    _refused(cortex("campaign", "run", path, "--store", tmp_path / "s.h5", "--quiet"), message)


def test_the_campaign_file_covers_the_issues_ranges():
    campaign = load(ROOT / "campaigns" / "protocol.toml")
    nodes = campaign.shells
    assert campaign.task == "protocol_bias" and len(nodes) == len(nodes.shells) * nodes.m
    betas = {b for node in nodes[:nodes.m] for b in (node.bulk_exponent, node.shear_exponent)}
    assert min(betas) == 0.0 and max(betas) == 0.4
    assert {n.wait_s for n in nodes[:nodes.m]} == {10.0, 30.0, 100.0, 300.0}
    assert {n.frequency_hz for n in nodes[:nodes.m]} == {0.02, 0.1, 1.0, 10.0}
    assert {n.shell.bending for n in nodes[::nodes.m]} == {"none"}
