"""`cortex afm synth --time-domain`: a tiny experiment simulated in time, written in the native
format with its truth and read by `afm analyze`'s reader; `--history relaxed`; `--hold force`
with `--ramp-speed-um-per-s`; impossible values refused (status 2)."""

import json

import numpy as np
import pytest

from analysis.afm.formats.reader import open as open_cells
from analysis.afm.recorded_protocol import protocol_of
from analysis.afm.timeseries import segment_moduli
from conftest import first_heights
from cortex.cli import main


@pytest.fixture
def tiny(monkeypatch):
    """One cell (0.1, 1 and 10 Hz, as the published design's first subset), its first two mean
    heights."""
    first_heights(monkeypatch, 2)


def test_synth_time_domain_writes_an_experiment_with_its_truth(tiny, tmp_path, capsys):
    """The experiment holds per height an approach and 5-period oscillations at 100 Hz; the
    segment fit of a noiseless recording finds a mean tension above γ_a (a 5 s wait leaves
    part of the steps' stress: found 14-33 % above) and a loss angle between the bulk's and
    the shear's (found 0.12-0.21 rad, δ_B 0.11, δ_S 0.44-0.51); truth.json holds the
    exponents, the wait and the cost."""
    out = tmp_path / "exp"
    assert main(["afm", "synth", "--time-domain", "--cells", "1", "--wait-s", "5", "--no-errors",
                 "--out", str(out), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["n_cells"] == 1
    truth = json.loads((out / "truth.json").read_text())
    cell_truth = truth["cells"][0]
    assert truth["time_domain"]["wait_s"] == 5.0 and truth["viscoelastic"]["bulk_exponent_median"] == 0.1
    assert abs(cell_truth["bulk_exponent"] - 0.1) < 0.15 and abs(cell_truth["shear_exponent"] - 0.3) < 0.15
    assert truth["time_domain"]["cost"][0]["steps"] > 2 * 5 * 64
    (cell,) = open_cells([str(out / "experiment.h5")])
    kinds = [(s.kind, s.frequency_hz if s.kind == "oscillation" else None) for s in cell.segments]
    assert kinds == [("approach", None), ("oscillation", 0.1), ("oscillation", 1.0), ("oscillation", 10.0)] * 2
    assert [s.stop - s.start for s in cell.segments if s.kind == "oscillation"] == [5000, 500, 50] * 2
    for row in segment_moduli(cell):
        f = cell_truth["frequencies"][str(row["frequency_hz"])]
        assert 1.0 < row["tension_mN_per_m"] / cell_truth["tension_mN_per_m"] < 1.5
        assert f["bulk_loss_angle_rad"] < row["loss_angle_rad"] < f["shear_loss_angle_rad"]
    assert np.all(np.diff(cell.time_s) > 0)
    ages = protocol_of(cell).ages_s()                   # the wait read back off the recording
    assert ages[0] == pytest.approx(5.0, abs=1.0) and ages[3] == pytest.approx(5.0, abs=1.0)
    assert np.allclose(np.diff(ages[:3]), [50.0, 5.0], atol=0.05)   # then 5 periods at 0.1 and 1 Hz


def test_synth_time_domain_relaxed_history_keeps_no_stress_from_the_first_height(tiny, tmp_path):
    """--history relaxed: the second height starts from its own relaxed droplet, so its segments'
    mean tension is that of the first height (found within 0.4 % at 0.1, 1 and 10 Hz; with the
    history carried it rises 12 % there: 1.39 -> 1.56 mN/m at 0.1 Hz, γ_a 1.17); truth.json says
    which history."""
    out = tmp_path / "exp"
    assert main(["afm", "synth", "--time-domain", "--cells", "1", "--wait-s", "5", "--no-errors",
                 "--history", "relaxed", "--out", str(out), "--json"]) == 0
    assert json.loads((out / "truth.json").read_text())["time_domain"]["history"] == "relaxed"
    (cell,) = open_cells([str(out / "experiment.h5")])
    first, second = np.split(np.array([row["tension_mN_per_m"] for row in segment_moduli(cell)]), 2)
    assert np.allclose(second, first, rtol=0.01)


def test_synth_time_domain_holds_the_force_after_fast_ramps(tiny, tmp_path):
    """--hold force --ramp-speed-um-per-s 1: each approach is the ramp at 1 µm/s (the first one
    step long) and a 5 s hold at the force the ramp reached, the plate creeping down as the
    cortex relaxes (found 0.01-0.03 µm); truth.json says both."""
    out = tmp_path / "exp"
    assert main(["afm", "synth", "--time-domain", "--cells", "1", "--wait-s", "5", "--no-errors", "--hold", "force",
                 "--ramp-speed-um-per-s", "1", "--out", str(out), "--json"]) == 0
    truth = json.loads((out / "truth.json").read_text())
    assert (truth["time_domain"]["hold"], truth["time_domain"]["ramp_speed_um_per_s"]) == ("force", 1.0)
    cell_truth = truth["cells"][0]
    (cell,) = open_cells([str(out / "experiment.h5")])
    first = cell.segments[0]
    assert cell.time_s[first.stop - 1] == pytest.approx(cell_truth["step_um"] / 1.0 + 5.0, abs=1e-9)
    for a in (s for s in cell.segments if s.kind == "approach"):
        hold = slice(a.stop - 4, a.stop)                   # the hold's last samples, 1 s apart
        assert np.allclose(cell.force_nN[hold], cell.force_nN[a.stop - 1], rtol=1e-6)
        assert np.all(np.diff(cell.height_um[hold]) < 0)


def test_synth_time_domain_short_memory_forgets_the_steps(tiny, tmp_path):
    """--memory-s 1: the cortex forgets each step's stress within the 5 s wait (e^-5), so every
    segment's mean tension is γ_a's (found within 1 %; the pure power law keeps 14-33 % above
    it, the test above); truth.json holds τ_c."""
    out = tmp_path / "exp"
    assert main(["afm", "synth", "--time-domain", "--cells", "1", "--wait-s", "5", "--no-errors",
                 "--memory-s", "1", "--out", str(out), "--json"]) == 0
    truth = json.loads((out / "truth.json").read_text())
    assert truth["time_domain"]["memory_s"] == 1.0
    (cell,) = open_cells([str(out / "experiment.h5")])
    tension = np.array([row["tension_mN_per_m"] for row in segment_moduli(cell)])
    assert np.allclose(tension, truth["cells"][0]["tension_mN_per_m"], rtol=0.03)


@pytest.mark.parametrize("args, message", [
    (["--memory-s", "0"], "--memory-s"),
    (["--memory-s", "nan"], "--memory-s"),
    (["--bulk-exponent", "0.7"], "must be in"),
    (["--ramp-speed-um-per-s", "0"], "--ramp-speed-um-per-s"),
    (["--hold", "position"], "--hold"),
    (["--wait-s", "-1"], "--wait-s"),
    (["--solver", "law"], "fast solver"),
    (["--jobs", "0"], "--jobs"),
    (["--history", "forgotten"], "--history"),
])
def test_impossible_time_domain_settings_are_refused(args, message, tmp_path, capsys):
    assert main(["afm", "synth", "--time-domain", "--cells", "1", "--out", str(tmp_path / "x"), *args]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err and not (tmp_path / "x" / "experiment.h5").exists()


@pytest.mark.parametrize("args", [["--wait-s", "5"], ["--history", "relaxed"], ["--hold", "force"],
                                  ["--ramp-speed-um-per-s", "1"], ["--memory-s", "5"], ["--jobs", "2"]])
def test_time_domain_options_without_time_domain_are_refused(args, tmp_path, capsys):
    assert main(["afm", "synth", "--cells", "1", *args, "--out", str(tmp_path / "x")]) == 2
    assert "--time-domain" in capsys.readouterr().err
