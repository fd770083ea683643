"""The calibration file: every part a command takes to read cells (the paper law, the
emulator, the complex-modulus table), loaded once by the one loader, `load_calibration`.

Layout of the file (a JSON document, versioned):

    format      "cortex-calibration"
    version     2 (1: law only, as `cortex analysis calibrate` writes)
    variants    the paper law per bending variant (λ, C, D, α table, goodness)
    emulator    per bending variant: axes volume_um3, h_tilde, ks_tilde, gamma_tilde,
                k_over_kb (nested lists in that axis order), dh_um, thickness_um
    provenance  per part (`emulator`, `law`): the campaign file's text, the
                store's fingerprint, the code version that ran it and when;
                `built`: the date and code version of this file

`build` makes the document from two finished stores (`make calibration`);
`load_calibration` reads one (None: the shipped default, `SHIPPED_NAME`) once into a
`CalibrationFile`: a `Calibration` (or None), an `Emulator` (or None, for a law-only
file), the provenance and where it came from, and (read on its first use) the
viscoelastic reading's `ComplexModel`: the complex-modulus table of the solver alone
(`viscoelastic_table`, no campaign behind it, so one table shipped in the package,
`TABLE_NAME`) with the file's emulator, or the shipped emulator for a law-only file;
and (read on its first use) the tension analysis's shell ramp table (`ramp_table`, built
by its own campaign, shipped in the package as `ramp_table.NAME`).
Every command reads the file here once and hands its parts on; no other code opens it.
"""

import json
import time
from dataclasses import dataclass
from functools import cached_property
from importlib import resources
from importlib.metadata import version
from os import PathLike
from pathlib import Path
from typing import Any, Callable

from analysis.calibration.emulator import Emulator, from_results
from analysis.calibration.law import FORMAT, Calibration, _nan_to_none, read_document
from analysis.calibration.ramp_table import NAME as RAMP_TABLE_NAME
from analysis.calibration.ramp_table import ShellTable
from analysis.calibration.ramp_table import read as read_ramp_table
from analysis.calibration.viscoelastic_table import ComplexTable
from common.errors import InputError

VERSION = 2
SHIPPED_NAME = "calibration.json"
TABLE_NAME = "viscoelastic_table.json"          # the complex-modulus table (`viscoelastic_table`)


SHIPPED_WHERE = "the shipped calibration"      # how messages name the default file


@dataclass(frozen=True)
class ComplexModel:
    """The complex forward model K* = K_sec · C of a viscoelastic cell (SPEC 10): the
    emulator's K_sec and the complex-modulus table's C."""

    emulator: Emulator
    table: ComplexTable


@dataclass(frozen=True)
class CalibrationFile:
    """A calibration file as read: its laws and its emulator (either may be None, not both),
    its provenance, and how messages name it (the path given, or `SHIPPED_WHERE`)."""

    calibration: Calibration | None
    emulator: Emulator | None
    provenance: dict[str, Any]
    where: str

    @cached_property
    def viscoelastic(self) -> ComplexModel:
        """The viscoelastic reading's forward model (read on first use): this file's emulator
        (the shipped one for a law-only file) and the shipped complex-modulus table."""
        emulator = self.emulator if self.emulator is not None else load_calibration(None).emulator
        assert emulator is not None, "the shipped calibration holds the emulator"
        return ComplexModel(emulator, _complex_table(shipped_path(TABLE_NAME)))

    @cached_property
    def shell_ramp(self) -> ShellTable:
        """The shell ramp table of `cortex afm tension` (read on first use): the shipped one."""
        return read_ramp_table(shipped_path(RAMP_TABLE_NAME))


def shipped_path(name: str = SHIPPED_NAME) -> Path:
    """A file shipped inside the installed package (default: the calibration file)."""
    return Path(str(resources.files("analysis.calibration") / "data" / name))


def _store_provenance(path: str | PathLike[str]) -> dict[str, Any]:
    from campaign.store.reader import read_provenance
    p = read_provenance(path)
    return {"store": Path(path).name, "campaign_text": p.get("config_text", ""),
            "fingerprint": p.get("fingerprint", ""), "code_version": p.get("code_version", ""),
            "run_date": p.get("created", ""), "versions": p.get("versions", "")}


def build(emulator_store: str | PathLike[str], law_store: str | PathLike[str] | None = None,
          progress: Callable[[str], None] | None = None) -> dict[str, Any]:
    """The calibration document from an emulator campaign's store and (optionally)
    the paper campaign's store (its law fitted by `analysis.calibration.law.calibrate`)."""
    from analysis.calibration.law import calibrate
    from analysis.calibration.command.pipeline import read_store
    results, _ = read_store(emulator_store)
    emulator = from_results(results, progress)
    doc: dict[str, Any] = {"format": FORMAT, "version": VERSION, "variants": {},
           "emulator": emulator.to_json(),
           "provenance": {"emulator": _store_provenance(emulator_store),
                          "built": {"date": time.strftime("%Y-%m-%d"), "code_version": version("cortex-poisson")}}}
    if law_store is not None:
        law_results, _ = read_store(law_store)
        done = law_results[law_results["state"] == "done"]
        if len(done) < len(law_results):
            raise InputError(f"{law_store}: {len(law_results) - len(done)} task(s) not done")
        cal, _, _ = calibrate(done, progress)
        doc["variants"] = cal.to_json()["variants"]
        doc["provenance"]["law"] = _store_provenance(law_store)
    return _nan_to_none(doc)


def write(doc: dict[str, Any], path: str | PathLike[str]) -> Path:
    """Write the document (atomic replace, `outputs.writing`: a full disk is a
    WriteError naming `path`; the caller has checked that `path` is ours)."""
    from outputs.writing import write_atomically
    text = json.dumps(doc, indent=None, separators=(",", ":")) + "\n"
    return Path(write_atomically(path, text.encode()))


def load_calibration(path: str | PathLike[str] | None = None) -> CalibrationFile:
    """The calibration file at `path` (None: the shipped default), read and parsed once.
    Malformed: InputError (one line)."""
    where = str(path) if path is not None else SHIPPED_WHERE
    path = Path(path) if path is not None else shipped_path()
    doc = read_document(path)
    cal = Calibration.from_document(path, doc) if doc.get("variants") else None
    emu = Emulator.from_json(doc["emulator"], str(path)) if doc.get("emulator") else None
    if cal is None and emu is None:
        raise InputError(f"{path}: holds neither a calibration law ('variants') nor an emulator")
    return CalibrationFile(cal, emu, doc.get("provenance", {}), where)


def _complex_table(path: Path) -> ComplexTable:
    """The complex-modulus table at `path`; InputError (one line) if it is missing."""
    if not path.is_file():
        raise InputError(f"{path}: the viscoelastic table is missing "
                         "(rebuild: make viscoelastic-table)")
    return ComplexTable.from_json(json.loads(path.read_text()), where=str(path))
