"""Viscosity and frequency as campaign grid axes (campaign/config.py), the
store's viscous columns, and `cortex analysis viscosity` on a small campaign."""

import subprocess

import numpy as np
import pytest

from campaign.config import load
from campaign.store.reader import read_results
from campaign.store.schema import task_id
from solver import viscous
from solver.model import Shell
from tests.conftest import BIN, ROOT

GRID = """[grid]
h0_um = 12.0
bulk_mN_per_m = 25.0
shear_mN_per_m = 8.33
tension_mN_per_m = 1.5
"""


def write(tmp_path, text):
    path = tmp_path / "c.toml"
    path.write_text(text)
    return path


def test_axes_multiply_the_grid_and_leave_elastic_ids_alone(tmp_path):
    elastic = load(write(tmp_path, GRID))
    both = load(write(tmp_path, GRID + "viscosity_Pa_s = [0.1, 1.0, 10.0]\nfrequency_hz = [1.0, 10.0]\n"))
    assert len(elastic.shells) == 1 and len(both.shells) == 6
    assert {(s.viscosity_Pa_s, s.frequency_hz) for s in both.shells} == {
        (e, f) for e in (0.1, 1.0, 10.0) for f in (1.0, 10.0)}
    # an elastic cell keeps the id it had before the viscous fields existed
    plain = Shell(volume_um3=4300.0, h0_um=12.0, bulk_mN_per_m=25.0, shear_mN_per_m=8.33,
                  tension_mN_per_m=1.5)
    assert "viscosity_Pa_s" not in plain.to_dict()
    assert task_id(elastic.shells[0], "fast") == task_id(plain, "fast")
    assert len({task_id(s, "fast") for s in both.shells}) == 6


@pytest.mark.parametrize("extra", ["viscosity_Pa_s = -1.0\nfrequency_hz = 1.0\n",
                                   "viscosity_Pa_s = 1.0\nfrequency_hz = 0.0\n",
                                   "viscosity_Pa_s = 1.0\n",
                                   "frequency_hz = [1.0, 10.0]\n"])
def test_bad_axes_one_line_exit_2(tmp_path, extra):
    path = write(tmp_path, GRID + extra)
    done = subprocess.run([str(BIN / "cortex"), "campaign", "run", str(path), "--store",
                           str(tmp_path / "s.h5")], capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert done.returncode == 2, done.stderr
    assert len(done.stderr.strip().splitlines()) == 1 and "Traceback" not in done.stderr
    assert not (tmp_path / "s.h5").exists()


def test_small_viscous_campaign_and_its_analysis(tmp_path):
    path = write(tmp_path, GRID + "viscosity_Pa_s = [0.01, 10.0]\nfrequency_hz = 10.0\n"
                 "[solver]\ntimeout_s = 900.0\n")
    store = tmp_path / "v.h5"
    done = subprocess.run([str(BIN / "cortex"), "campaign", "run", str(path), "--store", str(store)],
                          capture_output=True, text=True, cwd=ROOT, timeout=900)
    assert done.returncode == 0, done.stderr
    frame = read_results(store)
    assert list(frame["state"]) == ["done", "done"]
    lin = viscous.prepare(load(path).shells[0])[0]
    for row in frame.itertuples():
        K = viscous.respond(lin, row.viscosity_Pa_s, row.frequency_hz).complex_modulus
        assert row.modulus_mN_per_m == pytest.approx(abs(K), rel=1e-9)
        assert row.loss_angle_rad == pytest.approx(np.angle(K), rel=1e-9)
    out = tmp_path / "analysis"
    done = subprocess.run([str(BIN / "cortex"), "analysis", "viscosity", str(store), "--out", str(out)],
                          capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert done.returncode == 0, done.stderr
    assert (out / "viscosity.png").stat().st_size > 0
    report = (out / "viscosity.md").read_text()
    # 0.01 Pa s at 10 Hz changes |K*| by ~1e-5, 10 Pa s by far more than 1 %: the limit is 0.01
    assert "| 10 | 0.01 | 0.628 |" in report


def test_viscous_axes_and_montecarlo_trials_are_refused_together(tmp_path):
    from common.errors import InputError
    with pytest.raises(InputError, match="montecarlo"):
        load(write(tmp_path, GRID + "viscosity_Pa_s = 1.0\nfrequency_hz = 1.0\n[montecarlo]\nnu = [0.5]\n"))
