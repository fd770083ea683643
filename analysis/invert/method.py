"""The two inversion methods behind one interface, chosen once by name
(`INVERSIONS`, keyed by `common.names.INVERSION_METHODS`).

An `Inversion` turns curves K(h̃) of cells into ν, K̃_S and K_B:

- `EmulatorInversion` fits K_B and K̃_S on the emulator (`analysis.invert.emulator_fit`)
  and gives every curve a 95 % interval by the parametric bootstrap of
  `analysis.invert.intervals` (all curves at once: the draws are shared), every
  frequency's median ν one too;
- `LawInversion` fits K(h̃) = K_B (1 + α exp(h̃/λ)) and inverts the paper's law
  (`analysis.invert.inversion`), one curve at a time; no interval: it is kept to
  compare with published numbers.

Callers ask the object: its bending `variants()`, its inversion of curves
(`invert`), of measured cells (`analyze_cells`: the law hands them to the
caller's `analyze_each`, the emulator to its `analyze_together`; for
`cortex afm analyze` those of `analysis.afm.analyze`), what it adds to a summary
(`summarise`), to a report (`report`) and to the figures (`figures`: the
emulator draws its intervals with the figure the caller gives).

`of(calibration, emulator)` builds the one a calibration file serves (None where
the file lacks the part it `needs`); `choose(method, ...)` builds one by name,
`invert_rows(rows, method, ...)` inverts a table of curves by name
(`analysis.invert.table`).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar, Protocol

import numpy as np
import numpy.typing as npt
import pandas as pd

from analysis.invert import intervals
from analysis.invert.emulator_fit import Curves, invert_curves_emulator
from analysis.invert.inversion import invert_curves, used_heights
from analysis.invert.measurement_errors import MeasurementErrors
from analysis.invert.table import invert_with
from common.errors import InputError
from common.names import INVERSION_METHODS

if TYPE_CHECKING:
    from analysis.afm.cell import Cell
    from analysis.calibration.law import Calibration
    from analysis.calibration.emulator import Emulator

Array = npt.NDArray[np.float64]
INTERVAL_COLUMNS = ("nu_lo95", "nu_hi95", "ks_lo95", "ks_hi95", "ln_ks_se")
Tables = tuple[pd.DataFrame, pd.DataFrame]


class CellAnalyses(Protocol):
    """How a caller analyses measured cells (`analysis.afm.analyze`): one cell at a time by
    a law, or all at once by an inversion with intervals; each gives (per cell-and-frequency
    table, per-segment table)."""

    def analyze_each(self, cells: list[Cell], calibration: Calibration, bending: str = ...) -> Tables: ...

    def analyze_together(self, cells: list[Cell], inversion: Any, bending: str = ...,
                         errors: MeasurementErrors | None = ...) -> Tables: ...


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

    @abstractmethod
    def invert(self, h: Array, k: Array, tension: Array, volume: Array, bending: str,
               errors: MeasurementErrors | None) -> pd.DataFrame:
        """Invert curves: h̃ and K (mN/m) of shape (curves, heights), NaN-padded; γ_a (mN/m) and
        V (µm³) per curve. One row per curve: ν, K̃_S, K_B, R², excluded_reason, the 95 %
        intervals (NaN where the method gives none) and the method's own columns."""

    @abstractmethod
    def analyze_cells(self, cells: list[Cell], bending: str, errors: MeasurementErrors | None,
                      analyses: CellAnalyses) -> Tables:
        """Measured cells by the caller's `analyses`: (per cell-and-frequency table, per-segment table)."""

    def summarise(self, summary: dict[str, Any], table: pd.DataFrame) -> dict[str, Any]:
        """The population summary of `table` with what the method adds to it."""
        return summary

    def report(self, bending: str, summary: dict[str, Any]) -> list[str]:
        """The lines the method adds to report.md (before the population table)."""
        return []

    def figures(self, table: pd.DataFrame, out: Any, intervals_figure: Callable[[pd.DataFrame, Any], Path]
                ) -> list[Path]:
        """The figures the method adds into the `OutputDir` `out` (`intervals_figure`: the
        caller's figure of each cell's 95 % interval)."""
        return []


class LawInversion(Inversion):
    """The paper's law of a `Calibration`, one curve at a time, without intervals."""

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

    def invert(self, h: Array, k: Array, tension: Array, volume: Array, bending: str,
               errors: MeasurementErrors | None) -> pd.DataFrame:
        out = invert_curves(h, k, tension, self.calibration, bending)
        for col in INTERVAL_COLUMNS:
            out[col] = np.nan
        return out

    def analyze_cells(self, cells: list[Cell], bending: str, errors: MeasurementErrors | None,
                      analyses: CellAnalyses) -> Tables:
        return analyses.analyze_each(cells, self.calibration, bending)


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

    def invert(self, h: Array, k: Array, tension: Array, volume: Array, bending: str,
               errors: MeasurementErrors | None) -> pd.DataFrame:
        errors = (errors or MeasurementErrors()).check()
        out = invert_curves_emulator(h, k, tension, volume, self.emulator, bending)
        use, _, _ = used_heights(h, k)
        theta = np.column_stack([np.log(out["bulk_mN_per_m"]), np.log(out["ks_tilde"])])
        ks_lo, ks_hi, nu_lo, nu_hi, ln_ks_se = intervals.cell_intervals(
            self.emulator, bending, theta, Curves(h, k, use, tension, volume), out["rms_mN_per_m"].to_numpy(),
            draws=errors.draws, volume_sd=errors.volume_rel_sd, height_sd_um=errors.height_sd_um,
            seed=errors.seed)
        out["nu_lo95"], out["nu_hi95"], out["ks_lo95"], out["ks_hi95"] = nu_lo, nu_hi, ks_lo, ks_hi
        out["ln_ks_se"] = ln_ks_se
        return out

    def analyze_cells(self, cells: list[Cell], bending: str, errors: MeasurementErrors | None,
                      analyses: CellAnalyses) -> Tables:
        return analyses.analyze_together(cells, self, bending, errors)

    def summarise(self, summary: dict[str, Any], table: pd.DataFrame) -> dict[str, Any]:
        """Each frequency's bootstrap 95 % interval of the median ν and its count of ν > 0.5."""
        meds = {r["frequency_hz"]: r for r in intervals.median_table(table)}
        for r in summary["frequencies"]:
            m = meds.get(r["frequency_hz"], {})
            r["median_nu_lo95"], r["median_nu_hi95"] = m.get("median_nu_lo95"), m.get("median_nu_hi95")
            r["n_nu_beyond_isotropic"] = int(((table["frequency_hz"] == r["frequency_hz"])
                                              & table["excluded_reason"].isna() & table["nu_beyond_isotropic"]).sum())
        return summary

    def report(self, bending: str, summary: dict[str, Any]) -> list[str]:
        """The median ν per frequency with its interval, and what a cell's interval includes."""
        lines = [f"Median ν per frequency with its bootstrap 95 % interval (variant `{bending}`):", "",
                 "| f (Hz) | cells | median ν | 95 % interval | cells with ν > 0.5 |", "|---|---|---|---|---|"]
        for r in summary["frequencies"]:
            lo, hi = r.get("median_nu_lo95"), r.get("median_nu_hi95")
            ci = f"[{lo:.3f}, {hi:.3f}]" if lo is not None and np.isfinite(lo) else "–"
            med = f"{r['median_nu']:.3f}" if r["median_nu"] is not None else "–"
            lines.append(f"| {r['frequency_hz']:g} | {r['n_cells']} | {med} | {ci} | "
                         f"{r.get('n_nu_beyond_isotropic', 0)} |")
        return lines + ["", "Each cell's 95 % interval (`nu_lo95`, `nu_hi95` in cells.csv) includes the volume "
                        "and height errors and the fit's residuals (parametric bootstrap through the emulator).", ""]

    def figures(self, table: pd.DataFrame, out: Any, intervals_figure: Callable[[pd.DataFrame, Any], Path]
                ) -> list[Path]:
        return [intervals_figure(table, out)]


INVERSIONS: dict[str, type[Inversion]] = {c.name: c for c in (EmulatorInversion, LawInversion)}
assert tuple(INVERSIONS) == INVERSION_METHODS, "one implementation per name of common.names"


def choose(method: str, calibration: Calibration | None, emulator: Emulator | None) -> Inversion:
    """The `method` inversion of a calibration file's parts; InputError (one line) for another
    name, or the method's `refusal` if the file lacks the part it needs."""
    if method not in INVERSIONS:
        raise InputError(f"method must be one of {', '.join(INVERSIONS)} (got {method!r})")
    inversion = INVERSIONS[method].of(calibration, emulator)
    if inversion is None:
        raise InputError(INVERSIONS[method].refusal)
    return inversion


def invert_rows(rows: pd.DataFrame, method: str = "emulator", calibration: Calibration | None = None,
                emulator: Emulator | None = None, bending: str = "standard",
                errors: MeasurementErrors | None = None) -> pd.DataFrame:
    """Invert every curve of `rows` (`analysis.invert.table`) by the method named `method`."""
    return invert_with(choose(method, calibration, emulator), rows, bending, errors)
