"""The tension-bias study's task kind (`studies.shell_reading_bias`, campaigns/tension-bias.toml):
one power-law ramp simulated in time and read as `cortex afm tension` reads it. An elastic cortex
(β = 0) reads γ_a within its interval; a power-law one (β = 0.3) reads it high, its interval
above the truth. Its table (`bias_table`, `markdown`) is the medians and coverage of the done rows."""

import math

import pytest

from campaign.kinds import find
from campaign.params_grid import ParamPoint
from solver.model import Shell

R = 6.8
CELL = Shell(volume_um3=4.0 * math.pi * R ** 3 / 3.0, h0_um=2.0 * R - 0.01, dh_um=1.4, bulk_mN_per_m=25.0,
             shear_mN_per_m=8.33, tension_mN_per_m=0.5)


def _task(beta):
    kind = find("studies.shell_reading_bias:shell_reading_bias")
    assert set(kind.params) == {"beta", "speed_um_per_s", "seed"}
    out = kind.compute(ParamPoint(CELL, {"beta": beta, "speed_um_per_s": 1.0, "seed": 0.0}))
    assert set(kind.results) <= set(out) and all(math.isfinite(v) for v in out.values())
    return out


def test_an_elastic_cortex_reads_its_tension_within_the_interval():
    out = _task(0.0)
    assert out["tension_covered"] == 1.0
    assert out["tension_lo95_ratio"] <= 1.0 <= out["tension_hi95_ratio"]
    assert out["tension_ratio"] == pytest.approx(1.0, abs=0.15)
    assert out["bulk_read_mN_per_m"] == pytest.approx(25.0, rel=0.3)
    assert out["ramp_samples"] > 1000


def test_a_power_law_cortex_reads_its_tension_high():
    out = _task(0.3)
    assert out["tension_ratio"] > 1.3 and out["tension_lo95_ratio"] > 1.0
    assert out["tension_covered"] == 0.0
    assert out["droplet_tension_ratio"] > out["tension_ratio"]     # the tension-only reading, higher still


def test_the_table_is_the_medians_and_coverage_of_the_done_rows():
    import pandas as pd

    from studies.shell_reading_bias import bias_table, markdown
    rows = pd.DataFrame({"state": ["done", "done", "done", "failed", "done"],
                         "beta": [0.0, 0.0, 0.0, 0.0, 0.3], "speed_um_per_s": [1.0] * 5,
                         "tension_ratio": [0.9, 1.0, 1.3, 9.0, 2.0], "tension_covered": [1.0, 1.0, 0.0, 1.0, 0.0],
                         "bulk_read_mN_per_m": [20.0, 30.0, 40.0, 0.0, 50.0], "bulk_mN_per_m": [20.0] * 5,
                         "depth_moves": [0.0, 0.0, 1.0, 0.0, 1.0]})
    table = bias_table(rows)
    first = table.iloc[0]
    assert (first.beta, first.ramps, first.tension_ratio_median, first.tension_ratio_max) == (0.0, 3, 1.0, 1.3)
    assert first.coverage == pytest.approx(2 / 3) and first.bulk_ratio_median == 1.5
    assert markdown(table).splitlines()[2:] == ["| 0 | 1.00 (0.90-1.30), 67 % |", "| 0.3 | 2.00 (2.00-2.00), 0 % |"]
