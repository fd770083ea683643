"""A campaign's points as each shell of a grid under each point of a product of axes: the one
shape the protocol grid (`campaign.protocol_grid.BiasGrid`) and a task kind's own parameters
(`campaign.params_grid.ParamGrid`) share.

With n shells and m points of the axes, point i is shell i // m under axis point i % m (the last
axis fastest). Its store columns are the shell's, each repeated m times, and one per axis, tiled
n times; its id and the campaign's fingerprint come from its `to_dict`.
"""

import math
import operator
from collections.abc import Iterator, Sequence
from typing import Any, Callable

import numpy as np

from campaign.grid import Grid
from solver.model import Shell


def numbers(value: Any) -> list[float] | None:
    """A campaign file's axis (a number or a list of them) as a non-empty list of finite floats;
    None if it is not one."""
    values = value if isinstance(value, list) else [value]
    if values and all(not isinstance(v, bool) and isinstance(v, (int, float)) and math.isfinite(v) for v in values):
        return [float(v) for v in values]
    return None


class ShellProduct(Sequence[Any]):
    """`shells` × `points` (tuples of numbers, one per column of `names`); a subclass makes a
    point of a shell and its values (`point`) and names what it holds (`noun`)."""

    noun = "point"

    def __init__(self, shells: Grid, points: Sequence[tuple[Any, ...]], names: Sequence[str]):
        self.shells, self.points, self.names = shells, list(points), tuple(names)
        self.m = len(points)

    def point(self, shell: Shell, values: tuple[Any, ...]) -> Any:
        raise NotImplementedError

    def __len__(self) -> int:
        return len(self.shells) * self.m

    def __getitem__(self, i: Any) -> Any:
        if isinstance(i, slice):
            return [self[j] for j in range(*i.indices(len(self)))]
        i = operator.index(i)
        if not -len(self) <= i < len(self):
            raise IndexError(f"{self.noun} {i} out of range ({len(self)} {self.noun}s)")
        s, p = divmod(i % len(self), self.m)
        return self.point(self.shells[s], self.points[p])

    def columns(self) -> dict[str, np.ndarray]:
        """The shells' columns (`Grid.columns`), each repeated per axis point, and the axes'."""
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
        return f"{type(self).__name__}({len(self.shells)} shells x {self.m} {self.noun}s)"
