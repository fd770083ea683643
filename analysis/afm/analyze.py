"""Measured cells -> curves -> the cells table: what `cortex afm analyze` does
around the one inversion (`analysis.invert.method.Inversion.invert`).

`measure(cells)`, once for every variant: the segment moduli of every cell
(`analysis.afm.timeseries.segment_moduli`), the curves K(h̃) per cell and
frequency (`analysis.invert.curves.curves_of`: γ_a = mean over the segments at
that frequency of <γ_eff>, V the cell's volume), and per cell its tension
deviation: the segment means over the whole recording (all frequencies),
max |<γ_eff>_i - median| / median.

`cell_table(measured, inverted, law, tension_tolerance)`, per variant: the inversion's
table with the segments' count and median loss angle per curve, the tension filter
(a deviation above `tension_tolerance` excludes the cell with that reason; published,
the default: TENSION_TOLERANCE = 10 %, e.g. blebbing; inf lifts it) and `outside_calibration`: for the emulator its
`outside_emulator`; for the paper's law (`law` given) whether K̃_S or γ̃_a lies
outside the law's grid (the α-table axes; ν then rests on the log law's
extrapolation; None for a law without a table). The law's table keeps the
columns and the row order (the recordings') it has always had.

`inverted(measured, inversion, bending, errors, tension_tolerance)`: the cells table of one
variant (the curves inverted, then `cell_table`); `analyze_cells(cells, inversion, bending,
errors, tension_tolerance)`: `measure` and `inverted` at once -> (cells table, segments table).

`summarise(table)`: the population summary (`analysis.afm.population.summary`)
and, for a table with intervals, each frequency's bootstrap 95 % interval of the
median ν (`analysis.invert.intervals.median_table`) and its count of ν > 0.5.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from analysis.afm.timeseries import segment_moduli
from analysis.invert.curves import Curves, curves_of
from common.errors import InputError

if TYPE_CHECKING:
    from analysis.afm.cell import Cell
    from analysis.calibration.law import Law
    from analysis.invert.measurement_errors import MeasurementErrors
    from analysis.invert.method import Inversion

TENSION_TOLERANCE = 0.10     # the published filter: the default of `tension_tolerance` (`check_tolerance`)
LAW_COLUMNS = ["cell_id", "frequency_hz", "bending", "volume_um3", "tension_mN_per_m", "tension_deviation",
               "n_segments", "loss_angle_rad", "nu", "ks_tilde", "bulk_mN_per_m", "alpha", "r2", "gamma_tilde",
               "n_heights", "h_tilde_max", "excluded_reason", "outside_calibration"]


@dataclass(frozen=True)
class Measured:
    """The cells as the inversion sees them: `segments` (one row per oscillation segment, the
    recordings' order), `curves`, per curve `n_segments` and `loss_angle_rad` (their median),
    per cell `deviation` and `median_tension` (mN/m), and the cells' order."""

    segments: pd.DataFrame
    curves: Curves
    n_segments: np.ndarray
    loss_angle_rad: np.ndarray
    deviation: dict[str, float]
    median_tension: dict[str, float]
    order: list[str]


def measure(cells: list[Cell]) -> Measured:
    """The `Measured` of `cells` (InputError for a cell without oscillations:
    `analysis.afm.analyze_pipeline.read` sets such recordings aside)."""
    segs = []
    for c in cells:
        if not c.oscillations():
            raise InputError(f"cell '{c.cell_id}': no oscillation segment to analyse")
        s = pd.DataFrame(segment_moduli(c))
        s.insert(0, "cell_id", c.cell_id)
        s["volume_um3"] = c.volume_um3
        segs.append(s)
    return measured_of(pd.concat(segs, ignore_index=True), [c.cell_id for c in cells])


def measured_of(rows: pd.DataFrame, order: list[str]) -> Measured:
    """The `Measured` of the segment rows `rows` (with `volume_um3`) of the cells `order`."""
    med, dev = {}, {}
    for cell, s in rows.groupby("cell_id", sort=False):
        med[cell] = float(np.median(s["tension_mN_per_m"]))
        dev[cell] = _deviation(s["tension_mN_per_m"], med[cell])
    curves = curves_of(rows)
    grouped = rows.groupby(["cell_id", "frequency_hz"])
    idx = pd.MultiIndex.from_frame(curves.keys[["cell_id", "frequency_hz"]])
    return Measured(rows.drop(columns=["volume_um3"]), curves, grouped.size().reindex(idx).to_numpy(),
                    grouped["loss_angle_rad"].median().reindex(idx).to_numpy(), dev, med, order)


def _deviation(tension: pd.Series, median: float) -> float:
    return float(np.max(np.abs(tension - median)) / median) if median > 0 else np.inf


def check_tolerance(tension_tolerance: float) -> float:
    """`tension_tolerance` (a fraction; inf lifts the filter) if it is a number >= 0, else InputError."""
    if not tension_tolerance >= 0:          # NaN too
        raise InputError(f"the tension tolerance must be a fraction >= 0, or inf (got {tension_tolerance:g})")
    return float(tension_tolerance)


def cell_table(measured: Measured, inverted: pd.DataFrame, law: Law | None = None,
               tension_tolerance: float = TENSION_TOLERANCE) -> pd.DataFrame:
    """The cells table of one variant from `inverted` (`Inversion.invert(measured.curves, ...)`);
    `law`: the variant's law when the paper's law inverted; `tension_tolerance`: the largest
    tension deviation kept (module docstring)."""
    table = inverted.copy()
    table["tension_deviation"] = table["cell_id"].map(measured.deviation)
    table["n_segments"] = measured.n_segments
    table["loss_angle_rad"] = measured.loss_angle_rad
    if law is None:
        table["outside_calibration"] = table["outside_emulator"]
    else:
        table["outside_calibration"] = pd.Series(
            [_outside(law, k, g) for k, g in zip(table["ks_tilde"], table["gamma_tilde"])], dtype=object)
    _tension_filter(table, check_tolerance(tension_tolerance),
                    measured.median_tension if law is not None else None)
    if law is None:
        return table
    rank = {c: i for i, c in enumerate(measured.order)}
    table = table.sort_values("cell_id", key=lambda s: s.map(rank), kind="stable")
    return table[LAW_COLUMNS].reset_index(drop=True)


def _tension_filter(table: pd.DataFrame, tolerance: float, median: dict[str, float] | None) -> None:
    """Exclude, in place, every row of a cell whose tension deviation exceeds `tolerance`
    (the reason names the median tension when `median` is given)."""
    bad = table["tension_deviation"] > tolerance
    limit = f"(limit {100 * tolerance:.3g} %)"
    table.loc[bad, "excluded_reason"] = [
        f"average tension not constant: deviates {100 * d:.0f} % from its median "
        + (f"{median[c]:.3g} mN/m " if median is not None else "") + limit
        for c, d in zip(table.loc[bad, "cell_id"], table.loc[bad, "tension_deviation"])]


def _outside(law: Law, ks: float, gamma: float) -> bool | None:
    if not law.ks_tilde or not law.gamma_tilde or ks is None or gamma is None:
        return None
    if not (np.isfinite(ks) and np.isfinite(gamma)):
        return None
    return bool(not min(law.ks_tilde) <= ks <= max(law.ks_tilde)
                or not min(law.gamma_tilde) <= gamma <= max(law.gamma_tilde))


def has_intervals(table: pd.DataFrame) -> bool:
    """Whether the table holds each result's 95 % interval (the emulator's)."""
    return "nu_lo95" in table


def summarise(table: pd.DataFrame) -> dict[str, Any]:
    """The population summary of `table` (module docstring)."""
    from analysis.afm.population.summary import summary
    out = summary(table)
    if not has_intervals(table):
        return out
    from analysis.invert.intervals import median_table
    meds = {r["frequency_hz"]: r for r in median_table(table)}
    for r in out["frequencies"]:
        m = meds.get(r["frequency_hz"], {})
        r["median_nu_lo95"], r["median_nu_hi95"] = m.get("median_nu_lo95"), m.get("median_nu_hi95")
        r["n_nu_beyond_isotropic"] = int(((table["frequency_hz"] == r["frequency_hz"])
                                          & table["excluded_reason"].isna() & table["nu_beyond_isotropic"]).sum())
    return out


def inverted(measured: Measured, inversion: Inversion, bending: str, errors: MeasurementErrors | None = None,
             tension_tolerance: float = TENSION_TOLERANCE) -> pd.DataFrame:
    """The cells table of the curves of `measured` inverted with variant `bending`, the tension
    filter at `tension_tolerance`."""
    from analysis.invert.method import LawInversion
    law = inversion.calibration[bending] if isinstance(inversion, LawInversion) else None
    return cell_table(measured, inversion.invert(measured.curves, bending, errors), law, tension_tolerance)


def analyze_cells(cells: list[Cell], inversion: Inversion, bending: str = "standard",
                  errors: MeasurementErrors | None = None,
                  tension_tolerance: float = TENSION_TOLERANCE) -> tuple[pd.DataFrame, pd.DataFrame]:
    """`cells` measured and inverted with variant `bending`: (cells table, segments table)."""
    measured = measure(cells)
    return inverted(measured, inversion, bending, errors, tension_tolerance), measured.segments
