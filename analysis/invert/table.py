"""Invert a long table of K(h̃) per cell (and frequency), with the 95 % intervals:
the common core of `cortex analysis invert` and `cortex afm analyze`.

Input rows: `cell_id, h_tilde, modulus_mN_per_m, tension_mN_per_m, volume_um3`
and optional `frequency_hz` (NaN: one curve per cell). One curve per
(cell_id, frequency_hz); its γ_a is the mean of its rows' tensions, its V their
first volume (checked where the rows are made: `analysis.invert.table_input`
for a table, `analysis.afm.cell.Cell.validate` for a recording).

`invert_with(inversion, rows, ...)` inverts every curve by an `Inversion`
(`analysis.invert.method`): the emulator with intervals, or the paper's law
without (NaN); `invert_rows(rows, method, ...)` (`analysis.invert.method`) picks
the inversion by name.

Output: one row per curve with `cell_id, frequency_hz, nu, nu_lo95, nu_hi95,
ks_tilde, ks_lo95, ks_hi95, bulk_mN_per_m, r2, method, excluded_reason` and
the method's other columns.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np
import numpy.typing as npt
import pandas as pd

from analysis.invert.measurement_errors import MeasurementErrors
from analysis.invert.inversion import to_curves
from common.names import INVERSION_METHODS

METHODS = INVERSION_METHODS
__all__ = ["METHODS", "MeasurementErrors", "CurveInversion", "curves", "invert_with"]

Array = npt.NDArray[np.float64]


class CurveInversion(Protocol):
    """What this module asks of an inversion (`analysis.invert.method.Inversion`): its name
    and its inversion of curves."""

    @property
    def name(self) -> str: ...

    def invert(self, h: Array, k: Array, tension: Array, volume: Array, bending: str,
               errors: MeasurementErrors | None) -> pd.DataFrame: ...


def curves(rows: pd.DataFrame) -> tuple[pd.DataFrame, Array, Array, Array, Array]:
    """(keys: cell_id and frequency_hz per curve, h̃, K, γ_a, V) of `rows` (module docstring)."""
    rows = rows.copy()
    if "frequency_hz" not in rows:
        rows["frequency_hz"] = np.nan
    rows["_f"] = rows["frequency_hz"].fillna(-1.0)
    keys, arr = to_curves(rows, ("cell_id", "_f"),
                          columns=("h_tilde", "modulus_mN_per_m", "tension_mN_per_m", "volume_um3"))
    tension = np.nanmean(arr["tension_mN_per_m"], axis=1)
    volume = arr["volume_um3"][:, 0]
    keys["frequency_hz"] = keys["_f"].where(keys["_f"] >= 0, np.nan)
    return keys.drop(columns=["_f", "n_rows"]), arr["h_tilde"], arr["modulus_mN_per_m"], tension, volume


def invert_with(inversion: CurveInversion, rows: pd.DataFrame, bending: str = "standard",
                errors: MeasurementErrors | None = None) -> pd.DataFrame:
    """Invert every curve of `rows` (DataFrame, columns as in the module docstring) by `inversion`."""
    keys, h, k, tension, volume = curves(rows)
    out = inversion.invert(h, k, tension, volume, bending, errors)
    out.insert(0, "cell_id", keys["cell_id"].to_numpy())
    out.insert(1, "frequency_hz", keys["frequency_hz"].to_numpy())
    out["tension_mN_per_m"], out["volume_um3"], out["method"], out["bending"] = tension, volume, inversion.name, bending
    first = ["cell_id", "frequency_hz", "nu", "nu_lo95", "nu_hi95", "ks_tilde", "ks_lo95", "ks_hi95",
             "bulk_mN_per_m", "r2", "method", "excluded_reason"]
    return out[first + [c for c in out.columns if c not in first]]
