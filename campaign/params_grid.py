"""A campaign's points for a task kind with parameters of its own (`campaign.kinds.Kind.params`,
other than the protocol's, `campaign.protocol_grid`): each shell of the grid under each point of
the `[params]` section's product.

The `[params]` section names every one of the kind's parameters, and only those, each a number or
a non-empty list of finite numbers (the kind's compute function checks what values it takes).
The points are the product of the lists in the kind's order (m of them, the last fastest); point
i is shell i // m under parameter point i % m. A point's store columns are the shell's and the
kind's parameters; its id and the campaign's fingerprint are made from `ParamPoint.to_dict`, the
shell's fields and the parameters'.
"""

import itertools
import math
import operator
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from campaign.grid import Grid
from common.errors import InputError
from solver.model import Shell


@dataclass(frozen=True)
class ParamPoint:
    """One point: the shell and the kind's parameters' values (column -> value)."""

    shell: Shell
    values: Mapping[str, float]

    def to_dict(self) -> dict[str, object]:
        """The shell's fields and the parameters' values."""
        return {**self.shell.to_dict(), **self.values}


def params_axes(path: Any, section: Any, names: Sequence[str]) -> dict[str, list[float]]:
    """The `[params]` section's axes, in the order of `names` (the kind's parameters); InputError
    naming what is wrong if a name is missing or unknown, or a value is not a finite number."""
    if not isinstance(section, dict):
        raise InputError(f"{path}: [params] must be a table")
    missing = [k for k in names if k not in section]
    unknown = sorted(set(section) - set(names))
    if missing or unknown:
        raise InputError(f"{path}: [params] names the task kind's parameters, {', '.join(names)}"
                         + (f" (missing: {', '.join(missing)})" if missing else "")
                         + (f" (unknown: {', '.join(unknown)})" if unknown else ""))
    axes = {}
    for key in names:
        values = section[key] if isinstance(section[key], list) else [section[key]]
        if not values or not all(not isinstance(v, bool) and isinstance(v, (int, float)) and math.isfinite(v)
                                 for v in values):
            raise InputError(f"{path}: [params] {key} must be a finite number or a non-empty list of them "
                             f"(got {section[key]!r})")
        axes[key] = [float(v) for v in values]
    return axes


class ParamGrid(Sequence[ParamPoint]):
    """The points of `shells` × the product of the `[params]` `axes` (`params_axes`)."""

    def __init__(self, shells: Grid, axes: Mapping[str, list[float]]):
        self.shells, self.names = shells, tuple(axes)
        self.points = list(itertools.product(*axes.values()))
        self.m = len(self.points)

    def __len__(self) -> int:
        return len(self.shells) * self.m

    def __getitem__(self, i: Any) -> Any:
        if isinstance(i, slice):
            return [self[j] for j in range(*i.indices(len(self)))]
        i = operator.index(i)
        if not -len(self) <= i < len(self):
            raise IndexError(f"point {i} out of range ({len(self)} points)")
        s, p = divmod(i % len(self), self.m)
        return ParamPoint(self.shells[s], dict(zip(self.names, self.points[p])))

    def columns(self) -> dict[str, np.ndarray]:
        """The shells' columns (`Grid.columns`), each repeated per parameter point, and the parameters'."""
        cols = {k: np.repeat(v, self.m) for k, v in self.shells.columns().items()}
        points = np.array(self.points, float).reshape(self.m, len(self.names))
        for j, key in enumerate(self.names):
            cols[key] = np.tile(points[:, j], len(self.shells))
        return cols

    def texts(self, template: str, keys: Sequence[str], encode: Callable[[Any], str]) -> Iterator[str]:
        """`template % tuple(encode(value of k) for k in keys)` at every point (keys among `to_dict`'s)."""
        for point in self:
            d = point.to_dict()
            yield template % tuple(encode(d[k]) for k in keys)

    def reprs(self) -> Iterator[str]:
        """repr(point.to_dict()) of every point, in order: what the campaign's fingerprint is made of."""
        return (repr(point.to_dict()) for point in self)

    def __repr__(self) -> str:
        return f"ParamGrid({len(self.shells)} shells x {self.m} parameter points)"
