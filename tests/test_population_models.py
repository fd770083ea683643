"""The population answer's statistics against known truth on generated data:
the random-effects fit, the trend (the line through the population means, and the
design-weighted mixed model), the paired tests, population.json."""

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from analysis.afm.population import mean_trend, random_effects, trend
from analysis.afm.population.paired import paired_tests
from analysis.afm.population.answer import answer
from solver.elasticity import poisson_of_ratio


def test_without_measurement_error_reml_is_the_sample_sd_and_mu_interval_the_t_one():
    rng = np.random.default_rng(3)
    y = rng.normal(-0.7, 0.8, 40)
    p = random_effects.fit(y, np.zeros_like(y))
    assert p.sd == pytest.approx(np.std(y, ddof=1), rel=1e-4)
    assert p.mean == pytest.approx(np.mean(y), abs=1e-9)
    assert p.share == 0.0
    lo, hi = stats.t.interval(0.95, len(y) - 1, loc=np.mean(y), scale=stats.sem(y))
    assert (p.mean_lo, p.mean_hi) == pytest.approx((lo, hi), rel=1e-9)


def test_random_effects_intervals_hold_the_truth_about_95_percent():
    rng = np.random.default_rng(7)
    mu, tau, hits_mu, hits_tau, reps = -1.0, 0.8, 0, 0, 120
    for _ in range(reps):
        s = rng.uniform(0.2, 0.8, 50)
        y = mu + tau * rng.standard_normal(50) + s * rng.standard_normal(50)
        p = random_effects.fit(y, s)
        hits_mu += p.mean_lo <= mu <= p.mean_hi
        hits_tau += p.sd_lo <= tau <= p.sd_hi
    assert 0.88 <= hits_mu / reps <= 1.0 and 0.88 <= hits_tau / reps <= 1.0


def test_random_effects_recovers_tau_and_the_share_from_a_large_sample():
    rng = np.random.default_rng(1)
    s = rng.uniform(0.3, 0.7, 4000)
    y = 0.2 + 0.5 * rng.standard_normal(s.size) + s * rng.standard_normal(s.size)
    p = random_effects.fit(y, s)
    assert p.mean == pytest.approx(0.2, abs=0.03) and p.sd == pytest.approx(0.5, abs=0.03)
    share = np.mean(s**2) / (0.25 + np.mean(s**2))
    assert p.share_lo <= share <= p.share_hi and p.share_hi - p.share_lo < 0.1
    # measurement error that is all there is: the share is near one, τ's interval reaches 0
    q = random_effects.fit(s[:60] * rng.standard_normal(60), s[:60])
    assert q.sd_lo == 0.0 and q.share_hi == 1.0


def _mixed(rng, n_cells, slope, tau, s_obs, freqs=(0.1, 1.0, 10.0), a=-0.7):
    cell, f, y, s = [], [], [], []
    for c in range(n_cells):
        u = tau * rng.standard_normal()
        for fr in freqs[: rng.integers(1, len(freqs) + 1)]:       # some cells at one frequency only
            cell.append(c), f.append(fr), s.append(s_obs)
            y.append(a + slope * np.log10(fr) + u + s_obs * rng.standard_normal())
    return trend.Observations.of(cell, f, y, s)


def test_trend_slope_and_its_interval_on_a_linear_mixed_sample():
    rng = np.random.default_rng(5)
    hits, reps = 0, 30
    for _ in range(reps):
        t = trend.fit(_mixed(rng, 60, 0.4, 0.8, 0.4))
        hits += t.slope_lo <= 0.4 <= t.slope_hi
    assert hits / reps >= 0.85
    big = trend.fit(_mixed(rng, 3000, 0.4, 0.8, 0.4), [1.0])
    assert big.slope == pytest.approx(0.4, abs=0.03) and big.cell_sd == pytest.approx(0.8, abs=0.05)
    assert big.residual_sd < 0.1           # the known measurement variance is all the scatter
    line = big.at[1.0]
    assert line["ln_ks_lo95"] < -0.7 < line["ln_ks_hi95"]
    assert line["nu"] == pytest.approx(float(poisson_of_ratio(np.exp(line["ln_ks"]))))
    assert line["nu_lo95"] < line["nu"] < line["nu_hi95"]


def test_pseudo_true_slope_is_the_line_when_the_means_are_on_one():
    pops = {f: (-0.7 + 0.3 * np.log10(f), 0.8) for f in (0.02, 0.1, 1.0, 10.0)}
    design = [((0.1, 1.0, 10.0), 50), ((0.02, 0.1, 1.0, 10.0), 10), ((0.02,), 25)]
    assert trend.pseudo_true_slope(pops, design) == pytest.approx(0.3, abs=1e-6)


def test_pseudo_true_slope_is_what_the_fit_reaches_on_a_large_sample():
    from analysis.afm.synth.cells import POPULATIONS, subset_sizes
    rng = np.random.default_rng(0)
    cell, f, y = [], [], []
    for freqs, n in subset_sizes(85):
        for _ in range(40 * n):
            z, c = rng.standard_normal(), len(set(cell))
            for fr in freqs:
                cell.append(c), f.append(fr), y.append(POPULATIONS[fr][0] + POPULATIONS[fr][1] * z)
    big = trend.fit(trend.Observations.of(cell, f, y, np.zeros(len(y))))
    assert big.slope == pytest.approx(trend.pseudo_true_slope(POPULATIONS, subset_sizes(85)), abs=0.01)


def _published_design(rng, s_obs, scale=1):
    """One experiment of the synth's design (cells per frequency set x `scale`), y = μ_f + σ_f z + N(0, s_obs²)
    with the synth's populations (μ_f not linear in log10 f): columns (cell, f, y)."""
    from analysis.afm.synth.cells import POPULATIONS, subset_sizes
    cell, f, y, c = [], [], [], 0
    for freqs, n in subset_sizes(85):
        for _ in range(n * scale):
            z = rng.standard_normal()
            for fr in freqs:
                cell.append(c), f.append(fr)
                y.append(POPULATIONS[fr][0] + POPULATIONS[fr][1] * z + s_obs * rng.standard_normal())
            c += 1
    return np.array(cell), np.array(f), np.array(y)


def _ols_through_true_means():
    from analysis.afm.synth.cells import POPULATIONS
    return float(np.polyfit(np.log10(list(POPULATIONS)), [m for m, _ in POPULATIONS.values()], 1)[0])


def test_mean_trend_is_the_line_through_the_sample_means_with_their_covariance():
    cell, f, y = _published_design(np.random.default_rng(2), 0.3, scale=20)
    freqs, means, cov, n, n_cells = mean_trend.means_and_covariance(cell, f, y)
    assert list(freqs) == [0.02, 0.1, 1.0, 10.0] and list(n) == [700, 1200, 1200, 1200] and n_cells == 1700
    assert means == pytest.approx([y[f == fr].mean() for fr in freqs], abs=1e-12)
    t = mean_trend.fit(cell, f, y, [1.0])
    assert t.slope == pytest.approx(np.polyfit(np.log10(freqs), means, 1)[0], abs=1e-12)
    assert t.intercept == pytest.approx(np.polyfit(np.log10(freqs), means, 1)[1], abs=1e-12)
    # the covariance of the means: 200 cells share 0.02 Hz with 0.1 Hz, y's covariance there σ_0.02 σ_0.1
    assert cov[0, 1] == pytest.approx(200 * 0.8 * 0.8 / (700 * 1200), rel=0.15)
    assert cov[1, 1] == pytest.approx((0.8**2 + 0.3**2) / 1200, rel=0.1)
    assert t.at[1.0]["ln_ks_lo95"] < t.at[1.0]["ln_ks"] < t.at[1.0]["ln_ks_hi95"]


def test_the_trend_holds_the_line_through_the_true_means_whatever_the_design():
    """The published design (50 cells at 0.1/1/10 Hz, 10 at all four, 25 at 0.02 Hz only) and small
    measurement error: the line through the population means holds the line through the true μ_f
    at about 95 %; the design-weighted slope (mixed model; 0.379 for this design) does not."""
    truth, rng, reps = _ols_through_true_means(), np.random.default_rng(11), 40
    new = old = 0
    for _ in range(reps):
        cell, f, y = _published_design(rng, 0.1)
        t = mean_trend.fit(cell, f, y)
        d = trend.fit(trend.Observations.of(cell, f, y, np.full(y.size, 0.1)))
        new += t.slope_lo <= truth <= t.slope_hi
        old += d.slope_lo <= truth <= d.slope_hi
    assert new >= 34 and old <= 8, (new, old)


def _table(rng, n=12):
    """Cells at 0.1/1/10 Hz whose ν falls with frequency in every cell, with a large spread between cells."""
    rows = []
    for c in range(n):
        z = rng.standard_normal()
        for k, f in enumerate((0.1, 1.0, 10.0)):
            ks = np.exp(-1.0 + 0.9 * z + 0.2 * k)
            rows.append({"cell_id": f"c{c}", "frequency_hz": f, "ks_tilde": ks, "nu": float(poisson_of_ratio(ks)),
                         "ks_lo95": ks * np.exp(-0.4), "ks_hi95": ks * np.exp(0.4), "ln_ks_se": 0.2,
                         "excluded_reason": None})
    rows.append({"cell_id": "solo", "frequency_hz": 0.02, "ks_tilde": 0.3, "nu": float(poisson_of_ratio(0.3)),
                 "ks_lo95": 0.2, "ks_hi95": 0.45, "ln_ks_se": 0.2, "excluded_reason": None})
    return pd.DataFrame(rows)


def test_paired_tests_see_a_shift_every_cell_shares():
    t = _table(np.random.default_rng(2))
    t.loc[(t.cell_id == "c0") & (t.frequency_hz == 10.0), "excluded_reason"] = "excluded"
    out = paired_tests(t)
    r = out["paired"]["0.1Hz_vs_1Hz"]
    assert r["n_cells"] == 12 and r["wilcoxon_p"] == pytest.approx(2 / 2**12)   # exact: all 12 signs alike
    assert out["paired"]["1Hz_vs_10Hz"]["n_cells"] == 11
    assert out["paired"]["0.02Hz_vs_0.1Hz"]["n_cells"] == 0 and out["paired"]["0.02Hz_vs_0.1Hz"]["wilcoxon_p"] is None
    assert out["friedman_n_cells"] == 11 and out["friedman_frequencies_hz"] == [0.1, 1.0, 10.0]
    assert out["friedman_p"] < 1e-4
    ok = t[t.excluded_reason.isna()]
    assert stats.mannwhitneyu(ok[ok.frequency_hz == 0.1].nu, ok[ok.frequency_hz == 1.0].nu).pvalue > 0.05


def test_population_json_has_the_interface_keys():
    doc = answer(_table(np.random.default_rng(4), n=20))
    keys = {"n_cells", "mean_ln_ks", "mean_ln_ks_lo95", "mean_ln_ks_hi95", "between_cell_sd_ln_ks",
            "between_cell_sd_ln_ks_lo95", "between_cell_sd_ln_ks_hi95", "measurement_sd_ln_ks", "measurement_share"}
    per_f = [r for r in doc["frequencies"] if r["n_cells"] >= 3]
    assert len(per_f) == 3 and all(keys <= set(r) for r in per_f)
    assert all(r["measurement_sd_ln_ks"] == pytest.approx(0.2) for r in per_f)   # each cell's ln_ks_se
    assert {"n_cells", "wilcoxon_p"} <= set(doc["paired"]["0.1Hz_vs_10Hz"]) and doc["friedman_p"] < 1e-3
    t = doc["trend"]
    assert {"slope_ln_ks_per_decade", "slope_lo95", "slope_hi95"} <= set(t)
    assert t["slope_ln_ks_per_decade"] == pytest.approx(0.2)   # _table: ln K̃_S rises by 0.2 per decade in every cell
    assert t["slope_lo95"] <= t["slope_ln_ks_per_decade"] <= t["slope_hi95"]
    assert [r["frequency_hz"] for r in t["frequencies"]] == [0.02, 0.1, 1.0, 10.0]   # the line at every one
    d = doc["trend_design_weighted"]
    assert d["slope_lo95"] < 0.2 < d["slope_hi95"] and d["n_cells"] == 21


def test_afm_analyze_writes_population_json_and_opens_the_report_with_the_trend(tmp_path):
    import json

    from analysis.afm.synth.cells import subset_sizes
    from analysis.calibration.law import Calibration
    from studies.synthetic import reference_law
    from cortex.cli import main
    cal = tmp_path / "cal.json"
    Calibration({b: reference_law(b) for b in ("standard", "double", "none")}).save(
        cal, borrow=("emulator", "viscoelastic_table"))      # the shipped emulator and table, named
    assert main(["afm", "synth", "--cells", "12", "--seed", "3", "--out", str(tmp_path / "exp"), "--solver", "law",
                 "--calibration", str(cal)]) == 0
    truth = json.loads((tmp_path / "exp" / "truth.json").read_text())
    pops = {float(f): p for f, p in truth["populations"].items()}
    assert truth["trend_slope_ln_ks_per_decade"] == pytest.approx(
        np.polyfit(np.log10(list(pops)), [m for m, _ in pops.values()], 1)[0])
    assert truth["trend_slope_design_weighted_ln_ks_per_decade"] == pytest.approx(
        trend.pseudo_true_slope(pops, subset_sizes(12)))
    assert main(["afm", "analyze", str(tmp_path / "exp"), "--calibration", str(cal), "--method", "law",
                 "--out", str(tmp_path / "a")]) == 0
    doc = json.loads((tmp_path / "a" / "population.json").read_text())
    assert doc["measurement_from_intervals"] is False          # the law gives no intervals
    assert all(r["measurement_share"] is None for r in doc["frequencies"])
    assert doc["trend"]["slope_lo95"] < doc["trend"]["slope_ln_ks_per_decade"] < doc["trend"]["slope_hi95"]
    assert doc["trend_design_weighted"]["n_observations"] >= doc["trend"]["n_cells"]
    first = [line for line in (tmp_path / "a" / "report.md").read_text().splitlines()[1:]
             if line and not line.startswith("Method:")][0]
    assert first.startswith("**Trend:**")
    assert all((tmp_path / "a" / n).stat().st_size > 0 for n in ("nu_paired.png", "nu_deconvolved.png", "nu_trend.png"))
