"""Reconstruction check and Monte-Carlo study: exact without errors, the
statistics defined as documented, errors widen the spread."""

import numpy as np
import pandas as pd
import pytest

from analysis.calibration.command import montecarlo, reconstruction
from analysis.calibration.law import Calibration, calibrate
from studies.synthetic import reference_law, results_table, trials_table

LAW = reference_law("standard")
CAL = Calibration({"standard": LAW})


def test_reconstruction_exact_on_law_data():
    results = results_table({"standard": LAW})
    cal, fits, _ = calibrate(results)
    rec = reconstruction.reconstruct(results, cal, fits)
    assert len(rec) == 30 and rec["excluded_reason"].isna().all()
    assert rec["n_heights"].eq(5).all()                       # h0 = 10 um (h~ = 0.48) is outside 0.5-0.75
    assert rec["nu_error"].abs().max() < 1e-9
    assert rec["nu_law_error"].abs().max() < 1e-9
    (s,) = reconstruction.summarise(rec)
    assert s["n_curves"] == 30 and s["n_excluded"] == 0 and s["max_abs_nu_error"] < 1e-9


def test_reconstruction_with_noise_reports_the_largest_error():
    results = results_table({"standard": LAW}, noise=0.003, rng=4)
    cal, fits, _ = calibrate(results)
    rec = reconstruction.reconstruct(results, cal, fits)
    (s,) = reconstruction.summarise(rec)
    assert s["max_abs_nu_error"] == pytest.approx(rec["nu_error"].abs().max())
    assert 1e-4 < s["max_abs_nu_error"] < 0.05
    worst = rec.loc[rec["nu_error"].abs().idxmax()]
    assert s["worst_at"] == {"shear_mN_per_m": worst["shear_mN_per_m"],
                             "tension_mN_per_m": worst["tension_mN_per_m"]}


def test_montecarlo_without_errors_recovers_nu_exactly():
    trials = trials_table(LAW, n_cells=12, n_studies=3, volume_rel_sd=0.0, height_sd_um=0.0, seed=1)
    records, studies, cells = montecarlo.montecarlo(trials, CAL)
    assert len(cells) == 3 * 2 * 3 * 12 and cells["excluded_reason"].isna().all()
    assert len(records) == 3 * 2 and len(studies) == 3 * 2 * 3
    for r in records:
        assert r["median"] == pytest.approx(r["nu_true"], abs=1e-10)
        assert r["iqr"] < 1e-10 and r["n_cells"] == 12 and r["n_studies"] == 3
        assert r["median_p05"] == pytest.approx(r["nu_true"], abs=1e-10)


def test_montecarlo_statistics_are_as_documented():
    """Hand-made per-cell results: median/iqr = median over studies of each
    study's median/IQR; p05/p95 percentiles over studies; excluded cells left out."""
    rng = np.random.default_rng(0)
    rows = []
    for study in range(5):
        for cell in range(9):
            rows.append({"bending": "standard", "nu_true": 0.5, "height_error_mode": "per_cell",
                         "study": study, "cell": cell, "nu": rng.normal(0.5, 0.1),
                         "excluded_reason": "x" if cell == 8 else None})
    cells = pd.DataFrame(rows)
    (rec,), studies = montecarlo.summarise(cells)
    kept = cells[cells["excluded_reason"].isna()]
    med = kept.groupby("study")["nu"].median().to_numpy()
    iqr = kept.groupby("study")["nu"].quantile(0.75).to_numpy() - kept.groupby("study")["nu"].quantile(0.25).to_numpy()
    assert rec["median"] == pytest.approx(np.median(med))
    assert rec["iqr"] == pytest.approx(np.median(iqr))
    assert rec["median_p05"] == pytest.approx(np.percentile(med, 5))
    assert rec["iqr_p95"] == pytest.approx(np.percentile(iqr, 95))
    assert rec["pooled_median"] == pytest.approx(kept["nu"].median())
    assert rec["excluded_fraction"] == pytest.approx(5 / 45)
    assert rec["n_cells"] == 9 and rec["n_studies"] == 5
    assert studies["n_included"].eq(8).all()


def test_measurement_errors_spread_the_recovered_nu():
    """With 7.5 % volume and 0.5 um per-cell height errors, the median stays
    near the truth but the IQR grows from 0 to a few hundredths or more."""
    trials = trials_table(LAW, nu_values=(0.43,), modes=("per_cell",), n_cells=55, n_studies=6, seed=5)
    (rec,), _, cells = montecarlo.montecarlo(trials, CAL)
    assert abs(rec["median"] - 0.43) < 0.05
    assert rec["iqr"] > 0.02
    assert rec["median_p05"] < rec["median"] < rec["median_p95"]


def test_trials_of_a_variant_are_inverted_with_that_variant():
    double = reference_law("double")
    trials = trials_table(double, nu_values=(0.25,), modes=("per_cell",), n_cells=5, n_studies=1,
                          volume_rel_sd=0.0, height_sd_um=0.0)
    cal = Calibration({"standard": LAW, "double": double})
    (rec,), _, _ = montecarlo.montecarlo(trials, cal)
    assert rec["bending"] == "double" and rec["median"] == pytest.approx(0.25, abs=1e-10)
