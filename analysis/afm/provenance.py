"""How an experiment was made (its provenance), and the reading of it that follows.

The experiment file (`analysis.afm.formats.h5`) records it in the group /provenance:

    attrs  kind       "measured" (imported from an instrument: JPK, Bruker) or "synthetic"
           model      synthetic only: "frequency-domain" (`analysis.afm.synth.cells`: the force at
                      each height relaxed, whatever the recorded approach holds) or "time-domain"
                      (`analysis.afm.synth.time_cells`: the whole protocol simulated in time)
           memory_s   time-domain only: τ_c (s), the cortex's turnover in
                      K(t) = K(1 s) (t/1 s)^-β e^(-t/τ_c); inf: no turnover (a pure power law)
           history    time-domain only: "carried" (one history through every height) or "relaxed"
    cortex time-domain only, compound (n,): cell_id, bulk_exponent, shear_exponent,
           bulk_1s_mN_per_m, shear_1s_mN_per_m (β_B, β_S, K_B(1 s), K_S(1 s) of each cell)

A file without /provenance (written before files recorded it) is "unknown": read as a measured one,
and the report says so. Instrument files and single-cell CSV files given to `afm analyze` directly
are measured. A malformed /provenance is an InputError naming the file (one line, exit status 2).

The reading (`reading`), policy apart from the mechanism above: without an explicit `--wait-s`,
a relaxed synthetic experiment (frequency-domain) is read in the relaxed state (wait inf, exactly
`--wait-s inf`), every other kind protocol-aware with each recording's own waits (None, exactly
`--wait-s recorded`); an explicit wait is taken as given.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from common.errors import InputError
from common.names import CORTEX_HISTORIES

KINDS = ("measured", "synthetic")
MODELS = ("frequency-domain", "time-domain")
GROUP = "provenance"
CORTEX_COLUMNS = ("bulk_exponent", "shear_exponent", "bulk_1s_mN_per_m", "shear_1s_mN_per_m")
CORTEX_DTYPE = np.dtype([("cell_id", h5py.string_dtype())] + [(c, "f8") for c in CORTEX_COLUMNS])


@dataclass(frozen=True)
class Provenance:
    """How an experiment was made: `kind` measured, synthetic or unknown (not recorded); a synthetic
    one's `model`; a time-domain one's τ_c (`memory_s`), `history` and per-cell cortex
    {cell_id: {bulk_exponent, shear_exponent, bulk_1s_mN_per_m, shear_1s_mN_per_m}}."""

    kind: str = "unknown"
    model: str | None = None
    memory_s: float | None = None
    history: str | None = None
    cortex: dict[str, dict[str, float]] = field(default_factory=dict)

    @property
    def relaxed(self) -> bool:
        """Whether every height's force was relaxed when made (a frequency-domain synthetic experiment)."""
        return self.kind == "synthetic" and self.model == "frequency-domain"

    def describe(self) -> str:
        """'measured', 'synthetic, frequency-domain', 'synthetic, time-domain', or what an unknown one is."""
        if self.kind == "unknown":
            return "no provenance recorded: read as measured"
        return self.kind if self.model is None else f"{self.kind}, {self.model}"

    def to_dict(self) -> dict[str, Any]:
        """summary.json's `provenance` (τ_c inf as null; the per-cell cortex left out)."""
        out: dict[str, Any] = {"kind": self.kind, "recorded": self.kind != "unknown"}
        if self.model is not None:
            out["model"] = self.model
        if self.model == "time-domain":
            out.update(memory_s=self.memory_s if self.memory_s is not None and math.isfinite(self.memory_s) else None,
                       history=self.history)
        return out


MEASURED = Provenance("measured")
FREQUENCY_DOMAIN = Provenance("synthetic", "frequency-domain")
UNKNOWN = Provenance()


def time_domain(truth_cells: Sequence[dict[str, Any]], history: str, memory_s: float = math.inf) -> Provenance:
    """The provenance of a time-domain synthetic experiment from its truth's cells (each with
    cell_id and the `CORTEX_COLUMNS`), its history and τ_c (s; inf: no turnover)."""
    cortex = {str(t["cell_id"]): {c: float(t[c]) for c in CORTEX_COLUMNS} for t in truth_cells}
    return _checked(Provenance("synthetic", "time-domain", float(memory_s), history, cortex), "time_domain")


def _checked(p: Provenance, where: str) -> Provenance:
    """`p`; InputError (one line, naming `where`) for a kind, model, τ_c, history or cortex out of place."""
    if p.kind not in KINDS:
        raise InputError(f"{where}: provenance kind '{p.kind}' (expected {' or '.join(KINDS)})")
    if (p.kind == "synthetic") != (p.model is not None) or (p.model is not None and p.model not in MODELS):
        raise InputError(f"{where}: provenance model '{p.model}' for kind '{p.kind}' (a synthetic experiment "
                         f"has one of {', '.join(MODELS)}; a measured one none)")
    timed = p.model == "time-domain"
    if timed != (p.memory_s is not None) or timed != (p.history is not None) or (not timed and p.cortex):
        raise InputError(f"{where}: provenance memory_s, history and cortex go with the time-domain model only, "
                         "and it needs the first two")
    if timed and not (p.memory_s is not None and p.memory_s > 0):
        raise InputError(f"{where}: provenance memory_s must be a number of seconds > 0, or inf (got {p.memory_s})")
    if timed and p.history not in CORTEX_HISTORIES:
        raise InputError(f"{where}: provenance history '{p.history}' (expected {' or '.join(CORTEX_HISTORIES)})")
    if any(not math.isfinite(v) for c in p.cortex.values() for v in c.values()):
        raise InputError(f"{where}: provenance cortex has a value that is not a finite number")
    return p


def write(f: h5py.File, p: Provenance) -> None:
    """/provenance of `p` into the open file `f` (nothing for an unknown one)."""
    if p.kind == "unknown":
        return
    g = f.create_group(GROUP)
    g.attrs["kind"] = p.kind
    for key in ("model", "memory_s", "history"):
        if getattr(p, key) is not None:
            g.attrs[key] = getattr(p, key)
    if p.cortex:
        rows = [(cid, *(c[k] for k in CORTEX_COLUMNS)) for cid, c in p.cortex.items()]
        g.create_dataset("cortex", data=np.array(rows, dtype=CORTEX_DTYPE))


def _text(value: Any) -> str:
    return value.decode() if isinstance(value, bytes) else str(value)


def read(f: h5py.File, where: str) -> Provenance:
    """The provenance of the open experiment file `f` (UNKNOWN without /provenance); InputError,
    naming `where`, if malformed."""
    if GROUP not in f:
        return UNKNOWN
    g = f[GROUP]
    if not isinstance(g, h5py.Group) or "kind" not in g.attrs:
        raise InputError(f"{where}: /{GROUP} is not a group with a 'kind' attribute")
    try:
        memory = float(g.attrs["memory_s"]) if "memory_s" in g.attrs else None
    except (TypeError, ValueError):
        raise InputError(f"{where}: provenance memory_s is not a number of seconds") from None
    cortex = {}
    if "cortex" in g:
        try:
            table = g["cortex"][()]
            cortex = {_text(r["cell_id"]): {c: float(r[c]) for c in CORTEX_COLUMNS} for r in table}
        except (TypeError, ValueError, KeyError, IndexError, OSError):
            raise InputError(f"{where}: provenance cortex is not a table of cell_id, "
                             f"{', '.join(CORTEX_COLUMNS)}") from None
    model, history = (_text(g.attrs[k]) if k in g.attrs else None for k in ("model", "history"))
    return _checked(Provenance(_text(g.attrs["kind"]), model, memory, history, cortex), where)


def of_data(paths: Sequence[str | Path]) -> Provenance:
    """The provenance of what `afm analyze` reads (`formats.reader.open`'s input): an experiment
    file's own, MEASURED for instrument and single-cell CSV files."""
    if len(paths) == 1 and Path(paths[0]).suffix.lower() in (".h5", ".hdf5"):
        from analysis.afm.formats.h5 import read_provenance
        return read_provenance(paths[0])
    return MEASURED


@dataclass(frozen=True)
class Reading:
    """How `afm analyze` reads an experiment: the protocol-aware reading's wait (None: each
    recording's own; inf: the relaxed state, no correction), its name and why."""

    wait_s: float | None
    name: str
    why: str

    def label(self) -> str:
        """summary.json's `reading`, e.g. 'relaxed (synthetic, frequency-domain)'."""
        return f"{self.name} ({self.why})"


def reading(p: Provenance, wait_s: float | None, as_made: bool, phase: bool = True) -> Reading:
    """The reading of an experiment of provenance `p`: as it was made (`as_made`: relaxed for a
    relaxed synthetic experiment, else protocol-aware with each recording's own waits), or with
    the explicit `wait_s` (None: recorded; inf: relaxed); without the viscoelastic reading (`phase`
    False) nothing is corrected, the relaxed state."""
    if not phase:
        return Reading(math.inf, "relaxed", f"--no-phase: no viscoelastic reading to correct; the experiment: "
                                            f"{p.describe()}")
    if as_made:
        return Reading(math.inf, "relaxed", p.describe()) if p.relaxed else \
            Reading(None, "protocol-aware", p.describe())
    given = "recorded" if wait_s is None else f"{wait_s:g}"
    name = "relaxed" if wait_s is not None and math.isinf(wait_s) else "protocol-aware"
    return Reading(wait_s, name, f"--wait-s {given}; the experiment: {p.describe()}")


def markdown(r: Reading, p: Provenance) -> str:
    """report.md's section on how the experiment was made and read."""
    made = {"unknown": "The experiment does not record how it was made (written before experiment files "
                       "recorded it); it is read as a measured one.",
            "measured": "The experiment was measured (imported from an instrument)."}.get(
        p.kind, f"The experiment is synthetic, made in the {p.model} model.")
    how = {"relaxed": "the relaxed-state reading: every height's force taken as relaxed, no correction",
           "protocol-aware": "the protocol-aware reading: every segment corrected for the stress kept from "
                             "the earlier height steps"}[r.name]
    return f"\n## How the experiment was made and read\n\n{made} Read by {how} ({r.why}).\n"
