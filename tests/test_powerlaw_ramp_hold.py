"""The ramp-and-hold reading of the power-law shell (`analysis.afm.tension.powerlaw_fit`,
its surrogate `powerlaw_shell` and its simulated model `powerlaw_simulated`) against
closed forms and cells made by the time-domain shell (`studies.powerlaw_ramps`); the
40-cell check is `bench/powerlaw_ramp_hold.py`."""

import numpy as np
import numpy.typing as npt
import pytest

from analysis.afm.tension import powerlaw_shell, powerlaw_simulated, shell_ramp
from analysis.afm.tension.powerlaw_fit import fit_ramp_hold
from common.errors import InputError
from counting import counted
from studies.powerlaw_ramps import Cell, recording


def test_memory_matrix_integrates_the_power_law_exactly():
    """A strain ramped linearly from 0 to 1 over T and held: the stress Σ M ΔU is
    ∫_0^T (t - t')^-β dt'/T = [t^(1-β) - (t - T)^(1-β)] / ((1 - β) T) after it, and U at β = 0."""
    T, beta = 2.0, 0.25
    t = np.r_[np.linspace(0.0, T, 41), np.geomspace(T + 0.01, 30.0, 20)]
    u = np.clip(t / T, 0.0, 1.0)
    stress = powerlaw_shell.memory_matrix(t, beta) @ np.diff(u, prepend=u[0])
    after = t > T
    exact = (t[after] ** (1 - beta) - (t[after] - T) ** (1 - beta)) / ((1 - beta) * T)
    np.testing.assert_allclose(stress[after], exact, rtol=1e-12)
    assert stress[-1] == pytest.approx(30.0 ** -beta, rel=0.02)        # long after: K(t)
    np.testing.assert_allclose(powerlaw_shell.memory_matrix(t, 0.0) @ np.diff(u, prepend=u[0]), u, atol=1e-12)


def test_surrogate_is_the_elastic_shell_at_beta_zero_and_scales_with_speed():
    """β = 0: the elastic shell's force on any history; β > 0: a ramp at speed v depends on
    K_B(1 s) and v only through K_B(1 s) v^β."""
    R, gamma, bulk, shear = 6.8, 0.5, 25.0, 0.4
    depth = np.linspace(0.0, 1.0, 60)
    elastic = shell_ramp.force_nN(depth, R, gamma, bulk, shear)
    for v in (0.3, 3.0):
        got = powerlaw_shell.force_nN(depth / v, depth, R, gamma, bulk, 0.0, shear)
        np.testing.assert_allclose(got, elastic, rtol=1e-4, atol=1e-6)   # w(d) on 400 depths
    beta = 0.2
    slow = powerlaw_shell.elastic_force_nN(depth / 0.5, depth, R, bulk, beta, gamma / bulk, shear)
    fast = powerlaw_shell.elastic_force_nN(depth / 2.0, depth, R, bulk * 0.25 ** beta, beta, gamma / bulk, shear)
    np.testing.assert_allclose(fast, slow, rtol=1e-9, atol=1e-12)


def test_the_model_of_a_constant_force_hold_is_the_recording_at_the_truth():
    """A constant-force pause is modelled as held (the force the model's ramp reached kept, its
    plate creeping): at the cell's truth the model's force at the recorded gaps is the noise-free
    recording's on its pause, while a cortex that relaxes less (β 0.15), which creeps less, reads
    ever more above the recorded force the longer it holds (its gap short of the recorded creep)."""
    cell = Cell(6.0, 0.8, 10.0, 0.5, 0.25, 1.5, 0.14 * 6.0, hold_s=4.0, noise_nN=0.0, hold_kind="force")
    made = recording(cell)
    history = powerlaw_simulated.RampHold(made.time_s, made.x_um, made.ramp_samples, "force")
    at_truth = powerlaw_simulated.force_nN(history, 2 * cell.radius_um, cell.radius_um, cell.tension_mN_per_m,
                                           cell.bulk_1s_mN_per_m, cell.beta, cell.shear_tilde)
    pause = slice(made.ramp_samples, None)
    creep = made.x_um[made.ramp_samples - 1] - made.x_um[-1]
    assert creep > 0.05                                              # the plate crept
    assert np.ptp(made.force_nN[pause]) < 3e-6                      # at constant force: 1.3e-6 nN
    # (the gap's root where a step's label is settled once more: F(h) jumps by ~1e-6 nN there)
    np.testing.assert_allclose(at_truth[pause], made.force_nN[pause], atol=1e-3 * made.force_nN[-1])
    firmer = powerlaw_simulated.force_nN(history, 2 * cell.radius_um, cell.radius_um, cell.tension_mN_per_m,
                                         cell.bulk_1s_mN_per_m, 0.15, cell.shear_tilde)
    excess = firmer - made.force_nN
    assert excess[-1] > excess[made.ramp_samples] + 0.05 * made.force_nN[-1]


# cells of the bench's ranges: a constant-height hold, a constant-force hold, a ramp alone
CELLS = [Cell(6.5, 0.94, 7.9, 1.68, 0.17, 0.38, 0.14 * 6.5, hold_s=23.0, tilt_nN_per_um=0.05),
         Cell(8.2, 0.37, 5.5, 0.11, 0.26, 2.45, 0.14 * 8.2, hold_s=22.0, tilt_nN_per_um=0.1, hold_kind="force"),
         Cell(7.7, 1.72, 32.7, 0.10, 0.27, 0.32, 0.14 * 7.7, tilt_nN_per_um=0.12)]


@pytest.mark.slow
@pytest.mark.parametrize("cell", CELLS, ids=["height-hold", "force-hold", "ramp-alone"])
def test_power_law_cells_read_their_tension(cell):
    """Ramps (and holds, at constant height or force) made by the time-domain shell give back
    γ_a inside its interval, within 10 % with a hold and 20 % alone (a ramp alone tells γ_a
    from K_B(1 s) and β by its shape only: the bench's ramps alone read it to a median 13-16 %),
    and β within 0.05 with a hold."""
    made = recording(cell, seed=1)
    fit = fit_ramp_hold(made.time_s, made.x_um, made.force_nN, made.ramp_samples, cell.radius_um, cell.shear_tilde,
                        cell.hold_kind)
    lo, hi = fit.tension_interval_mN_per_m
    assert fit.tension_mN_per_m == pytest.approx(cell.tension_mN_per_m, rel=0.10 if cell.hold_s else 0.20)
    assert lo <= cell.tension_mN_per_m <= hi
    assert fit.noise_nN == pytest.approx(cell.noise_nN, rel=0.15)
    assert fit.baseline_slope_nN_per_um == pytest.approx(cell.tilt_nN_per_um, abs=0.05)
    if cell.hold_s:
        assert fit.hold
        assert fit.beta == pytest.approx(cell.beta, abs=0.05)
        assert fit.bulk_1s_mN_per_m == pytest.approx(cell.bulk_1s_mN_per_m, rel=0.25)


@pytest.mark.slow
def test_a_constant_force_hold_of_a_fast_relaxing_cell_reads_its_tension():
    """A constant-force hold of a cell with β 0.26 and a low tension (γ_a/K_B(1 s) 0.02),
    whose creep through binned knots read γ_a 2.4×: γ_a within 10 % inside its interval, β
    within 0.05."""
    cell = Cell(5.6, 0.39, 19.3, 0.53, 0.26, 1.09, 0.14 * 5.6, hold_s=10.0, tilt_nN_per_um=0.06, hold_kind="force")
    made = recording(cell, seed=1)
    fit = fit_ramp_hold(made.time_s, made.x_um, made.force_nN, made.ramp_samples, cell.radius_um, cell.shear_tilde,
                        "force")
    lo, hi = fit.tension_interval_mN_per_m
    assert fit.tension_mN_per_m == pytest.approx(cell.tension_mN_per_m, rel=0.10)
    assert lo <= cell.tension_mN_per_m <= hi
    assert fit.beta == pytest.approx(cell.beta, abs=0.05)


@pytest.mark.slow
def test_an_elastic_cell_reads_as_beta_zero():
    """The elastic shell is the power law's β = 0: a ramp and hold of an elastic cortex (the
    time-domain shell at β = 0) reads β ≈ 0, K_B within 15 % and γ_a inside its interval."""
    cell = Cell(6.5, 0.94, 12.0, 0.5, 0.0, 1.0, 0.14 * 6.5, hold_s=15.0, tilt_nN_per_um=0.05)
    made = recording(cell, seed=3)
    fit = fit_ramp_hold(made.time_s, made.x_um, made.force_nN, made.ramp_samples, cell.radius_um, cell.shear_tilde)
    lo, hi = fit.tension_interval_mN_per_m
    assert fit.beta < 0.01
    assert fit.bulk_1s_mN_per_m == pytest.approx(cell.bulk_1s_mN_per_m, rel=0.15)
    assert lo <= cell.tension_mN_per_m <= hi and hi - lo < 0.3 * cell.tension_mN_per_m


@pytest.mark.parametrize("tabled", [True, False], ids=["table", "simulator"])
def test_a_noise_free_cell_reads_exactly_in_a_few_simulations(monkeypatch, tabled):
    """At zero noise the reading is the truth: the tabled simulator polished by one simulation
    (the table alone reads γ_a a few per cent off: its scaling's error), or, where the table
    does not hold the recording, the defect correction's fixed point (the simulator's force there
    is the recording), settled within SIMULATIONS simulations; each counted, γ_a within 0.3 %, β
    within 0.003, a residual far below any noise."""
    from analysis.afm.tension import powerlaw_fit
    cell = Cell(6.0, 0.8, 10.0, 0.5, 0.2, 1.5, 0.14 * 6.0, hold_s=4.0, noise_nN=0.0, tilt_nN_per_um=0.05)
    made = recording(cell)
    calls = counted(monkeypatch, powerlaw_simulated, "force_nN")
    if not tabled:
        monkeypatch.setattr(powerlaw_fit, "tabled_fit", lambda *args, **kwargs: None)
    fit = fit_ramp_hold(made.time_s, made.x_um, made.force_nN, made.ramp_samples, cell.radius_um, cell.shear_tilde)
    assert fit.tabled == tabled and fit.simulations == len(calls)
    if tabled:
        assert fit.simulations == powerlaw_fit.POLISH_SIMULATIONS
    else:
        assert fit.converged and 2 <= fit.simulations <= powerlaw_fit.SIMULATIONS + 5     # and the Jacobian's
        assert abs(fit.surrogate[0] / cell.tension_mN_per_m - 1.0) > 0.01    # the surrogate alone is off
    assert fit.tension_mN_per_m == pytest.approx(cell.tension_mN_per_m, rel=3e-3)
    assert fit.bulk_1s_mN_per_m == pytest.approx(cell.bulk_1s_mN_per_m, rel=1e-2)
    assert fit.beta == pytest.approx(cell.beta, abs=3e-3)
    assert fit.noise_nN < 1e-3


def test_bad_input_is_one_clear_error():
    t = np.linspace(0.0, 1.0, 50)
    with pytest.raises(InputError):
        fit_ramp_hold(t, t[:-1], t, 40, 6.0)
    with pytest.raises(InputError):
        fit_ramp_hold(t, t, t, 1, 6.0)


@pytest.mark.slow
def test_the_command_reads_a_ramp_and_its_pause(tmp_path, capsys):
    """`cortex afm tension --power-law`: the power_law_* columns of the approach row give
    back the cell's γ_a and β from the ramp and the constant-height pause after it, where
    the elastic shell's γ_a is far high; tension.csv has the columns."""
    import json

    from analysis.afm.formats.csvcell import write_csv_cell
    from analysis.afm.formats.instruments import to_cell
    from cortex.cli import main
    from studies.powerlaw_ramps import as_recording
    cell = CELLS[0]
    volume = 4.0 * np.pi / 3.0 * cell.radius_um ** 3
    path = write_csv_cell(tmp_path / "c.csv", to_cell(as_recording(recording(cell, seed=2), "c"), volume, "synthetic"))
    status = main(["afm", "tension", str(path), "--power-law", "--shear-ratio", str(cell.shear_tilde), "--json",
                   "--out", str(tmp_path / "out")])
    assert status == 0
    rows = json.loads(capsys.readouterr().out)["rows"]
    ramp = next(r for r in rows if r["part"] == "approach")
    assert ramp["power_law_hold"] == "height" and ramp["power_law_shear_ratio_source"] == "given"
    assert ramp["power_law_tension_mN_per_m"] == pytest.approx(cell.tension_mN_per_m, rel=0.10)
    assert ramp["power_law_tension_lo95_mN_per_m"] <= cell.tension_mN_per_m <= ramp["power_law_tension_hi95_mN_per_m"]
    assert ramp["power_law_exponent"] == pytest.approx(cell.beta, abs=0.05)
    assert ramp["tension_mN_per_m"] > 1.3 * cell.tension_mN_per_m          # the elastic shell's reading
    import pandas as pd
    assert "power_law_exponent" in pd.read_csv(tmp_path / "out" / "tension.csv")


def test_the_ends_of_the_shear_ratio_interval_are_located_between_the_profile_points(monkeypatch):
    """A profile whose √Δχ² is not linear in ln K̃_S (Δχ² = 16 (K̃_S/0.5 − 1)², its 95 % set
    0.255-0.745): read between the five nodes and the best alone, its ends miss by ~0.05 in
    ln K̃_S; each end located between the last node inside and the first outside (at most
    END_FITS fits an end) is read within 0.01 of it."""
    from analysis.afm.tension import powerlaw_shear
    from analysis.afm.tension.powerlaw_fit import Solved
    from analysis.afm.tension.shell_shear import profile_bands

    def chi2(shear: float) -> float:
        return 16.0 * (shear / 0.5 - 1.0) ** 2
    fits = []

    def correct(s, radius, shear, q0, **kwargs):
        fits.append(shear)
        return Solved(np.array([shear]), 100.0 + chi2(shear), np.eye(1), np.zeros(2))
    monkeypatch.setattr(powerlaw_shear, "correct", correct)
    nodes = [float(v) for v in np.geomspace(*powerlaw_shear.SHEAR_RANGE, powerlaw_shear.NODES)] + [0.5]
    done = {v: Solved(np.array([v]), 100.0 + chi2(v), np.eye(1), np.zeros(2)) for v in nodes}

    def band() -> npt.NDArray[np.float64]:
        shears = sorted(done)
        return np.log(profile_bands(shears, [chi2(v) for v in shears], [])[0])
    truth = np.log([0.255, 0.745])
    assert np.all(np.abs(band() - truth) > 0.04)
    powerlaw_shear._ends(None, 6.0, done, 1.0, None)  # type: ignore[arg-type]
    np.testing.assert_allclose(band(), truth, atol=0.01)
    assert 2 <= len(fits) <= 2 * powerlaw_shear.END_FITS


@pytest.fixture(scope="module")
def stiff_shear_cell():
    """A cell with a hold whose K̃_S = 1.5 is far from 1/3, and its recording."""
    cell = Cell(6.5, 0.94, 7.9, 1.5, 0.17, 0.38, 0.14 * 6.5, hold_s=23.0, tilt_nN_per_um=0.05)
    made = recording(cell, seed=1)
    ramp = slice(0, made.ramp_samples)
    pause = slice(made.ramp_samples, None)
    return cell, tuple(a[ramp] for a in (made.time_s, made.x_um, made.force_nN)), \
        tuple(a[pause] for a in (made.time_s, made.x_um, made.force_nN))


@pytest.mark.slow
def test_unknown_shear_ratio_is_profiled_and_holds_the_truth(stiff_shear_cell):
    """Without --shear-ratio (and no prior) K̃_S is profiled over 0.1-2: its interval holds the
    truth 1.5 and leaves out 0.2 (the simulator's own least squares there: Δχ² 5.7; 1/3, at 1.4,
    is inside: this hold tells K̃_S only from below), γ_a within 5 % inside its widened interval;
    --shear-ratio still fixes K̃_S."""
    from analysis.afm.tension.powerlaw_row import power_law_columns
    cell, ramp, pause = stiff_shear_cell
    truth = cell.tension_mN_per_m
    forced = power_law_columns(ramp, pause, cell.radius_um, 1.0 / 3.0)
    free = power_law_columns(ramp, pause, cell.radius_um, None)
    assert forced["power_law_shear_ratio_source"] == "given"
    assert forced["power_law_shear_ratio_lo95"] == forced["power_law_shear_ratio_hi95"] == 1.0 / 3.0
    assert free["power_law_shear_ratio_source"] == "profiled" and free["power_law_hold"] == "height"
    assert 0.2 < free["power_law_shear_ratio_lo95"] <= cell.shear_tilde <= free["power_law_shear_ratio_hi95"]
    assert free["power_law_tension_mN_per_m"] == pytest.approx(truth, rel=0.05)
    assert free["power_law_tension_lo95_mN_per_m"] <= truth <= free["power_law_tension_hi95_mN_per_m"]
    assert free["power_law_exponent"] == pytest.approx(cell.beta, abs=0.03)


@pytest.mark.slow
def test_an_oscillation_prior_gives_the_shear_ratio(stiff_shear_cell):
    """With the oscillations' prior (and no --shear-ratio) K̃_S is the prior's, taken as given."""
    from analysis.afm.tension.powerlaw_row import power_law_columns
    from analysis.afm.tension.priors import Prior
    cell, ramp, pause = stiff_shear_cell
    prior = Prior(bulk_mN_per_m=10.0, bulk_sd_mN_per_m=2.0, shear_tilde=1.5, shear_log_sd=0.1, bulk_exponent=0.17,
                  bulk_exponent_sd=0.02, shear_exponent=0.17, shear_exponent_sd=0.02, time_scale_s=3.0,
                  noise_nN=0.02)
    row = power_law_columns(ramp, pause, cell.radius_um, None, prior)
    assert row["power_law_shear_ratio_source"] == "oscillation prior"
    assert row["power_law_shear_ratio"] == row["power_law_shear_ratio_lo95"] == 1.5
    assert row["power_law_tension_mN_per_m"] == pytest.approx(cell.tension_mN_per_m, rel=0.03)


def test_the_calibrations_tables_reach_the_fit_given_or_profiled(monkeypatch):
    """`--calibration`'s power-law table is the one the tabled fit reads, and its shell ramp table
    the one the surrogate reads where the table does not hold the recording, K̃_S given or profiled
    (the fit stopped there: only the tables' paths are checked here)."""
    from analysis.afm.tension import powerlaw_fit, powerlaw_tabled
    from analysis.afm.tension.powerlaw_row import power_law_columns
    from common.errors import SolverError
    radius, contact = 6.5, 13.0
    x = np.linspace(contact + 0.5, contact - 0.9, 300)                       # a 1 µm/s approach, 0.9 µm deep
    f = shell_ramp.force_nN(np.clip(contact - x, 0.0, None), radius, 0.9, 8.0, 1.0 / 3.0)
    ramp = (np.linspace(0.0, 1.4, x.size), x, f + np.random.default_rng(3).normal(0.0, 0.02, x.size))
    mine, powerlaw, seen, tabled = shell_ramp.shipped(), powerlaw_tabled.resolve(None), [], []

    def not_held(*args, **kwargs):
        tabled.append(args[5] if len(args) > 5 else kwargs.get("powerlaw"))
        return None

    def stop(*args, **kwargs):
        seen.append(args[5] if len(args) > 5 else kwargs.get("table"))
        raise SolverError("stopped at the surrogate")

    monkeypatch.setattr(powerlaw_fit, "tabled_fit", not_held)
    monkeypatch.setattr(powerlaw_fit, "surrogate_fits", stop)
    for shear in (1.0 / 3.0, None):
        row = power_law_columns(ramp, None, radius, shear, None, mine, powerlaw)
        assert row["power_law_note"] == "not read: stopped at the surrogate"
    assert len(seen) == 2 and all(t is mine for t in seen)
    assert tabled and all(t is powerlaw for t in tabled)