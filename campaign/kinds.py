"""Task kinds: what one grid point of a campaign computes, registered by the package that owns it.

A kind (`Kind`) names

- its parameters: the grid's axes its point is made of, each column with its unit (every kind has
  the shell's, `campaign.store.schema.PARAMS`; a kind with the protocol's columns,
  `campaign.protocol_grid.PROTOCOL_PARAMS`, takes a `[protocol]` section and its points are
  `campaign.protocol_grid.BiasNode`s; a kind with other columns of its own takes a `[params]`
  section giving each, and its points are `campaign.params_grid.ParamPoint`s);
- its result columns beyond the compression's (`campaign.store.schema.RESULTS`, always there),
  each with its unit (`"1"`: dimensionless);
- its compute function, a point (a `solver.model.Shell`, a `BiasNode` or a `ParamPoint`) into
  {result column: value} (None: the engine's own compression, `campaign.tasks.compute`);
- its version, an integer raised whenever the numbers it computes change. The store's fingerprint
  holds the kind's name and version (`campaign.config.Campaign.fingerprint`), and the store keeps
  both as the attributes `task_kind` and `task_version`: a resumed store made by another version
  is refused in one line (`campaign.store.store.Store`).

The owner registers it where its compute function lives (`register`, at import): the engine's
compressions in `campaign/tasks.py`, the Monte-Carlo trials in `campaign/trials.py`, the tables in
analysis (`analysis.calibration.viscoelastic_table`, `analysis.afm.tension.shell_table`,
`analysis.afm.tension.powerlaw_grid`, `analysis.afm.synth.protocol_bias`). A campaign file names a kind in `[campaign] task`:
`"compression"` (the default, the engine's), or `"MODULE:NAME"`, the module that registers it
(imported then, on every rank and in every task process: a kind's compute function travels to the
task process by reference) and the kind's name. So a new kind, in any importable module, needs no
edit here or anywhere in the engine.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

from common.errors import InputError

COMPRESSION = "compression"         # the engine's own kind, the default


@dataclass(frozen=True)
class Kind:
    """One task kind (module docstring)."""

    name: str
    version: int
    results: Mapping[str, str]                      # result column -> unit, beyond schema.RESULTS
    compute: Callable[[Any], dict[str, float]] | None = None   # a grid point -> results; None: compression
    params: Mapping[str, str] = field(default_factory=dict)    # parameter columns -> unit beyond the shell's
    doc: str = ""                                   # one line: what a task computes

    def stamp(self) -> str:
        """What the store's fingerprint holds of the kind: 'NAME@VERSION'."""
        return f"{self.name}@{self.version}"


_KINDS: dict[str, Kind] = {}


def register(kind: Kind) -> Kind:
    """Register `kind` under its name (again the same kind: nothing happens); returns it.
    ValueError if another kind has the name already (two owners of one name)."""
    if not kind.name or ":" in kind.name:
        raise ValueError(f"a task kind's name is a word without ':' (got {kind.name!r})")
    if isinstance(kind.version, bool) or not isinstance(kind.version, int) or kind.version < 1:
        raise ValueError(f"task kind {kind.name}: its version is an integer >= 1 (got {kind.version!r})")
    known = _KINDS.get(kind.name)
    if known is not None and known != kind:
        raise ValueError(f"task kind {kind.name!r} is registered already, by another owner")
    _KINDS[kind.name] = kind
    return kind


def registered() -> dict[str, Kind]:
    """The kinds registered so far, by name."""
    return dict(_KINDS)


def find(spec: str, where: str = "[campaign] task") -> Kind:
    """The kind a campaign file names: `compression`, or `MODULE:NAME` (MODULE imported: it registers
    NAME). InputError, one line naming `where`, if the module cannot be imported or registers no such kind."""
    if not isinstance(spec, str) or not spec:
        raise InputError(f"{where} must be a string, \"compression\" or \"MODULE:NAME\" (got {spec!r})")
    if spec == COMPRESSION:
        import campaign.tasks   # noqa: F401  (registers the engine's compression)
        return _KINDS[COMPRESSION]
    module, sep, name = spec.partition(":")
    if not sep:
        raise InputError(f"{where} = {spec!r}: name the module that registers the kind, "
                         f"\"MODULE:{spec}\" (or \"compression\")")
    try:
        importlib.import_module(module)
    except ImportError as err:
        raise InputError(f"{where} = {spec!r}: module {module!r} cannot be imported ({err})") from None
    kind = _KINDS.get(name)
    if kind is None:
        raise InputError(f"{where} = {spec!r}: module {module!r} registers no task kind {name!r}")
    return kind
