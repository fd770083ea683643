"""The calibration bundle: every part a command takes to read cells, named by one manifest
and loaded once by the one loader, `load_calibration`.

The parts (`PARTS`; adding one, e.g. a correction table, is one line there):

    law                 the paper law per bending variant (`law`: λ, C, D, α table, goodness)
    emulator            the spline of the solver's K/K_B per bending variant (`emulator`)
    viscoelastic_table  the complex-modulus correspondence factor C (`viscoelastic_table`)
    ramp_table          the shell ramp table of `cortex afm tension` (`ramp_table`)
    powerlaw_table      the power-law ramp and hold table of its power-law reading (`powerlaw_table`)

Layout of the file (a JSON document, versioned):

    format      "cortex-calibration"
    version     2 (1: law only, as `cortex analysis calibrate` writes)
    parts       the manifest: part -> "embedded" (in this document: `variants` for the law,
                `emulator` for the emulator), "shipped" (the shipped bundle's part) or a path
                (relative to this file's folder) of a file holding the part
    variants    the paper law per bending variant
    emulator    per bending variant: axes volume_um3, h_tilde, ks_tilde, gamma_tilde,
                k_over_kb (nested lists in that axis order), dh_um, thickness_um
    provenance  per part (`emulator`, `law`): the campaign file's text, the
                store's fingerprint, the code version that ran it and when;
                `built`: the date and code version of this file

A file holds what it embeds (`variants`, `emulator`: embedded without a manifest entry) and
what its manifest names, nothing more: a law-only file without a manifest has no emulator and
no tables, and a reading that needs one refuses in one line. It takes the shipped bundle's part
only where its manifest says "shipped". A named part that is missing or unreadable is an
InputError (one line). `CalibrationFile.sources` says for each part where it came from (the
file's path, or "shipped"); `afm analyze` writes it to summary.json and report.md.

`build` makes the document from two finished stores (`make calibration`); its manifest names
the tables beside it, or borrows the shipped ones.
Every command reads the file here once and hands its parts on; no other code opens it.
"""

import json
import time
from dataclasses import dataclass, field
from functools import cached_property, lru_cache
from importlib import resources
from importlib.metadata import version
from os import PathLike
from pathlib import Path
from typing import Any, Callable

from analysis.calibration.emulator import Emulator, from_results
from analysis.calibration.law import FORMAT, Calibration, _nan_to_none, read_document
from analysis.calibration.powerlaw_table import NAME as POWERLAW_TABLE_NAME
from analysis.calibration.powerlaw_table import PowerLawTable
from analysis.calibration.powerlaw_table import from_document as powerlaw_from_document
from analysis.calibration.ramp_table import NAME as RAMP_TABLE_NAME
from analysis.calibration.ramp_table import ShellTable
from analysis.calibration.ramp_table import from_document as ramp_from_document
from analysis.calibration.viscoelastic_table import ComplexTable
from common.errors import InputError

VERSION = 2
SHIPPED_NAME = "calibration.json"
TABLE_NAME = "viscoelastic_table.json"          # the complex-modulus table (`viscoelastic_table`)
SHIPPED = "shipped"                             # a manifest entry: the shipped bundle's part
EMBEDDED = "embedded"                           # a manifest entry: in this document


SHIPPED_WHERE = "the shipped calibration"      # how messages name the default file
SHIPPED_PARTS = {"viscoelastic_table": TABLE_NAME, "ramp_table": RAMP_TABLE_NAME,
                 "powerlaw_table": POWERLAW_TABLE_NAME}      # the built file's manifest


@dataclass(frozen=True)
class Part:
    """One replaceable part of the bundle: the document key that embeds it (None: a file of its
    own), how to read it from a JSON document read from `where`, and how to rebuild the shipped one."""

    key: str | None
    read: Callable[[dict[str, Any], str], Any]
    rebuild: str


PARTS: dict[str, Part] = {
    "law": Part("variants", lambda doc, where: Calibration.from_document(where, doc), "make calibration"),
    "emulator": Part("emulator", lambda doc, where: Emulator.from_json(doc["emulator"], where), "make calibration"),
    "viscoelastic_table": Part(None, lambda doc, where: ComplexTable.from_json(doc, where=where),
                               "make viscoelastic-table"),
    "ramp_table": Part(None, lambda doc, where: ramp_from_document(doc, where), "make ramp-table"),
    "powerlaw_table": Part(None, lambda doc, where: powerlaw_from_document(doc, where), "make powerlaw-table"),
}


@dataclass(frozen=True)
class ComplexModel:
    """The complex forward model K* = K_sec · C of a viscoelastic cell (SPEC 10): the
    emulator's K_sec and the complex-modulus table's C."""

    emulator: Emulator
    table: ComplexTable


@dataclass(frozen=True)
class CalibrationFile:
    """A calibration bundle as read: its law and its emulator (either may be None, not both),
    its provenance, how messages name it (the path given, or `SHIPPED_WHERE`), where each
    part it has comes from (`sources`: part -> path or "shipped") and the files of the
    parts it names but reads on first use (`files`: part -> path), and its manifest as read (the
    embedded parts listed: written back as `parts`, the same bundle)."""

    calibration: Calibration | None
    emulator: Emulator | None
    provenance: dict[str, Any]
    where: str
    sources: dict[str, str] = field(default_factory=dict)
    files: dict[str, Path] = field(default_factory=dict)
    manifest: dict[str, str] = field(default_factory=dict)    # as read: part -> embedded, shipped or a path

    @property
    def default_method(self) -> str:
        """The inversion method this bundle serves when none is named: emulator if it has one, else law."""
        return "emulator" if self.emulator is not None else "law"

    def require(self, parts: tuple[str, ...], use: str) -> None:
        """InputError (one line) unless this bundle has every part of `parts`, which `use` needs."""
        missing = [p for p in parts if p not in self.sources]
        if missing:
            names = ", ".join(f'"{p}": "{SHIPPED}"' for p in missing)
            raise InputError(f"{self.where}: {use} needs the part(s) {', '.join(missing)}, which this calibration "
                             f"does not name (its manifest may borrow the shipped ones: \"parts\": {{{names}}})")

    def part(self, name: str) -> Any:
        """The part `name` read from its own file (read once); InputError (one line) if not named."""
        self.require((name,), f"the {name.replace('_', ' ')}")
        return _read_part(name, self.files[name])

    @cached_property
    def viscoelastic(self) -> ComplexModel:
        """The viscoelastic reading's forward model (read on first use): this bundle's emulator
        and complex-modulus table; InputError (one line) if it does not name them."""
        self.require(("emulator", "viscoelastic_table"), "the viscoelastic reading")
        assert self.emulator is not None
        return ComplexModel(self.emulator, self.part("viscoelastic_table"))

    @cached_property
    def shell_ramp(self) -> ShellTable:
        """The shell ramp table of `cortex afm tension` (read on first use)."""
        table: ShellTable = self.part("ramp_table")
        return table

    @cached_property
    def powerlaw(self) -> PowerLawTable:
        """The power-law ramp and hold table of `cortex afm tension` (read on first use)."""
        table: PowerLawTable = self.part("powerlaw_table")
        return table


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
          progress: Callable[[str], None] | None = None, folder: str | PathLike[str] | None = None) -> dict[str, Any]:
    """The calibration document from an emulator campaign's store and (optionally)
    the paper campaign's store (its law fitted by `analysis.calibration.law.calibrate`). Its
    manifest names each table (`SHIPPED_PARTS`) by its file where `folder` (where the document
    goes) holds one, and borrows the shipped one elsewhere."""
    from analysis.calibration.law import calibrate
    from analysis.calibration.command.pipeline import read_store
    results, _ = read_store(emulator_store)
    emulator = from_results(results, progress)
    doc: dict[str, Any] = {"format": FORMAT, "version": VERSION, "parts": _table_parts(folder), "variants": {},
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


def _table_parts(folder: str | PathLike[str] | None) -> dict[str, str]:
    """The built document's manifest of its tables: the file in `folder` where it is there, else "shipped"."""
    return {part: name if folder is not None and (Path(folder) / name).is_file() else SHIPPED
            for part, name in SHIPPED_PARTS.items()}


def write(doc: dict[str, Any], path: str | PathLike[str]) -> Path:
    """Write the document (atomic replace, `outputs.writing`: a full disk is a
    WriteError naming `path`; the caller has checked that `path` is ours)."""
    from outputs.writing import write_atomically
    text = json.dumps(doc, indent=None, separators=(",", ":")) + "\n"
    return Path(write_atomically(path, text.encode()))


def load_calibration(path: str | PathLike[str] | None = None) -> CalibrationFile:
    """The calibration bundle at `path` (None: the shipped default), read and parsed once (its
    own-file parts on first use). Malformed, or naming a missing part: InputError (one line)."""
    shipped = path is None
    where = SHIPPED_WHERE if shipped else str(path)
    path = shipped_path() if path is None else Path(path)
    doc = read_document(path)
    manifest = _manifest(path, doc)
    sources: dict[str, str] = {}
    files: dict[str, Path] = {}
    embedded: dict[str, Any] = {}
    for name, entry in manifest.items():
        if entry == SHIPPED:
            if shipped:
                raise InputError(f"{path}: the shipped bundle cannot borrow '{name}' from itself")
            base = _shipped()
            base.require((name,), f"'{name}' borrowed from the shipped bundle")
            sources[name] = SHIPPED
            if PARTS[name].key is not None:
                embedded[name] = base.calibration if name == "law" else base.emulator
            else:
                files[name] = base.files[name]
        elif entry == EMBEDDED:
            embedded[name] = PARTS[name].read(doc, str(path))
            sources[name] = SHIPPED if shipped else str(path)
        else:
            files[name] = _part_file(path, name, entry)
            sources[name] = SHIPPED if shipped else str(files[name])
            if PARTS[name].key is not None:
                embedded[name] = _read_part(name, files[name])
    if "law" not in embedded and "emulator" not in embedded:
        raise InputError(f"{path}: holds neither a calibration law ('variants') nor an emulator")
    return CalibrationFile(embedded.get("law"), embedded.get("emulator"), doc.get("provenance", {}), where,
                           sources, files, manifest)


@lru_cache(maxsize=1)
def _shipped() -> CalibrationFile:
    """The shipped bundle, which other bundles borrow parts from (read once per process)."""
    return load_calibration(None)


def _manifest(path: Path, doc: dict[str, Any]) -> dict[str, str]:
    """The document's manifest (`parts`), with the parts it embeds and does not list; InputError
    (one line) for an unknown part, an entry that is not a string, or an embedded part not there."""
    given = doc.get("parts", {})
    if not isinstance(given, dict) or not all(isinstance(v, str) for v in given.values()):
        raise InputError(f"{path}: 'parts' must map part names to \"{EMBEDDED}\", \"{SHIPPED}\" or a path")
    unknown = sorted(set(given) - set(PARTS))
    if unknown:
        raise InputError(f"{path}: unknown part(s) {', '.join(unknown)} in 'parts' (known: {', '.join(PARTS)})")
    manifest = {n: EMBEDDED for n, part in PARTS.items() if part.key is not None and doc.get(part.key)}
    manifest.update(given)
    for name, entry in manifest.items():
        key = PARTS[name].key
        if entry == EMBEDDED and (key is None or not doc.get(key)):
            raise InputError(f"{path}: 'parts' says '{name}' is embedded, but the document does not hold it")
    return manifest


def _part_file(path: Path, name: str, entry: str) -> Path:
    """The file of part `name` that the manifest of `path` names (relative to its folder);
    InputError (one line) if it is not a file."""
    file = path.parent / entry
    if not file.is_file():
        raise InputError(f"{path}: the {name.replace('_', ' ')} it names, {file}, is missing "
                         f"(rebuild: {PARTS[name].rebuild})")
    return file


@lru_cache(maxsize=8)
def _read_part(name: str, file: Path) -> Any:
    """Part `name` read from `file` (once per process); InputError (one line) if unreadable."""
    try:
        doc = json.loads(file.read_text())
    except (OSError, ValueError) as err:
        raise InputError(f"{file}: cannot read the {name.replace('_', ' ')} ({err}; rebuild: "
                         f"{PARTS[name].rebuild})") from None
    if not isinstance(doc, dict):
        raise InputError(f"{file}: the {name.replace('_', ' ')} is not a JSON object")
    part = PARTS[name]
    return part.read(doc if part.key is None else read_document(file), str(file))
