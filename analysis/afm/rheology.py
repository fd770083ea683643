"""The viscoelastic reading of a recording: complex moduli per cell and frequency, power
laws across frequencies, the paired test of β_S against β_B (SPEC 10).

Per cell and frequency (`analysis.viscoelastic_fit`): the measured K*_j = |K_j| e^{iδ_j}
at each used height (δ_j the segment's loss angle minus the instrument's lag at that
frequency, `instrument_lags`), fitted for K_B = |K_B*|, δ_B, K_S = |K_S*|, δ_S with 95 %
intervals and the complex ν*; only curves the magnitude-only analysis includes.

Per cell with ≥ 3 such frequencies, power laws by least squares in ln f:

    ln K_B(f) = ln K_B,1Hz + β_B ln(f / 1 Hz),   ln K_S(f) = ln K_S,1Hz + β_S ln(f / 1 Hz),

and in every bootstrap draw the same fit of that draw's moduli (a cell's frequencies
share its draws of the volume and height errors), whose percentiles are the 95 %
intervals of β. A power-law (structural damping) material has δ = βπ/2 at every
frequency: `bulk_power_law_consistent` says whether the mean fitted δ_B over the
frequencies minus β_B π/2 has a 95 % interval holding 0 (likewise shear).

The same slope gives the relaxation laws K(t) = K(1 s) t^-β (`power_law`, `modulus_1s`:
K(1 s) = |K*(1 Hz)| / (Γ(1-β) (2π)^β), one frequency: β = 2δ/π) a cell's protocol is replayed
with (`cortex_laws`, the protocol-aware reading) and `cortex afm tension` takes its priors from
(`analysis.afm.tension.priors`).

Population: medians and quartiles of β_B and β_S and the Wilcoxon signed-rank test of
β_S - β_B over the cells (`scipy.stats.wilcoxon`; one-sided, β_S > β_B, as the
turnover reading predicts, and two-sided).
"""

from __future__ import annotations

import warnings
import zlib
from collections.abc import Iterable
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd
from scipy.stats import wilcoxon

from analysis.invert import intervals
from analysis.invert.emulator_fit import CurveArrays
from analysis.invert.inversion import to_curves, used_heights
from analysis.viscoelastic_fit import complex_poisson, draws, fit
from common.errors import InputError

if TYPE_CHECKING:
    from analysis.afm.cell import Cell
    from analysis.calibration.emulator import Emulator
    from analysis.calibration.file import ComplexModel
    from analysis.calibration.viscoelastic_table import ComplexTable
    from analysis.invert.measurement_errors import MeasurementErrors

MIN_FREQUENCIES = 3
RHEOLOGY_COLUMNS = ("cell_id", "bulk_exponent", "bulk_exponent_lo95", "bulk_exponent_hi95", "shear_exponent",
                    "shear_exponent_lo95", "shear_exponent_hi95", "bulk_1hz_mN_per_m", "shear_1hz_mN_per_m")
NO_LAG = "none given: the loss angles include the instrument's own phase lag"


def parse_lags(text: str) -> dict[float, float]:
    """`F=RAD,...` -> {frequency_hz: lag_rad}; InputError (one line) if malformed."""
    lags = {}
    for item in filter(None, (p.strip() for p in text.split(","))):
        try:
            f_text, rad_text = item.split("=")
            f, rad = float(f_text), float(rad_text)
        except ValueError:
            raise InputError(f"--phase-lag-rad: '{item}' is not F=RAD (e.g. 1=0.05,10=0.3)") from None
        if not (np.isfinite(f) and f > 0 and np.isfinite(rad) and abs(rad) < np.pi):
            raise InputError(f"--phase-lag-rad: '{item}' needs a frequency > 0 Hz and |lag| < pi rad")
        lags[f] = rad
    if not lags:
        raise InputError("--phase-lag-rad: give F=RAD pairs separated by commas")
    return lags


def reference_lags(cells: list[Cell]) -> dict[float, float]:
    """{frequency_hz: lag_rad} from recordings on the bare dish: per oscillation segment the
    phase of the force relative to the compression -h(t) (`analysis.afm.timeseries.fit_sinusoid`),
    the median per frequency (a hard dish answers in phase, so this is the instrument's lag)."""
    from analysis.afm.timeseries import fit_sinusoid
    phases: dict[float, list[float]] = {}
    for cell in cells:
        for s in cell.oscillations():
            t = cell.time_s[s.start:s.stop] - cell.time_s[s.start]
            fitted = fit_sinusoid(t, np.vstack([cell.force_nN[s.start:s.stop], -cell.height_um[s.start:s.stop]]),
                                  s.frequency_hz)
            lag = np.angle(np.exp(1j * (fitted["phase"][0] - fitted["phase"][1])))
            phases.setdefault(float(s.frequency_hz), []).append(-float(lag))
    if not phases:
        raise InputError("--phase-reference: the recording has no oscillation segment")
    return {f: float(np.median(v)) for f, v in phases.items()}


def instrument_lags(lags: dict[float, float] | None, frequencies: Iterable[float]) -> dict[float, float]:
    """Lag (rad) per frequency of the data (0 where none was given). The instrument makes the
    recorded force trail by its lag, so δ_true = δ_measured + lag. InputError if lags were
    given but not for every frequency of the data."""
    if lags is None:
        return {f: 0.0 for f in frequencies}
    missing = [f for f in frequencies if not any(np.isclose(f, g) for g in lags)]
    if missing:
        raise InputError(f"instrument phase: no lag for {', '.join(f'{f:g}' for f in missing)} Hz "
                         f"(given for {', '.join(f'{f:g}' for f in sorted(lags))} Hz)")
    return {f: next(v for g, v in lags.items() if np.isclose(f, g)) for f in frequencies}


def _cell_normals(cell_ids: list[str], draws_: int, seed: int) -> Any:
    """(rows, M, 2) standard normals, the same for every row of one cell."""
    cache = {}
    for c in set(cell_ids):
        cache[c] = np.random.default_rng([seed, zlib.crc32(str(c).encode())]).standard_normal((draws_, 2))
    return np.stack([cache[c] for c in cell_ids])


def per_frequency(table: pd.DataFrame, segments: pd.DataFrame, emulator: Emulator, bending: str,
                  table_c: ComplexTable, errors: MeasurementErrors | None = None,
                  lags: dict[float, float] | None = None) -> tuple[pd.DataFrame, Any, Any]:
    """Fit every included (cell, frequency) of `table` (the magnitude-only analysis, emulator
    columns) to the complex K* of `segments`: the new columns (a DataFrame aligned with
    `table`) and the draws θ_m (rows, M, 4) with θ*."""
    errors = errors or intervals_errors()
    lag, curves, lnk, start = _inputs(table, segments, lags)
    theta, s2 = fit(table_c, emulator, bending, curves, lnk, start)
    normals = _cell_normals(table["cell_id"].tolist(), errors.draws, errors.seed)
    th_m = draws(table_c, emulator, bending, theta, s2, curves, lnk, normals, volume_sd=errors.volume_rel_sd,
                 height_sd_um=errors.height_sd_um, seed=errors.seed)
    return _columns(theta, th_m, table["frequency_hz"].map(lag).to_numpy(float)), theta, th_m


def _inputs(table: pd.DataFrame, segments: pd.DataFrame,
            lags: dict[float, float] | None) -> tuple[dict[float, float], CurveArrays, Any, Any]:
    """The instrument lags, the curves, ln K* per segment and the fit's start (θ from `table`)."""
    freqs = sorted(segments["frequency_hz"].unique())
    lag = instrument_lags(lags, freqs)
    segs = segments.assign(_delta=segments["loss_angle_rad"] + segments["frequency_hz"].map(lag))
    segs = segs.merge(table[["cell_id", "frequency_hz", "volume_um3", "tension_mN_per_m"]],
                      on=["cell_id", "frequency_hz"], how="inner", suffixes=("_seg", ""))
    keys, arr = to_curves(segs, ("cell_id", "frequency_hz"),
                          columns=("h_tilde", "modulus_mN_per_m", "_delta", "volume_um3"))
    pos = pd.MultiIndex.from_frame(keys[["cell_id", "frequency_hz"]])
    idx = pos.get_indexer(pd.MultiIndex.from_frame(table[["cell_id", "frequency_hz"]]))
    h, k, d = (arr[c][idx] for c in ("h_tilde", "modulus_mN_per_m", "_delta"))
    use = used_heights(h, k)[0]
    tension, volume = table["tension_mN_per_m"].to_numpy(float), table["volume_um3"].to_numpy(float)
    curves = CurveArrays(h, k, use, tension, volume)
    with np.errstate(invalid="ignore", divide="ignore"):
        lnk = np.log(np.where(use, k, 1.0)) + 1j * np.where(use, d, 0.0)
    start = np.column_stack([np.log(table["bulk_mN_per_m"]), np.log(table["ks_tilde"])])
    start[table["excluded_reason"].notna().to_numpy()] = np.nan
    return lag, curves, lnk, start


def point_moduli(table: pd.DataFrame, segments: pd.DataFrame, model: ComplexModel, bending: str,
                 lags: dict[float, float] | None = None) -> pd.DataFrame:
    """θ* alone (no draws) per (cell_id, frequency_hz) of `table`: `bulk_abs`, `bulk_delta`,
    `shear_abs`, `shear_delta` (|K_B*|, δ_B, |K_S*|, δ_S; mN/m, rad) and `tension` (the table's
    γ_a), what `cortex_laws` needs."""
    _, curves, lnk, start = _inputs(table, segments, lags)
    theta, _ = fit(model.table, model.emulator, bending, curves, lnk, start)
    return pd.DataFrame({"cell_id": table["cell_id"].to_numpy(), "frequency_hz": table["frequency_hz"].to_numpy(),
                         "bulk_abs": np.exp(theta[:, 0]), "bulk_delta": theta[:, 2],
                         "shear_abs": np.exp(theta[:, 0] + theta[:, 1]), "shear_delta": theta[:, 3],
                         "tension": table["tension_mN_per_m"].to_numpy(float)})


def intervals_errors() -> MeasurementErrors:
    from analysis.invert.measurement_errors import MeasurementErrors
    return MeasurementErrors()


def _interval(x: Any) -> tuple[Any, Any]:
    """Percentile 95 % interval along the last axis (NaN where every draw is NaN)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)        # all-NaN rows: excluded curves
        lo, hi = np.nanpercentile(x, [100 * (1 - intervals.LEVEL) / 2, 100 * (1 + intervals.LEVEL) / 2], axis=-1)
    return lo, hi


def _columns(theta: Any, th_m: Any, lag: Any) -> pd.DataFrame:
    """The per-frequency columns from θ* and the draws."""
    out = {}
    for name, col in (("bulk_loss_angle_rad", 2), ("shear_loss_angle_rad", 3)):
        lo, hi = _interval(th_m[..., col])
        out[name], out[name.replace("_rad", "_lo95_rad")], out[name.replace("_rad", "_hi95_rad")] = theta[:, col], lo, hi
    for name, x, xm in (("viscoelastic_bulk_mN_per_m", theta[:, 0], th_m[..., 0]),
                        ("viscoelastic_shear_mN_per_m", theta[:, 0] + theta[:, 1], th_m[..., 0] + th_m[..., 1])):
        lo, hi = _interval(xm)
        out[name], out[name.replace("_mN", "_lo95_mN")], out[name.replace("_mN", "_hi95_mN")] = \
            np.exp(x), np.exp(lo), np.exp(hi)
    nu = complex_poisson(np.nan_to_num(theta))
    ok = np.isfinite(theta).all(axis=1)
    out["nu_complex_real"], out["nu_complex_imag"] = np.where(ok, nu.real, np.nan), np.where(ok, nu.imag, np.nan)
    out["instrument_phase_rad"] = lag
    return pd.DataFrame(out)


def _slopes(x: Any, y: Any) -> tuple[Any, Any]:
    """Least-squares slope and intercept of y against x along the first axis (NaN-free columns)."""
    xm = x.mean()
    slope = ((x - xm)[:, None] * (y - y.mean(axis=0))).sum(axis=0) / ((x - xm) ** 2).sum()
    return slope, y.mean(axis=0) - slope * xm


def power_laws(table: pd.DataFrame, theta: Any, th_m: Any) -> pd.DataFrame:
    """One row per cell with ≥ MIN_FREQUENCIES fitted frequencies: exponents with intervals,
    the 1 Hz moduli, and the power-law check of the loss angles."""
    rows = []
    ok = np.isfinite(theta).all(axis=1)
    for cell, g in table[ok].groupby("cell_id", sort=True):
        if len(g) < MIN_FREQUENCIES:
            continue
        i = g.index.to_numpy()
        x = np.log(g["frequency_hz"].to_numpy(float))
        row = {"cell_id": cell, "n_frequencies": len(g)}
        for name, y, ym, col in (("bulk", theta[i, 0], th_m[i, :, 0], 2),
                                 ("shear", theta[i, 0] + theta[i, 1], th_m[i, :, 0] + th_m[i, :, 1], 3)):
            beta, c = _slopes(x, y[:, None])
            beta_m, _ = _slopes(x, ym)
            lo, hi = _interval(beta_m)
            d_lo, d_hi = _interval(th_m[i, :, col].mean(axis=0) - beta_m * np.pi / 2)
            row.update({f"{name}_exponent": float(beta[0]), f"{name}_exponent_lo95": float(lo),
                        f"{name}_exponent_hi95": float(hi), f"{name}_1hz_mN_per_m": float(np.exp(c[0])),
                        f"{name}_loss_angle_mean_rad": float(theta[i, col].mean()),
                        f"{name}_power_law_loss_angle_rad": float(beta[0] * np.pi / 2),
                        f"{name}_power_law_consistent": bool(d_lo <= 0.0 <= d_hi)})
        rows.append(row)
    cols = list(RHEOLOGY_COLUMNS) + ["n_frequencies"] + [f"{n}_{k}" for n in ("bulk", "shear") for k in
                                                         ("loss_angle_mean_rad", "power_law_loss_angle_rad",
                                                          "power_law_consistent")]
    return pd.DataFrame(rows, columns=cols)


EXPONENT_RANGE = (0.0, 0.9)      # the exponents a cell's cortex is replayed with


def power_law(log_f: Any, log_abs: Any, delta: Any) -> tuple[Any, Any]:
    """(β, ln |K*(1 Hz)|) of one cell's moduli at frequencies exp(`log_f`): the slope and value at
    1 Hz of the line through ln |K*| (`_slopes`, as `power_laws`; rows of `log_abs` and `delta`
    the frequencies, columns e.g. bootstrap draws); one frequency: β = 2δ/π (δ its loss angle)."""
    x, y = np.asarray(log_f, float), np.asarray(log_abs, float)
    if x.size > 1:
        return _slopes(x, y)
    slope = 2.0 * np.asarray(delta, float)[0] / np.pi
    return slope, y[0] - slope * x[0]


def modulus_1s(abs_1hz: Any, beta: Any) -> Any:
    """K(1 s) of the relaxation law K(t) = K(1 s) t^-β whose |K*(ω)| = K(1 s) Γ(1-β) ω^β has the
    value `abs_1hz` at 1 Hz: K(1 s) = |K*(1 Hz)| / (Γ(1-β) (2π)^β)."""
    from scipy.special import gamma
    return np.asarray(abs_1hz) / (gamma(1.0 - np.asarray(beta)) * (2 * np.pi) ** np.asarray(beta))


def cortex_laws(moduli: pd.DataFrame) -> pd.DataFrame:
    """Per cell the relaxation laws K(t) = K(1 s) t^-β its protocol is replayed with, from the
    point fits at each frequency (`point_moduli`: `bulk_abs`, `bulk_delta`, ...): β and ln |K*(1 Hz)|
    of `power_law`, β clipped to EXPONENT_RANGE, K(1 s) = `modulus_1s`, and γ_a the median
    tension. Columns `cell_id`, `tension`, `bulk_beta`, `bulk_1s`, `shear_beta`, `shear_1s`."""
    rows = []
    for cell, g in moduli.dropna(subset=["bulk_abs", "shear_abs", "bulk_delta", "shear_delta"]).groupby("cell_id"):
        x = np.log(g["frequency_hz"].to_numpy(float))
        row: dict[str, Any] = {"cell_id": cell, "tension": float(g["tension"].median())}
        for name in ("bulk", "shear"):
            y = np.log(g[f"{name}_abs"].to_numpy(float))[:, None]
            slope, at_1hz = (float(np.ravel(v)[0]) for v in power_law(x, y, g[f"{name}_delta"].to_numpy(float)))
            beta = float(np.clip(slope, *EXPONENT_RANGE))
            row[f"{name}_beta"] = beta
            row[f"{name}_1s"] = float(modulus_1s(np.exp(at_1hz), beta))
        rows.append(row)
    return pd.DataFrame(rows, columns=["cell_id", "tension", "bulk_beta", "bulk_1s", "shear_beta", "shear_1s"])


def paired_test(rheology: pd.DataFrame) -> dict[str, Any]:
    """The population of exponents and the Wilcoxon signed-rank test of β_S against β_B."""
    b, s = rheology["bulk_exponent"].to_numpy(float), rheology["shear_exponent"].to_numpy(float)
    out: dict[str, Any] = {"test": "Wilcoxon signed-rank, shear_exponent - bulk_exponent over the cells", "n_cells": int(b.size)}
    for name, x in (("bulk_exponent", b), ("shear_exponent", s)):
        q = np.percentile(x, [25, 50, 75]) if x.size else [np.nan] * 3
        out[name] = {"median": float(q[1]), "q25": float(q[0]), "q75": float(q[2])}
    if b.size < 2 or np.all(s - b == 0):
        out.update(median_difference=float(np.median(s - b)) if b.size else None, p_value_greater=None,
                   p_value_two_sided=None, shear_exponent_greater=None)
        return out
    out["median_difference"] = float(np.median(s - b))
    out["p_value_greater"] = float(wilcoxon(s, b, alternative="greater").pvalue)
    out["p_value_two_sided"] = float(wilcoxon(s, b).pvalue)
    out["shear_exponent_greater"] = bool(out["p_value_greater"] < 0.05)
    return out


def analyze(table: pd.DataFrame, segments: pd.DataFrame, model: ComplexModel, bending: str,
            errors: MeasurementErrors | None = None, lags: dict[float, float] | None = None,
            lag_source: str | None = None) -> tuple[pd.DataFrame, pd.DataFrame, dict[str, Any]]:
    """The viscoelastic reading with the complex forward model `model` (the calibration file's
    `ComplexModel`: emulator and complex-modulus table): (table with the per-frequency columns,
    rheology table, summary dict with the instrument phase and the paired test)."""
    cols, theta, th_m = per_frequency(table, segments, model.emulator, bending, model.table, errors, lags)
    table = pd.concat([table.reset_index(drop=True), cols], axis=1)
    rheology = power_laws(table, theta, th_m)
    summ = {"instrument_phase": lag_source or NO_LAG,
            "instrument_phase_rad": {str(f): v for f, v in sorted((lags or {}).items())},
            "paired_test": paired_test(rheology)}
    return table, rheology, summ


def markdown(rheology: pd.DataFrame, summ: dict[str, Any]) -> str:
    """report.md's section on the viscoelastic reading."""
    t = summ["paired_test"]
    lines = ["", "## Viscoelastic cortex (SPEC 10)", "",
             f"Instrument phase: {summ['instrument_phase']}.", "",
             f"{t['n_cells']} cells with >= {MIN_FREQUENCIES} frequencies (rheology.csv): power laws "
             "|K_B*| = K_B,1Hz f^beta_B, |K_S*| = K_S,1Hz f^beta_S.", ""]
    if t["n_cells"]:
        b, s = t["bulk_exponent"], t["shear_exponent"]
        lines += ["| exponent | median | quartiles |", "|---|---|---|",
                  f"| beta_B | {b['median']:.3f} | {b['q25']:.3f} - {b['q75']:.3f} |",
                  f"| beta_S | {s['median']:.3f} | {s['q25']:.3f} - {s['q75']:.3f} |", ""]
    if t.get("p_value_greater") is not None:
        lines.append(f"Wilcoxon signed-rank, beta_S - beta_B (median {t['median_difference']:.3f}): "
                     f"p = {t['p_value_greater']:.3g} for beta_S > beta_B, {t['p_value_two_sided']:.3g} two-sided.")
    return "\n".join(lines) + "\n"
