"""Invert a long table of K(h̃) per cell (and frequency), with the 95 % intervals:
what `cortex analysis invert` does with the table `analysis.invert.table_input` reads.

Input rows: `cell_id, h_tilde, modulus_mN_per_m, tension_mN_per_m, volume_um3`
and optional `frequency_hz` (NaN: one curve per cell), made into curves by
`analysis.invert.curves.curves_of`. `invert_with(inversion, rows, ...)` inverts
every curve by an `Inversion` (`analysis.invert.method`: the emulator with
intervals, or the paper's law without, NaN), the same `Inversion.invert`
`cortex afm analyze` calls; `invert_rows(rows, method, ...)`
(`analysis.invert.method`) picks the inversion by name.

Output: one row per curve with `cell_id, frequency_hz, nu, nu_lo95, nu_hi95,
ks_tilde, ks_lo95, ks_hi95, bulk_mN_per_m, r2, method, excluded_reason` and
the method's other columns.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import pandas as pd

from analysis.invert.curves import curves_of
from analysis.invert.measurement_errors import MeasurementErrors
from common.names import INVERSION_METHODS

if TYPE_CHECKING:
    from analysis.invert.method import Inversion

METHODS = INVERSION_METHODS
__all__ = ["METHODS", "invert_with"]


def invert_with(inversion: Inversion, rows: pd.DataFrame, bending: str = "standard",
                errors: MeasurementErrors | None = None) -> pd.DataFrame:
    """Invert every curve of `rows` (DataFrame, columns as in the module docstring) by `inversion`."""
    return inversion.invert(curves_of(rows), bending, errors)
