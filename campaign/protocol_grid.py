"""A protocol-bias campaign's nodes (`[campaign] task = "protocol_bias"`, SPEC 12): each shell
of the grid (`campaign.grid.Grid`) under each point of the `[protocol]` section's product.

The `[protocol]` axes (PROTOCOL_KEYS, each a number or a list):

    bulk_exponent, shear_exponent   β_B, β_S of K(t) = K(1 s) t^-β (K(1 s): the grid's moduli)
    wait_s                          T_w, the wait at the mean height before the oscillation
    frequency_hz                    f, the oscillation's frequency

Node i is shell i // m under protocol point i % m (m points, the last axis fastest), so the
protocol varies fastest. A node's store columns are the shell's parameters and PROTOCOL_PARAMS
(`campaign.store.schema`; the frequency as `protocol_frequency_hz`, apart from the viscous
interior's `frequency_hz`); its id and the campaign's fingerprint are made from `to_dict`, the
shell's fields and the protocol's.
"""

import itertools
import math
import operator
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from campaign.grid import Grid
from common.errors import InputError
from solver.model import Shell

PROTOCOL_KEYS = ("bulk_exponent", "shear_exponent", "wait_s", "frequency_hz")
COLUMN = {"bulk_exponent": "bulk_exponent", "shear_exponent": "shear_exponent", "wait_s": "wait_s",
          "frequency_hz": "protocol_frequency_hz"}      # a [protocol] key's store column


@dataclass(frozen=True)
class ProtocolNode:
    """One node: the shell (K(1 s) its moduli, h0 = h_m + Δh/2) and the protocol point."""

    shell: Shell
    bulk_exponent: float
    shear_exponent: float
    wait_s: float
    frequency_hz: float

    def to_dict(self) -> dict[str, object]:
        """The shell's fields and the protocol's (as their store columns)."""
        return {**self.shell.to_dict(), **{COLUMN[k]: getattr(self, k) for k in PROTOCOL_KEYS}}


def protocol_axes(path: Any, section: dict[str, Any]) -> dict[str, list[float]]:
    """The `[protocol]` section's axes, each a non-empty list of numbers in range; InputError if not."""
    unknown = set(section) - set(PROTOCOL_KEYS)
    if unknown:
        raise InputError(f"{path}: unknown key {sorted(unknown)[0]!r} in [protocol] (known: {', '.join(PROTOCOL_KEYS)})")
    axes = {}
    for key in PROTOCOL_KEYS:
        if key not in section:
            raise InputError(f"{path}: [protocol] needs {key}")
        values = section[key] if isinstance(section[key], list) else [section[key]]
        if not values or any(isinstance(v, bool) or not isinstance(v, (int, float)) for v in values):
            raise InputError(f"{path}: [protocol] {key} must be a number or a non-empty list of numbers")
        axes[key] = [float(v) for v in values]
    for key in ("bulk_exponent", "shear_exponent"):
        if not all(0.0 <= v < 1.0 for v in axes[key]):
            raise InputError(f"{path}: [protocol] {key} must be in [0, 1) (got {axes[key]})")
    if not all(math.isfinite(v) and v >= 0 for v in axes["wait_s"]) or \
            not all(math.isfinite(v) and v > 0 for v in axes["frequency_hz"]):
        raise InputError(f"{path}: [protocol] wait_s must be >= 0 and frequency_hz > 0")
    return axes


class ProtocolGrid(Sequence):
    """The nodes of `shells` × the product of the protocol `axes` ({PROTOCOL_KEYS key: values})."""

    def __init__(self, shells: Grid, axes: dict[str, list[float]]):
        self.shells = shells
        self.points = list(itertools.product(*(axes[k] for k in PROTOCOL_KEYS)))
        self.m = len(self.points)

    def __len__(self) -> int:
        return len(self.shells) * self.m

    def __getitem__(self, i):  # type: ignore[override]
        if isinstance(i, slice):
            return [self[j] for j in range(*i.indices(len(self)))]
        i = operator.index(i)
        if not -len(self) <= i < len(self):
            raise IndexError(f"node {i} out of range ({len(self)} nodes)")
        s, p = divmod(i % len(self), self.m)
        return ProtocolNode(self.shells[s], *self.points[p])

    def columns(self) -> dict[str, np.ndarray]:
        """The shells' columns (`Grid.columns`), each repeated per protocol point, and PROTOCOL_PARAMS."""
        cols = {k: np.repeat(v, self.m) for k, v in self.shells.columns().items()}
        points = np.array(self.points, float)
        for j, key in enumerate(PROTOCOL_KEYS):
            cols[COLUMN[key]] = np.tile(points[:, j], len(self.shells))
        return cols

    def texts(self, template: str, keys: Sequence[str], encode: Callable[[Any], str]) -> Iterator[str]:
        """`template % tuple(encode(value of k) for k in keys)` at every node (keys among `to_dict`'s)."""
        for node in self:
            d = node.to_dict()
            yield template % tuple(encode(d[k]) for k in keys)

    def reprs(self) -> Iterator[str]:
        """repr(node.to_dict()) of every node, in order: what the campaign's fingerprint is made of."""
        return (repr(node.to_dict()) for node in self)

    def __repr__(self) -> str:
        return f"ProtocolGrid({len(self.shells)} shells x {self.m} protocol points)"
