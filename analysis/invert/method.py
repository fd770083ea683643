"""The two inversion methods behind one interface, chosen once by name
(`INVERSIONS`, keyed by `common.names.INVERSION_METHODS`).

An `Inversion` turns curves K(h̃) of cells into ν, K̃_S and K_B:

- `EmulatorInversion` fits K_B and K̃_S on the emulator (`analysis.invert.emulator_fit`)
  and gives every curve a 95 % interval by the parametric bootstrap of
  `analysis.invert.intervals` (all curves at once: the draws are shared);
- `LawInversion` fits K(h̃) = K_B (1 + α exp(h̃/λ)) and inverts the paper's law
  (`analysis.invert.inversion`), all curves at once; no interval: it is kept to
  compare with published numbers.

Callers ask the object its bending `variants()` and its inversion of curves
(`invert(curves, bending, errors)`: `analysis.invert.curves.Curves` in, one row per
curve out); what a table of results means for a population, a report or a figure
is the caller's to read from the table.

`of(calibration, emulator)` builds the one a calibration file serves (None where
the file lacks the part it `needs`); `choose(method, ...)` builds one by name,
`invert_rows(rows, method, ...)` inverts a long table of curves by name
(`analysis.invert.table`).

Output of `invert`: one row per curve with `cell_id, frequency_hz, nu, nu_lo95,
nu_hi95, ks_tilde, ks_lo95, ks_hi95, bulk_mN_per_m, r2, method, excluded_reason`,
the method's other columns, then `tension_mN_per_m, volume_um3, bending`.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import TYPE_CHECKING, ClassVar

import numpy as np
import numpy.typing as npt
import pandas as pd

from analysis.invert import intervals
from analysis.invert.curves import Curves, curves_of
from analysis.invert.emulator_fit import CurveArrays, invert_curves_emulator
from analysis.invert.inversion import invert_curves, used_heights
from analysis.invert.measurement_errors import MeasurementErrors
from common.errors import InputError
from common.names import INVERSION_METHODS

if TYPE_CHECKING:
    from analysis.calibration.law import Calibration
    from analysis.calibration.emulator import Emulator

Array = npt.NDArray[np.float64]
INTERVAL_COLUMNS = ("nu_lo95", "nu_hi95", "ks_lo95", "ks_hi95", "ln_ks_se")
FIRST_COLUMNS = ("cell_id", "frequency_hz", "nu", "nu_lo95", "nu_hi95", "ks_tilde", "ks_lo95", "ks_hi95",
                 "bulk_mN_per_m", "r2", "method", "excluded_reason")


class Inversion(ABC):
    """One inversion method over the part of a calibration file it needs."""

    name: ClassVar[str]         # as `--method` names it
    needs: ClassVar[str]        # the part of the calibration file it needs, as messages name it
    instead: ClassVar[str]      # the method a file without that part serves
    refusal: ClassVar[str]      # `cortex analysis invert`'s one line when the file lacks that part

    @classmethod
    @abstractmethod
    def of(cls, calibration: Calibration | None, emulator: Emulator | None) -> Inversion | None:
        """The inversion a calibration file's parts serve; None if it lacks the part `needs` names."""

    @abstractmethod
    def variants(self) -> list[str]:
        """The bending variants it can invert with."""

    def invert(self, curves: Curves, bending: str, errors: MeasurementErrors | None = None) -> pd.DataFrame:
        """Invert `curves` with the bending variant `bending` (`errors`: what the 95 % intervals
        include): one row per curve, columns as in the module docstring (intervals NaN where
        the method gives none)."""
        out = self._fit(curves.h_tilde, curves.modulus_mN_per_m, curves.tension_mN_per_m, curves.volume_um3,
                        bending, errors)
        out.insert(0, "cell_id", curves.keys["cell_id"].to_numpy())
        out.insert(1, "frequency_hz", curves.keys["frequency_hz"].to_numpy())
        out["tension_mN_per_m"], out["volume_um3"] = curves.tension_mN_per_m, curves.volume_um3
        out["method"], out["bending"] = self.name, bending
        return out[list(FIRST_COLUMNS) + [c for c in out.columns if c not in FIRST_COLUMNS]]

    @abstractmethod
    def _fit(self, h: Array, k: Array, tension: Array, volume: Array, bending: str,
             errors: MeasurementErrors | None) -> pd.DataFrame:
        """h̃ and K (mN/m) of shape (curves, heights), NaN-padded; γ_a (mN/m) and V (µm³) per
        curve. One row per curve: ν, K̃_S, K_B, R², excluded_reason, the 95 % intervals and the
        method's own columns."""


class LawInversion(Inversion):
    """The paper's law of a `Calibration`, all curves at once, without intervals."""

    name = "law"
    needs = "paper law"
    instead = "emulator"
    refusal = "the calibration file holds no paper law ('variants'): use --method emulator"

    def __init__(self, calibration: Calibration) -> None:
        self.calibration = calibration

    @classmethod
    def of(cls, calibration: Calibration | None, emulator: Emulator | None) -> LawInversion | None:
        return None if calibration is None else cls(calibration)

    def variants(self) -> list[str]:
        return list(self.calibration.laws)

    def _fit(self, h: Array, k: Array, tension: Array, volume: Array, bending: str,
             errors: MeasurementErrors | None) -> pd.DataFrame:
        out = invert_curves(h, k, tension, self.calibration, bending)
        for col in INTERVAL_COLUMNS:
            out[col] = np.nan
        return out


class EmulatorInversion(Inversion):
    """K_B and K̃_S fitted on an `Emulator`, all curves at once, with 95 % intervals."""

    name = "emulator"
    needs = "emulator tables"
    instead = "law"
    refusal = ("the calibration file holds no emulator tables: use --method law, or a "
               "calibration built by `make calibration` (cortex analysis build-calibration)")

    def __init__(self, emulator: Emulator) -> None:
        self.emulator = emulator

    @classmethod
    def of(cls, calibration: Calibration | None, emulator: Emulator | None) -> EmulatorInversion | None:
        return None if emulator is None else cls(emulator)

    def variants(self) -> list[str]:
        return list(self.emulator.tables)

    def _fit(self, h: Array, k: Array, tension: Array, volume: Array, bending: str,
             errors: MeasurementErrors | None) -> pd.DataFrame:
        errors = (errors or MeasurementErrors()).check()
        out = invert_curves_emulator(h, k, tension, volume, self.emulator, bending)
        use, _, _ = used_heights(h, k)
        theta = np.column_stack([np.log(out["bulk_mN_per_m"]), np.log(out["ks_tilde"])])
        ks_lo, ks_hi, nu_lo, nu_hi, ln_ks_se = intervals.cell_intervals(
            self.emulator, bending, theta, CurveArrays(h, k, use, tension, volume), out["rms_mN_per_m"].to_numpy(),
            draws=errors.draws, volume_sd=errors.volume_rel_sd, height_sd_um=errors.height_sd_um,
            seed=errors.seed)
        out["nu_lo95"], out["nu_hi95"], out["ks_lo95"], out["ks_hi95"] = nu_lo, nu_hi, ks_lo, ks_hi
        out["ln_ks_se"] = ln_ks_se
        return out


INVERSIONS: dict[str, type[Inversion]] = {c.name: c for c in (EmulatorInversion, LawInversion)}
assert tuple(INVERSIONS) == INVERSION_METHODS, "one implementation per name of common.names"


def choose(method: str, calibration: Calibration | None, emulator: Emulator | None,
           where: str | None = None) -> Inversion:
    """The `method` inversion of a calibration file's parts; InputError (one line) for another
    name, or, if the file lacks the part it needs, the method's `refusal` (`where` given: the
    file's name, what it lacks and the method it serves instead)."""
    if method not in INVERSIONS:
        raise InputError(f"method must be one of {', '.join(INVERSIONS)} (got {method!r})")
    kind = INVERSIONS[method]
    inversion = kind.of(calibration, emulator)
    if inversion is None:
        raise InputError(kind.refusal if where is None else f"{where}: holds no {kind.needs}; use --method {kind.instead}")
    return inversion


def invert_rows(rows: pd.DataFrame, method: str = "emulator", calibration: Calibration | None = None,
                emulator: Emulator | None = None, bending: str = "standard",
                errors: MeasurementErrors | None = None) -> pd.DataFrame:
    """Invert every curve of the long table `rows` (`analysis.invert.curves`) by the method named `method`."""
    return choose(method, calibration, emulator).invert(curves_of(rows), bending, errors)
