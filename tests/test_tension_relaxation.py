"""A pause's force relaxation (analysis/afm/tension/relaxation.py) on pauses of
known truth: F_∞ + A φ(t) sampled at 1 kHz (as `synth` records) with 0.02 nN of
white noise; and through `cortex afm tension`, the relaxed force's tension,
the last half's for comparison and the flag of a pause too short to relax."""

import numpy as np
import pytest

from analysis.afm.formats.csvcell import write_csv_cell
from analysis.afm.formats.instruments import to_cell
from analysis.afm.tension.pause import pause_tension
from analysis.invert.measurement_errors import MeasurementErrors
from analysis.afm.tension.pipeline import Options, run
from analysis.afm.tension.relaxation import EXPONENTIAL, NONE, POWER, fit_relaxation, shape, time_to_s
from solver.geometry import cell_radius
from studies.tension_synth import RATE_HZ, droplet_force_nN, droplet_recording

F_INF, AMPLITUDE, NOISE = 4.0, 1.5, 0.02
T = np.arange(3000) / RATE_HZ                  # a 3 s pause at 1 kHz
CASES = {EXPONENTIAL: (0.4, float("nan")), POWER: (0.1, 1.0)}     # (τ s, β)
TOLERANCE_NN = 0.01                            # F_∞ within 0.25 % at this noise


def _pause(model, seed, t=T, tau_beta=None):
    tau, beta = tau_beta or CASES[model]
    rng = np.random.default_rng(seed)
    return F_INF + AMPLITUDE * shape(model, t, tau, beta) + NOISE * rng.standard_normal(t.size)


@pytest.mark.parametrize("model", (EXPONENTIAL, POWER))
def test_the_relaxed_force_the_model_and_the_interval_over_50_pauses(model):
    fits = [fit_relaxation(T + 7.0, _pause(model, seed)) for seed in range(50)]     # t since the pause's start
    assert all(r.model == model and r.flag == "" for r in fits)
    errors = np.array([r.relaxed_force_nN - F_INF for r in fits])
    assert np.max(np.abs(errors)) < TOLERANCE_NN
    covered = sum(r.relaxed_force_lo95_nN <= F_INF <= r.relaxed_force_hi95_nN for r in fits)
    assert covered >= 44                     # nominal 47.5 of 50; P(≤ 43) ≈ 1 % for a true 95 % interval
    tau, beta = CASES[model]
    times = np.array([r.time_s for r in fits])
    assert np.median(times) == pytest.approx(time_to_s(model, np.exp(-1.0), tau, beta), rel=0.05)
    assert all(r.bic_margin > 10 for r in fits)


def test_the_time_scales_are_where_the_relaxing_part_falls_to_1_over_e_and_10_percent():
    assert time_to_s(EXPONENTIAL, np.exp(-1.0), 0.4) == pytest.approx(0.4)
    for share in (np.exp(-1.0), 0.1):
        for model, (tau, beta) in CASES.items():
            assert shape(model, time_to_s(model, share, tau, beta), tau, beta) == pytest.approx(share)


def test_the_last_half_misses_a_slow_tail_that_the_fit_recovers():
    """A power-law cortex (β = 1): 4 % of A is still relaxing in the last half."""
    f = _pause(POWER, 1)
    r = fit_relaxation(T, f)
    assert np.mean(f[T.size // 2:]) - F_INF > 0.05          # 0.066 nN
    assert abs(r.relaxed_force_nN - F_INF) < TOLERANCE_NN


def test_a_flat_pause_has_no_relaxation():
    flat = F_INF + NOISE * np.random.default_rng(5).standard_normal(T.size)
    r = fit_relaxation(T, flat)
    assert r.model == NONE and r.flag == "" and np.isnan(r.time_s)
    assert r.relaxed_force_nN == pytest.approx(np.mean(flat))
    assert r.relaxed_force_lo95_nN < F_INF < r.relaxed_force_hi95_nN


def test_a_pause_too_short_to_relax_is_flagged():
    """τ = 2 s in a 1 s pause: 90 % of the relaxation would take 4.6 s."""
    t = T[:1000]
    r = fit_relaxation(t, _pause(EXPONENTIAL, 2, t, (2.0, float("nan"))))
    assert r.model == EXPONENTIAL and r.t90_s > r.pause_s
    assert r.flag.startswith("too short to relax") and "1 s pause" in r.flag
    # a power-law cortex with β = 0.3 never sheds 90 % in a pause
    slow = fit_relaxation(T, _pause(POWER, 3, T, (0.05, 0.3)))
    assert slow.model == POWER and slow.flag.startswith("too short to relax")
    # too few samples, and a relaxed force that is not positive
    assert fit_relaxation(T[:10], _pause(EXPONENTIAL, 4, T[:10])).flag.startswith("too few samples")
    below = fit_relaxation(T, _pause(EXPONENTIAL, 4) - 2.0 * F_INF)
    assert below.flag.startswith("relaxed force poorly determined")


def test_the_force_error_widens_the_tension_interval_as_it_should():
    volume, h = 4300.0, 12.0
    force = float(droplet_force_nN(volume, 1.0, np.array([h]))[0])
    exact = MeasurementErrors(volume_rel_sd=0.0, height_sd_um=0.0, draws=20000)
    p = pause_tension(force, h, volume, errors=exact, force_sd_nN=0.05 * force)
    assert (p.tension_lo95_mN_per_m, p.tension_hi95_mN_per_m) == pytest.approx((1 - 0.098, 1 + 0.098), abs=0.006)


VOLUME, TENSION = 3000.0, 0.8


def _cell(cell_id, tau_s, pause_n):
    depth = 2.0 * float(cell_radius(VOLUME)) * 0.3
    rec = droplet_recording(VOLUME, TENSION, depth, cell_id=cell_id, pause_n=pause_n, baseline_nN=1.0, seed=6,
                            pause_relaxation_nN=lambda t: 2.0 * shape(EXPONENTIAL, t, tau_s))
    return to_cell(rec, VOLUME, "synthetic")


def test_the_command_reads_the_relaxed_force_and_flags_a_short_pause(tmp_path):
    paths = [write_csv_cell(tmp_path / "relaxed.csv", _cell("relaxed", 0.5, 4000)),
             write_csv_cell(tmp_path / "short.csv", _cell("short", 1.5, 1000))]
    result = run(paths, Options(power_law=False), out=tmp_path / "out")
    pauses = {r["cell_id"]: r for r in result["rows"] if r["part"] == "pause"}
    ok, short = pauses["relaxed"], pauses["short"]
    assert ok["relaxation_model"] == EXPONENTIAL and ok["relaxation_flag"] == ""
    assert ok["relaxation_time_s"] == pytest.approx(0.5, rel=0.05)
    assert ok["tension_mN_per_m"] == pytest.approx(TENSION, rel=0.01)
    assert ok["tension_lo95_mN_per_m"] < TENSION < ok["tension_hi95_mN_per_m"]
    assert ok["force_nN"] == ok["relaxed_force_nN"]
    assert ok["last_half_tension_mN_per_m"] > ok["tension_mN_per_m"]   # the last half still holds e^-4 of A
    assert short["relaxation_flag"].startswith("too short to relax")
    assert short["last_half_tension_mN_per_m"] > 1.05 * TENSION         # what the last half alone would say
    report = result["report"].read_text()
    assert "Flagged pauses" in report and "short pause" in report and "too short to relax" in report
    import pandas as pd
    table = pd.read_csv(result["table"])
    assert {"relaxation_model", "relaxation_time_s", "relaxed_force_nN", "last_half_tension_mN_per_m"} <= set(table)


def test_a_relaxed_force_below_zero_gives_no_tension_but_the_last_half_for_comparison():
    """A pause (dish known, no ramp) whose last half pushes but whose relaxation heads below zero."""
    from analysis.afm.tension.pipeline import Trace, analyse
    t = T[:1000]
    f = -1.0 + 3.0 * shape(EXPONENTIAL, t, 2.0) + NOISE * np.random.default_rng(7).standard_normal(t.size)
    parts = [(0, "pause", t, f, np.full(t.size, 12.0))]
    row, = analyse(Trace("c", "synthetic", VOLUME, "known", parts, dish_known=True), Options()).rows
    assert row["relaxed_force_nN"] == pytest.approx(-1.0, abs=0.2) and np.isnan(row["tension_mN_per_m"])
    assert row["relaxation_flag"].startswith("too short to relax")
    assert row["last_half_force_nN"] > 0.9 and row["last_half_tension_mN_per_m"] > 0
