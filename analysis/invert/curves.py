"""Curves K(h̃), one per cell and frequency: what every inversion takes.

A long table (one row per height: `cell_id, h_tilde, modulus_mN_per_m,
tension_mN_per_m, volume_um3` and optional `frequency_hz`, NaN: one curve per
cell) becomes one curve per (cell_id, frequency_hz), sorted by both: its
heights h̃ in rising order, its moduli K (mN/m), NaN-padded to the longest;
its γ_a the mean of its rows' tensions; its V the first row's volume (checked
where the rows are made: `analysis.invert.table_input` for a table,
`analysis.afm.cell.Cell.validate` for a recording).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import pandas as pd

from analysis.invert.inversion import to_curves

Array = npt.NDArray[np.float64]


@dataclass(frozen=True)
class Curves:
    """`keys`: cell_id and frequency_hz per curve; `h_tilde`, `modulus_mN_per_m` of shape
    (curves, heights), NaN-padded; `tension_mN_per_m` (γ_a) and `volume_um3` per curve."""

    keys: pd.DataFrame
    h_tilde: Array
    modulus_mN_per_m: Array
    tension_mN_per_m: Array
    volume_um3: Array

    def __len__(self) -> int:
        return len(self.keys)


def curves_of(rows: pd.DataFrame) -> Curves:
    """The `Curves` of a long table `rows` (module docstring)."""
    rows = rows.copy()
    if "frequency_hz" not in rows:
        rows["frequency_hz"] = np.nan
    rows["_f"] = rows["frequency_hz"].fillna(-1.0)
    keys, arr = to_curves(rows, ("cell_id", "_f"),
                          columns=("h_tilde", "modulus_mN_per_m", "tension_mN_per_m", "volume_um3"))
    tension = np.nanmean(arr["tension_mN_per_m"], axis=1)
    volume = arr["volume_um3"][:, 0]
    keys["frequency_hz"] = keys["_f"].where(keys["_f"] >= 0, np.nan)
    return Curves(keys.drop(columns=["_f", "n_rows"]), arr["h_tilde"], arr["modulus_mN_per_m"], tension, volume)
