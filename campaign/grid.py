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

What a new store needs of every point, its parameters (`columns`), its
task id and the text its fingerprint hashes (`texts`), is made from the
axes without making the shells: the column of axis k is a_k[c_k] over all
i at once, and a point's text is a template filled with its axes' values
each printed once (10,000 points: 1 ms and 7 ms, against ~60 ms through
the shells).
"""

import itertools
import math
import operator
from collections.abc import Iterator, Sequence

from common.errors import InputError
from solver.geometry import cell_radius
from solver.model import Shell

GRID_KEYS = ("volume_um3", "h0_um", "dh_um", "bulk_mN_per_m", "shear_mN_per_m",
             "tension_mN_per_m", "thickness_um", "bending", "viscosity_Pa_s", "frequency_hz")
OPTIONAL = ("viscosity_Pa_s", "frequency_hz")     # absent: an elastic cell
CHECK_GROUPS = (("volume_um3", "h0_um", "dh_um"), ("bulk_mN_per_m", "shear_mN_per_m", "tension_mN_per_m"),
                OPTIONAL)                      # the fields one of Shell's checks reads together


def absolute(p, ratios, radius=None):
    """A grid point (a dict) with its dimensionless coordinates (the keys of
    `ratios`) turned into absolute ones, in place; `radius` R_cell(V) at its
    volume where known (else computed). The same operations, in the same
    order, on a dict of columns (numpy arrays) give each point's values bit
    for bit (`Grid.columns`)."""
    if "h0_um" in ratios:
        r = float(cell_radius(p["volume_um3"])) if radius is None else radius
        p["h0_um"] = 2.0 * r * p["h0_um"] + 0.5 * p["dh_um"]
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

    def indices(self):
        """{varying key: its coordinate c_k at every point, in order} (int arrays)."""
        import numpy as np
        out, stride = {}, self.n
        for key, axis in zip(self.keys, self.axes):
            stride //= len(axis)
            out[key] = np.arange(self.n) // stride % len(axis)
        return out

    def columns(self):
        """{GRID_KEYS key: its value at every point, in order}: floats as a
        float64 array (NaN for an absent optional value), `bending` as an array
        of str; a dimensionless axis made absolute with `absolute` on the
        columns, R_cell(V) computed once per volume as for one shell."""
        import numpy as np
        at = self.indices()
        cols = {k: np.full(self.n, np.nan if v is None else v, object if k == "bending" else float)
                for k, v in self.fixed.items() if k in GRID_KEYS}
        for key, axis in zip(self.keys, self.axes):
            cols[key] = np.array(axis, None if key == "bending" else float)[at[key]]
        radius = None
        if "h0_um" in self.ratios:
            volumes = self.axes[self.keys.index("volume_um3")] if "volume_um3" in at else [self.fixed["volume_um3"]]
            radius = np.array([float(cell_radius(v)) for v in volumes])[at.get("volume_um3", 0)]
        return absolute(cols, self.ratios, radius)

    def texts(self, template, keys, encode):
        """`template % tuple(encode(value of k) for k in keys)` at every point,
        in order (`keys` among `Shell.to_dict`'s), without making the shells:
        each axis's values and each fixed field are encoded once, a
        dimensionless axis's absolute values once per point (`columns`). What
        a campaign's fingerprint and task ids are made of: 10,000 texts in
        ~7 ms, against ~40 ms through the shells."""
        derived = [k for k in keys if k in self.ratios]
        cols = self.columns() if derived else {}
        rows: Iterator[tuple] = itertools.product(*[[encode(v) for v in axis] for axis in self.axes])
        if derived:
            rows = map(operator.add, rows, zip(*[map(encode, cols[k].tolist()) for k in derived]))
        first = self[0].to_dict()                  # the fields every point shares (a varying one's is never read)
        fixed = tuple(encode(first[k]) for k in keys)
        place = {k: i for i, k in enumerate(self.keys)} | {k: len(self.keys) + i for i, k in enumerate(derived)}
        width = len(self.keys) + len(derived)
        pick = operator.itemgetter(*[place.get(k, width + i) for i, k in enumerate(keys)])
        return map(template.__mod__, map(pick, map(operator.add, rows, itertools.repeat(fixed))))

    def reprs(self):
        """repr(shell.to_dict()) of every point, in order (`texts`): what the
        campaign's fingerprint is made of."""
        names = list(self[0].to_dict())
        return self.texts("{" + ", ".join(f"{n!r}: %s" for n in names) + "}", names, repr)

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
