"""population.json of `cortex afm analyze`: the population answer from the cells table.

Per frequency (the included cells, y = ln K̃_S, s its standard error `ln_ks_se`): the
random-effects fit (`analysis.afm.population.random_effects`: μ, between-cell SD τ,
measurement SD s_m and its share of the observed variance, with 95 % intervals), beside
the raw numbers (mean and SD of y, median and IQR of ν) and the ν the deconvolved
population N(μ, τ²) implies (median ν = ν(e^μ); quartiles ν(e^(μ ± 0.674 τ)), ν falling
as K̃_S rises). The paired tests
(`analysis.afm.population.paired`). The trend (`trend`): the least-squares line through
the per-frequency population means, every frequency weighted alike
(`analysis.afm.population.mean_trend`, with the line's ν at each measured frequency and on
a grid of frequencies for the figure's band); beside it `trend_design_weighted`, the slope
of the mixed model over all cells and frequencies (`analysis.afm.population.trend`), whose
weights follow the number of cells measured at each frequency.

Without standard errors (the `law` method) every s is 0: τ is then the raw
spread and the measurement fields are null.
"""

from collections.abc import Iterable

import numpy as np
import pandas as pd

from analysis.afm.population import mean_trend, random_effects, trend
from analysis.afm.population.paired import paired_tests
from solver.elasticity import poisson_of_ratio

BAND_POINTS = 9          # frequencies of the trend's band (log-spaced over the measured range)
Q3 = 0.6744897501960817  # z of the upper quartile


def _cells(table: pd.DataFrame) -> tuple[pd.DataFrame, bool]:
    """Included rows with y = ln K̃_S and s; whether the table has standard errors."""
    ok = table[table["excluded_reason"].isna()].copy()
    ok["ln_ks"] = np.log(ok["ks_tilde"].astype(float))
    has = "ln_ks_se" in ok.columns and bool(np.isfinite(ok["ln_ks_se"].astype(float)).any())
    ok["s"] = ok["ln_ks_se"].astype(float) if has else 0.0
    return ok, has


def _deconvolved_nu(mu: float, tau: float) -> dict:
    if not np.isfinite(mu):
        return {"population_median_nu": None, "population_iqr_nu": None}
    lo, hi = poisson_of_ratio(np.exp(mu + Q3 * tau)), poisson_of_ratio(np.exp(mu - Q3 * tau))
    return {"population_median_nu": float(poisson_of_ratio(np.exp(mu))), "population_iqr_nu": float(hi - lo)}


def per_frequency(ok: pd.DataFrame, has_intervals: bool) -> list:
    rows = []
    for f, g in ok.groupby("frequency_hz", sort=True):
        pop = random_effects.fit(g["ln_ks"], g["s"]).to_dict()
        if not has_intervals:
            pop.update({k: None for k in pop if k.startswith("measurement_")})
        nu = g["nu"].to_numpy(float)
        q1, q3 = np.percentile(nu, [25, 75])
        rows.append({"frequency_hz": float(f), **pop, "raw_mean_ln_ks": float(g["ln_ks"].mean()),
                     "raw_sd_ln_ks": float(g["ln_ks"].std(ddof=1)) if len(g) > 1 else None,
                     "raw_median_nu": float(np.median(nu)), "raw_iqr_nu": float(q3 - q1),
                     **_deconvolved_nu(pop["mean_ln_ks"], pop["between_cell_sd_ln_ks"])})
    return rows


def answer(table: pd.DataFrame) -> dict:
    """The population.json document of a cells table (`analysis.afm.analyze`)."""
    ok, has = _cells(table)
    doc = {"measurement_from_intervals": has, "frequencies": per_frequency(ok, has), **paired_tests(table)}
    freqs = sorted(map(float, ok["frequency_hz"].unique()))
    band: Iterable[float] = np.geomspace(freqs[0], freqs[-1], BAND_POINTS) if len(freqs) > 1 else []
    line = mean_trend.fit(ok["cell_id"], ok["frequency_hz"], ok["ln_ks"], sorted(set(freqs) | set(map(float, band))))
    doc["trend"] = None if line is None else _with_band(line.to_dict(), freqs)
    mixed = trend.fit(trend.Observations.of(ok["cell_id"], ok["frequency_hz"], ok["ln_ks"], ok["s"]))
    doc["trend_design_weighted"] = None if mixed is None else {
        k: v for k, v in mixed.to_dict().items() if k != "frequencies"}
    return doc


def _with_band(t: dict, measured: list) -> dict:
    """The trend's rows split into `band` (all) and `frequencies` (the measured ones)."""
    t["band"] = t.pop("frequencies")
    t["frequencies"] = [r for r in t["band"] if r["frequency_hz"] in set(measured)]
    return t
