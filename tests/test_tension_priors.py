"""`cortex afm tension` takes the shell's priors from the recording's own oscillations
(`analysis.afm.tension.priors`): a synthetic cell of known truth whose recording holds an approach
ramp onto its free sphere, made by the elastic shell (`studies.tension_synth.shell_ramp`), and the
oscillation segments of `afm synth` (power-law moduli, the emulator's forward model) of the same
cell; the ramp's K_B and K_S are the oscillations' laws at the ramp's time scale (`ramp_modulus`),
its K_S/K_B near 0.3, which one shallow ramp alone cannot tell from 2.5."""

import json

import numpy as np
import pytest

from analysis.afm.cell import Cell, Segment
from cortex.cli import main
from jpk_writer import write_force
from analysis.afm.rheology import modulus_1s
from analysis.afm.synth import cells as sy
from analysis.afm.synth.rheology import ViscoelasticForward, emulator_complex
from analysis.afm.tension.pipeline import Options, _trace, analyse
from analysis.afm.tension.priors import COLUMNS, _calibration, ramp_modulus
from solver.geometry import cell_radius
from studies.tension_synth import shell_ramp

SPEED = 1.0            # µm/s, the approach
SAMPLES = 1200
DEPTH = 0.05          # of R: a shallow ramp (the shared instrument files reach δ/R 0.03-0.07)


@pytest.fixture(scope="module")
def recording():
    """(cell with ramp, retract and oscillations; the same without oscillations; truth γ_a, K_B, K̃_S)."""
    forward = ViscoelasticForward(0.1, 0.2, emulator_complex(_calibration().viscoelastic), seed=3)
    [osc], truth = sy.generate(1, seed=3, errors=False, forward=forward)
    c = truth["cells"][0]
    radius, at_1hz = float(cell_radius(c["volume_um3"])), c["frequencies"][1.0]
    depth = DEPTH * radius
    time_s = depth / SPEED
    kb = float(ramp_modulus(modulus_1s(at_1hz["bulk_mN_per_m"], c["bulk_exponent"]), c["bulk_exponent"], time_s))
    ks = float(ramp_modulus(modulus_1s(at_1hz["shear_mN_per_m"], c["shear_exponent"]), c["shear_exponent"], time_s))
    x, f = shell_ramp(radius, c["tension_mN_per_m"], kb, ks, depth, n=SAMPLES, noise_nN=0.02, seed=4)
    t = (x[0] - x) / SPEED
    n = x.size
    ramp_only = Cell("c", c["volume_um3"], np.r_[t, t[-1] + t + t[1]], np.r_[f, f[::-1]], np.r_[x, x[::-1]],
                     [Segment("approach", 0, n), Segment("retract", n, 2 * n)], volume_source="synthetic",
                     spring_constant_N_per_m=0.1)
    t0 = ramp_only.time_s[-1] + 1.0
    segs = ramp_only.segments + [Segment(s.kind, s.start + 2 * n, s.stop + 2 * n, s.frequency_hz, s.amplitude_um)
                                 for s in osc.segments]
    both = Cell("c", c["volume_um3"], np.r_[ramp_only.time_s, t0 + osc.time_s], np.r_[ramp_only.force_nN, osc.force_nN],
                np.r_[ramp_only.height_um, osc.height_um], segs, volume_source="synthetic", spring_constant_N_per_m=0.1)
    return both, ramp_only, (c["tension_mN_per_m"], kb, ks / kb)


def _row(cell, **options):
    row, = analyse(_trace(cell), Options(**{"power_law": False, **options})).rows
    return row


def test_the_oscillations_narrow_the_tension_and_keep_the_truth(recording):
    both, _, (gamma, kb, shear) = recording
    on, off = _row(both), _row(both, oscillation_priors=False)
    assert on["prior_source"] == "oscillations" and on["prior_note"] == ""
    assert on["prior_bulk_modulus_mN_per_m"] == pytest.approx(kb, rel=0.05)        # the reading finds the truth's laws
    assert on["prior_shear_ratio"] == pytest.approx(shear, rel=0.1)
    assert on["prior_time_scale_s"] == pytest.approx(DEPTH * on["radius_um"] / SPEED, rel=0.1)   # contact_guess
    assert 0.0 < on["prior_bulk_exponent_sd"] < 0.05 and on["prior_bulk_modulus_sd_mN_per_m"] > 0
    width = lambda r: r["tension_hi95_mN_per_m"] - r["tension_lo95_mN_per_m"]    # noqa: E731
    assert width(on) < 0.8 * width(off), (width(on), width(off))         # 0.43 against 0.61 mN/m
    for r in (on, off):
        assert r["tension_lo95_mN_per_m"] <= gamma <= r["tension_hi95_mN_per_m"], (gamma, r["tension_lo95_mN_per_m"],
                                                                                  r["tension_hi95_mN_per_m"])
        assert r["bulk_modulus_lo95_mN_per_m"] <= kb <= r["bulk_modulus_hi95_mN_per_m"]
    assert on["shear_ratio_lo95"] <= shear <= on["shear_ratio_hi95"]


def test_without_oscillations_or_with_the_option_nothing_changes_but_the_columns_say_none(recording):
    both, ramp_only, _ = recording
    alone, off = _row(ramp_only), _row(both, oscillation_priors=False)
    for row, why in ((alone, "no oscillation segment in the recording"), (off, "--no-oscillation-priors")):
        assert row["prior_source"] == "none" and row["prior_note"] == why
        assert all(np.isnan(row[k]) for k in COLUMNS if k not in ("prior_source", "prior_note"))
    same = [k for k in alone if k not in ("prior_note", "segment")]
    assert {k: alone[k] for k in same} == pytest.approx({k: off[k] for k in same}, nan_ok=True)
    assert "prior_source" not in _row(ramp_only, model="droplet")      # tension-only readings take no priors



def test_a_jpk_archive_with_modulations_and_the_option_that_switches_them_off(recording, tmp_path, capsys):
    """The same recording as a JPK archive read without a dish reference (the oscillations' gaps from
    the ramp's contact point): the same priors; `--no-oscillation-priors` says none."""
    both, _, _ = recording
    path = write_force(tmp_path / "c.jpk-force", both, dish_um=20.0)
    rows = {}
    for flag in (["--out", str(tmp_path / "out")], ["--no-oscillation-priors"]):
        assert main(["afm", "tension", str(path), "--volume", str(both.volume_um3), "--json", "--no-power-law", *flag]) == 0
        rows[flag[0] != "--out"], = json.loads(capsys.readouterr().out)["rows"]
    import pandas as pd
    assert pd.read_csv(tmp_path / "out" / "tension.csv")["prior_source"].tolist() == ["oscillations"]
    assert "| oscillations: K_B " in (tmp_path / "out" / "report.md").read_text()
    on, off = rows[False], rows[True]
    direct = _row(both)
    assert on["prior_source"] == "oscillations" and off["prior_source"] == "none"
    assert off["prior_note"] == "--no-oscillation-priors" and off["prior_bulk_modulus_mN_per_m"] is None
    for key in ("prior_bulk_modulus_mN_per_m", "prior_shear_ratio", "tension_mN_per_m"):
        assert on[key] == pytest.approx(direct[key], rel=0.02), key


def test_a_bundles_viscoelastic_table_reads_the_oscillations(recording, tmp_path):
    """A bundle naming a modified complex-modulus table (ln C + 0.5 δ_B) gives other priors than the
    shipped one, and the row names the bundle (`prior_calibration_source`); the shell ramp table,
    which it names unchanged, gives the same hash."""
    from analysis.afm.tension.calibration_parts import tension_calibration
    from analysis.calibration.file import RAMP_TABLE_NAME, TABLE_NAME, load_calibration
    from bundles import bundle_copy, shipped_part
    both, _, _ = recording
    doc = shipped_part(TABLE_NAME)
    ln_c = np.asarray(doc["ln_c_real"], float)
    ln_c[..., [tuple(t) for t in doc["terms"]].index((1, 0))] += 0.5
    doc["ln_c_real"] = ln_c.tolist()
    mine = _row(both, calibration=tension_calibration(load_calibration(bundle_copy(tmp_path, {TABLE_NAME: doc}))))
    shipped = _row(both)
    assert (mine["prior_calibration_source"], shipped["prior_calibration_source"]) == (
        str(tmp_path / "calibration.json"), "shipped")
    assert mine["prior_source"] == "oscillations"
    assert abs(mine["prior_bulk_modulus_mN_per_m"] / shipped["prior_bulk_modulus_mN_per_m"] - 1.0) > 0.01
    assert mine["shell_table_sha256"] == shipped["shell_table_sha256"]
    assert mine["shell_table_source"] == str(tmp_path / RAMP_TABLE_NAME)
