"""The parts of a calibration bundle `cortex afm tension` reads, chosen once from the bundle
`--calibration` names (read by the one loader, `analysis.calibration.file.load_calibration`):
a part the bundle names replaces the shipped bundle's, a part it does not name is the shipped
bundle's, and every shell row says which (`TensionCalibration.columns`).

    shell ramp table   the shell model's (`shell_ramp`): the bundle's `ramp_table` part where its
                       manifest names one (its own file, or "shipped"), else the shipped one
    power-law table    the power-law reading's tabled simulator (`powerlaw_tabled`): the bundle's
                       `powerlaw_table` part where its manifest names one, else the shipped one
    oscillations       the bundle whose emulator and complex-modulus table read the recording's
                       oscillations for the shell's priors (`priors.read_laws`): the given one
                       where it names both parts, else the shipped one

Each table's file is identified by its SHA-256 (the first SHA_DIGITS hex digits).
"""

import hashlib
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

from analysis.calibration.file import CalibrationFile, load_calibration
from analysis.calibration.powerlaw_table import PowerLawTable
from analysis.calibration.ramp_table import ShellTable

SHA_DIGITS = 16
SHIPPED = "shipped"          # a source: the shipped bundle's part (as `CalibrationFile.sources` says it)
OSCILLATION_PARTS = ("emulator", "viscoelastic_table")


@dataclass(frozen=True)
class TensionCalibration:
    """The shell ramp table with where it came from (SHIPPED or its file's path) and its file's
    SHA-256, the bundle the priors' viscoelastic reading reads, and the power-law table with its
    source and SHA-256 (module doc)."""

    table: ShellTable
    table_source: str
    table_sha256: str
    oscillations: CalibrationFile
    powerlaw: PowerLawTable
    powerlaw_source: str
    powerlaw_sha256: str

    def columns(self) -> dict[str, str]:
        """A shell row's columns: `shell_table_source`, `shell_table_sha256`,
        `prior_calibration_source` (SHIPPED or the bundle's path), `powerlaw_table_source` and
        `powerlaw_table_sha256`."""
        osc = SHIPPED if set(OSCILLATION_PARTS) <= {p for p, s in self.oscillations.sources.items()
                                                     if s == SHIPPED} else self.oscillations.where
        return {"shell_table_source": self.table_source, "shell_table_sha256": self.table_sha256,
                "prior_calibration_source": osc, "powerlaw_table_source": self.powerlaw_source,
                "powerlaw_table_sha256": self.powerlaw_sha256}


def tension_calibration(bundle: CalibrationFile | None = None) -> TensionCalibration:
    """The parts of `bundle` (None: the shipped bundle) the tension reading uses (module doc);
    InputError (one line) where a part the bundle names is missing or malformed."""
    shipped = load_calibration(None)
    given = shipped if bundle is None else bundle
    with_table = given if "ramp_table" in given.sources else shipped
    with_powerlaw = given if "powerlaw_table" in given.sources else shipped
    oscillations = given if all(p in given.sources for p in OSCILLATION_PARTS) else shipped
    return TensionCalibration(with_table.shell_ramp, with_table.sources["ramp_table"], _digest(with_table, "ramp_table"),
                              oscillations, with_powerlaw.powerlaw, with_powerlaw.sources["powerlaw_table"],
                              _digest(with_powerlaw, "powerlaw_table"))


def _digest(bundle: CalibrationFile, part: str) -> str:
    """The first SHA_DIGITS hex digits of the SHA-256 of a part's file."""
    return hashlib.sha256(Path(bundle.files[part]).read_bytes()).hexdigest()[:SHA_DIGITS]


@lru_cache(maxsize=1)
def shipped_parts() -> TensionCalibration:
    """The shipped bundle's parts (read once per process): what a reading without a bundle uses."""
    return tension_calibration(None)
