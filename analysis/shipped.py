"""The calibration file: the emulator tables and the paper law in one versioned
JSON document, and the default one shipped inside the package.

Layout (a superset of `calibration.json`, so `Calibration.load` reads it too):

    format      "cortex-calibration"
    version     2 (1: law only, as `cortex analysis calibrate` writes)
    variants    the paper law per bending variant (λ, C, D, α table, goodness)
    emulator    per bending variant: axes volume_um3, h_tilde, ks_tilde, gamma_tilde,
                k_over_kb (nested lists in that axis order), dh_um, thickness_um
    provenance  per part (`emulator`, `law`): the campaign file's text, the
                store's fingerprint, the code version that ran it and when;
                `built`: the date and code version of this file

`build` makes the document from two finished stores (`make calibration`);
`read` reads one (None: the shipped default, `SHIPPED_NAME`) once into a
`CalibrationFile`: a `Calibration` (or None), an `Emulator` (or None, for a
law-only file), the provenance and where it came from; `load` gives the same
as a tuple.
"""

import json
import time
from dataclasses import dataclass
from importlib import resources
from importlib.metadata import version
from os import PathLike
from pathlib import Path
from typing import Any, Callable

from analysis.calibration import FORMAT, Calibration, _nan_to_none, read_document
from analysis.emulator import Emulator, from_results
from common.errors import InputError

VERSION = 2
SHIPPED_NAME = "calibration.json"


SHIPPED_WHERE = "the shipped calibration"      # how messages name the default file


@dataclass(frozen=True)
class CalibrationFile:
    """A calibration file as read: its laws and its emulator (either may be None, not both),
    its provenance, and how messages name it (the path given, or `SHIPPED_WHERE`)."""

    calibration: Calibration | None
    emulator: Emulator | None
    provenance: dict[str, Any]
    where: str


def shipped_path() -> Path:
    """The default calibration file inside the installed package."""
    return Path(str(resources.files("analysis") / "data" / SHIPPED_NAME))


def _store_provenance(path):
    from campaign.store.reader import read_provenance
    p = read_provenance(path)
    return {"store": Path(path).name, "campaign_text": p.get("config_text", ""),
            "fingerprint": p.get("fingerprint", ""), "code_version": p.get("code_version", ""),
            "run_date": p.get("created", ""), "versions": p.get("versions", "")}


def build(emulator_store: str | PathLike[str], law_store: str | PathLike[str] | None = None,
          progress: Callable[[str], None] | None = None) -> dict[str, Any]:
    """The calibration document from an emulator campaign's store and (optionally)
    the paper campaign's store (its law fitted by `analysis.calibration.calibrate`)."""
    from analysis.calibration import calibrate
    from analysis.calibrate.pipeline import read_store
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


def read(path: str | PathLike[str] | None = None) -> CalibrationFile:
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


def load(path: str | PathLike[str] | None = None) -> tuple[Calibration | None, Emulator | None, dict[str, Any]]:
    """(Calibration or None, Emulator or None, provenance dict) of a calibration file (`read`)."""
    file = read(path)
    return file.calibration, file.emulator, file.provenance
