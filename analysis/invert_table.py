"""Invert a long table of K(h̃) per cell (and frequency) by either method, with
the 95 % intervals: the common core of `cortex analysis invert` and `cortex afm
analyze`.

Input rows: `cell_id, h_tilde, modulus_mN_per_m, tension_mN_per_m`, optional
`frequency_hz` (NaN: one curve per cell) and `volume_um3` (default 4300 µm³).
One curve per (cell_id, frequency_hz); its γ_a is the mean of its rows'
tensions, its V their first volume.

- `emulator` (default): K_B and K̃_S fitted on the emulator
  (`analysis.emulator_fit`), intervals by the parametric bootstrap of
  `analysis.intervals` (volume SD, height SD and draws are options);
- `law`: the paper's law and its inversion (`analysis.inversion`); no
  interval (NaN): it is kept to compare with published numbers.

Output: one row per curve with `cell_id, frequency_hz, nu, nu_lo95, nu_hi95,
ks_tilde, ks_lo95, ks_hi95, bulk_mN_per_m, r2, method, excluded_reason` and
the method's other columns.
"""

from dataclasses import dataclass

import numpy as np

from analysis import intervals
from analysis.emulator_fit import Curves, invert_curves_emulator
from analysis.inversion import invert_curves, to_curves, used_heights
from common.errors import InputError
from common.names import INVERSION_METHODS

METHODS = INVERSION_METHODS
DEFAULT_VOLUME_UM3 = 4300.0


@dataclass
class Errors:
    """The measurement errors an interval includes (defaults: the published ones)."""

    volume_rel_sd: float = intervals.VOLUME_SD
    height_sd_um: float = intervals.HEIGHT_SD_UM
    draws: int = intervals.DRAWS
    seed: int = 0

    def check(self):
        if not (0 <= self.volume_rel_sd < 0.5):
            raise InputError(f"--volume-sd must be in [0, 0.5) (got {self.volume_rel_sd:g})")
        if not (0 <= self.height_sd_um < 5):
            raise InputError(f"--height-sd must be in [0, 5) um (got {self.height_sd_um:g})")
        if not (10 <= self.draws <= 100_000):
            raise InputError(f"--draws must be in 10..100000 (got {self.draws})")
        return self


def _curves(rows):
    rows = rows.copy()
    if "frequency_hz" not in rows:
        rows["frequency_hz"] = np.nan
    if "volume_um3" not in rows:
        rows["volume_um3"] = DEFAULT_VOLUME_UM3
    rows["_f"] = rows["frequency_hz"].fillna(-1.0)
    keys, arr = to_curves(rows, ("cell_id", "_f"),
                          columns=("h_tilde", "modulus_mN_per_m", "tension_mN_per_m", "volume_um3"))
    tension = np.nanmean(arr["tension_mN_per_m"], axis=1)
    volume = arr["volume_um3"][:, 0]
    keys["frequency_hz"] = keys["_f"].where(keys["_f"] >= 0, np.nan)
    return keys.drop(columns=["_f", "n_rows"]), arr["h_tilde"], arr["modulus_mN_per_m"], tension, volume


def invert_rows(rows, method="emulator", calibration=None, emulator=None, bending="standard",
                errors=None):
    """Invert every curve of `rows` (DataFrame, columns as in the module docstring)."""
    if method not in METHODS:
        raise InputError(f"method must be one of {', '.join(METHODS)} (got {method!r})")
    keys, h, k, tension, volume = _curves(rows)
    if method == "law":
        if calibration is None:
            raise InputError("the calibration file holds no paper law ('variants'): use --method emulator")
        out = invert_curves(h, k, tension, calibration, bending)
        for col in ("nu_lo95", "nu_hi95", "ks_lo95", "ks_hi95"):
            out[col] = np.nan
    else:
        if emulator is None:
            raise InputError("the calibration file holds no emulator tables: use --method law, or a "
                             "calibration built by `make calibration` (cortex analysis build-calibration)")
        errors = (errors or Errors()).check()
        out = invert_curves_emulator(h, k, tension, volume, emulator, bending)
        use, _, _ = used_heights(h, k)
        theta = np.column_stack([np.log(out["bulk_mN_per_m"]), np.log(out["ks_tilde"])])
        ks_lo, ks_hi, nu_lo, nu_hi = intervals.cell_intervals(
            emulator, bending, theta, Curves(h, k, use, tension, volume), out["rms_mN_per_m"].to_numpy(),
            draws=errors.draws, volume_sd=errors.volume_rel_sd, height_sd_um=errors.height_sd_um,
            seed=errors.seed)
        out["nu_lo95"], out["nu_hi95"], out["ks_lo95"], out["ks_hi95"] = nu_lo, nu_hi, ks_lo, ks_hi
    out.insert(0, "cell_id", keys["cell_id"].to_numpy())
    out.insert(1, "frequency_hz", keys["frequency_hz"].to_numpy())
    out["tension_mN_per_m"], out["volume_um3"], out["method"], out["bending"] = tension, volume, method, bending
    first = ["cell_id", "frequency_hz", "nu", "nu_lo95", "nu_hi95", "ks_tilde", "ks_lo95", "ks_hi95",
             "bulk_mN_per_m", "r2", "method", "excluded_reason"]
    return out[first + [c for c in out.columns if c not in first]]


def median_table(table):
    """Per frequency: included cells, median ν and its bootstrap 95 % interval."""
    rows = []
    ok = table[table["excluded_reason"].isna()]
    for f, g in table.groupby(table["frequency_hz"].fillna(-1.0), sort=True):
        nu = ok.loc[ok.index.isin(g.index), "nu"].to_numpy(float)
        med, lo, hi = intervals.median_interval(nu)
        rows.append({"frequency_hz": float(f) if f >= 0 else None, "n_cells": int(nu.size),
                     "n_excluded": int(len(g) - nu.size), "median_nu": med, "median_nu_lo95": lo,
                     "median_nu_hi95": hi})
    return rows
