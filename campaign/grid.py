"""A campaign's compressions: the Cartesian product of the grid's axes, as a
sequence that makes each `Shell` when it is asked for.

Point i of the product over the axes a_1 .. a_K (GRID_KEYS order, the last
axis fastest) has the coordinates i = Σ_k c_k Π_{m>k} |a_m|, so
`Grid[i]` takes c_k from i by divmod, last axis first. Dimensionless axes
(h̃, K̃_S, γ̃_a: `absolute`) become absolute values when the shell is made:

    h0 = 2 R_cell(V) h̃ + Δh/2,   K_S = K̃_S K_B,   γ_a = γ̃_a K_B.

A campaign holds its axes, not its shells: a Shell takes 460-640 bytes (the
more when made without `__init__`), and every rank loads the campaign, so a
million compressions held 0.3-0.65 GB on each rank. Making shell i takes
~1.7 µs; going through all of them in order ~1.3 µs each.

The grid is checked once, when it is made (`check`): `Shell`'s checks each
read one field or the fields of one of CHECK_GROUPS, and a field's values
come from its axis, or (a dimensionless axis) from its group's axes, so the
points that run through the product of one group's axes (or one other
axis), every other axis at its first value, show each check every value it
can meet. Where one fails, the points are checked in order, which raises
the first failing point's error, as checking each point does. The shells
are then made without their own checks (`Shell.unchecked`).
"""

import itertools
import math
import operator
from collections.abc import Sequence

from solver.errors import InputError
from solver.geometry import cell_radius
from solver.model import Shell

GRID_KEYS = ("volume_um3", "h0_um", "dh_um", "bulk_mN_per_m", "shear_mN_per_m",
             "tension_mN_per_m", "thickness_um", "bending", "viscosity_Pa_s", "frequency_hz")
OPTIONAL = ("viscosity_Pa_s", "frequency_hz")     # absent: an elastic cell
CHECK_GROUPS = (("volume_um3", "h0_um", "dh_um"), ("bulk_mN_per_m", "shear_mN_per_m", "tension_mN_per_m"),
                OPTIONAL)                      # the fields one of Shell's checks reads together


def absolute(p, ratios):
    """A grid point (a dict) with its dimensionless coordinates (the keys of
    `ratios`) turned into absolute ones, in place."""
    if "h0_um" in ratios:
        p["h0_um"] = 2.0 * float(cell_radius(p["volume_um3"])) * p["h0_um"] + 0.5 * p["dh_um"]
    for key in ("shear_mN_per_m", "tension_mN_per_m"):
        if key in ratios:
            p[key] = p[key] * p["bulk_mN_per_m"]
    return p


class Grid(Sequence):
    """The shells of the product of `axes` ({GRID_KEYS key: list of values},
    `[None]` for an absent optional one), `ratios` naming the dimensionless
    axes, each shell at `resolution`. Made by `check`ing the grid first.
    Axes of one value are kept as the fields every shell shares."""

    def __init__(self, axes, ratios, resolution):
        self.fixed = {k: axes[k][0] for k in GRID_KEYS if len(axes[k]) == 1} | {"resolution": resolution}
        self.keys = tuple(k for k in GRID_KEYS if len(axes[k]) > 1)
        self.axes = tuple(tuple(axes[k]) for k in self.keys)
        self.ratios = frozenset(ratios)
        self.n = math.prod(len(a) for a in self.axes)
        self._last_first = tuple((len(a), a) for a in reversed(self.axes))

    def __len__(self):
        return self.n

    def __getitem__(self, i):
        if isinstance(i, slice):
            return [self[j] for j in range(*i.indices(self.n))]
        i = operator.index(i)
        if not -self.n <= i < self.n:
            raise IndexError(f"grid point {i} out of range ({self.n} points)")
        i %= self.n
        combo = []
        for size, axis in self._last_first:
            i, c = divmod(i, size)
            combo.append(axis[c])
        return self._shell(combo[::-1])

    def __iter__(self):
        return map(self._shell, itertools.product(*self.axes))

    def _shell(self, combo):
        if self.ratios:
            return Shell.unchecked(absolute({**self.fixed, **dict(zip(self.keys, combo))}, self.ratios))
        return Shell.unchecked(self.fixed, zip(self.keys, combo))

    def __repr__(self):
        return f"Grid({self.n} shells over {', '.join(self.keys) or 'one point'})"


def check(path, axes, ratios, resolution):
    """`Grid(axes, ratios, resolution)` once `Shell`'s checks pass for every
    point (module docstring); else InputError naming `path` and the first
    failing point's error."""
    first = {k: axes[k][0] for k in GRID_KEYS}
    groups = CHECK_GROUPS + tuple((k,) for k in GRID_KEYS if all(k not in g for g in CHECK_GROUPS))
    try:
        for group in groups:
            for combo in itertools.product(*(axes[k] for k in group)):
                Shell(**absolute({**first, **dict(zip(group, combo))}, ratios), resolution=resolution)
    except InputError:
        for combo in itertools.product(*(axes[k] for k in GRID_KEYS)):
            try:
                Shell(**absolute(dict(zip(GRID_KEYS, combo)), ratios), resolution=resolution)
            except InputError as err:
                raise InputError(f"{path}: [grid] {err}") from None
    return Grid(axes, ratios, resolution)
