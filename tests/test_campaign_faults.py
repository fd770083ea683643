"""The test-only knobs of a campaign's [test] section (tests/faults.py): the
task sleep is wall time without CPU and counts towards the task's timeout,
changes no number, and bad values are refused; the made-up law is the
analysis's reference law."""

import time

import pytest

import faults
from campaign import task_hooks
from campaign.tasks import compute
from common.errors import InputError
from solver.model import Shell

SHELL = Shell(volume_um3=4300.0, h0_um=12.0, bulk_mN_per_m=25.0, shear_mN_per_m=8.33, tension_mN_per_m=1.5)


def test_a_sleeping_task_takes_its_wall_time_without_cpu_and_gives_the_same_numbers():
    plain = compute(SHELL, "fast", 60.0, hooks=faults.Knobs(every_row="fake_law"))   # also warms up the geometry
    wall, cpu = time.monotonic(), time.process_time()
    slept = compute(SHELL, "fast", 60.0, hooks=faults.Knobs(every_row="fake_law", compression_sleep_s=0.3))
    wall, cpu = time.monotonic() - wall, time.process_time() - cpu
    assert slept[0] == plain[0] == "done"
    assert slept[1] == plain[1]                                 # the knob changes no number
    assert wall >= 0.3                                          # a sleep lasts at least that long
    assert cpu < 0.3 * wall                                     # ... and does not compute


def test_the_sleep_counts_towards_the_task_timeout():
    sleepy = faults.Knobs(every_row="fake_law", compression_sleep_s=600.0)
    state, results, error, _ = compute(SHELL, "fast", 0.2, hooks=sleepy)
    assert (state, results) == ("failed", {}) and error == "timed out after 0.2 s"


def test_fake_law_is_the_reference_law_of_the_analysis():
    """K of the fake compressions at three grid points is K_B (1 + α exp(h̃/λ))
    of studies.synthetic.reference_law('standard'), from the force it returns."""
    from analysis.calibration.law_fits import modulus_law
    from studies.synthetic import reference_law
    law = reference_law("standard")
    for shear, tension, h0 in ((8.33, 0.5, 15.0), (15.0, 1.5, 12.0), (25.0, 3.0, 11.0)):
        shell = Shell(volume_um3=4300.0, h0_um=h0, bulk_mN_per_m=25.0, shear_mN_per_m=shear,
                      tension_mN_per_m=tension)
        out = faults.fake_law(shell)
        alpha = law.alpha_of(shear / 25.0, tension / 25.0)
        expected = modulus_law(out["h_tilde"], 25.0, alpha, law.lam)
        assert out["modulus_mN_per_m"] == pytest.approx(expected, rel=1e-9)


@pytest.mark.parametrize("table, message", [
    ({"trial_sleep_s": -1.0}, "trial_sleep_s must be a number of seconds >= 0"),
    ({"compression_sleep_s": "long"}, "compression_sleep_s must be a number of seconds >= 0"),
    ({"compression_sleep_s": True}, "compression_sleep_s must be a number of seconds >= 0"),
    ({"trial_sleep_s": float("inf")}, "trial_sleep_s must be a number of seconds >= 0"),
    ({"raise_task": [7]}, "raise_task must be grid indices 0..3"),
    ({"noop": 1}, "noop must be true or false"),
])
def test_bad_knobs_are_refused_in_one_line(table, message):
    with pytest.raises(InputError) as err:
        faults.parse("c.toml", table, 4)
    assert message in str(err.value) and "\n" not in str(err.value)


def test_knobs_parse_into_what_the_scheduler_reads():
    knobs = faults.parse("c.toml", {"fake_law": True, "raise_task": [1], "trial_sleep_s": 0.5}, 3)
    assert [knobs.fault(row) for row in range(3)] == ["fake_law", "raise", "fake_law"]
    noop = faults.parse("c.toml", {"noop": True, "nan_task": 7}, 10**6)     # no entry per row of the grid
    assert (noop.fault(0), noop.fault(7), noop.fault(999_999), noop.by_row) == ("noop", "nan", "noop", {7: "nan"})
    assert faults.Knobs().fault(0) is None
    assert (knobs.compression_sleep_s, knobs.trial_sleep_s) == (0.0, 0.5)
    assert faults.parse("c.toml", {}, 3) == faults.Knobs()


def test_without_the_test_suite_a_test_section_is_refused_in_one_line(tmp_path):
    """The faults live in the test suite: the product alone (no CORTEX_TASK_HOOKS)
    refuses a campaign file with a [test] section, status 2, nothing written."""
    from conftest import cortex
    (tmp_path / "c.toml").write_text('[grid]\nh0_um = 12.0\nbulk_mN_per_m = 25.0\nshear_mN_per_m = 8.33\n'
                                     'tension_mN_per_m = 1.5\n[test]\nnoop = true\n')
    out = cortex("campaign", "run", tmp_path / "c.toml", "--store", tmp_path / "s.h5",
                 env={task_hooks.ENV: ""})
    assert out.returncode == 2 and not (tmp_path / "s.h5").exists()
    assert out.stderr.strip().count("\n") == 0 and "[test] is for the test suite only" in out.stderr
    assert cortex("campaign", "run", tmp_path / "c.toml", "--store", tmp_path / "s.h5").returncode == 0
