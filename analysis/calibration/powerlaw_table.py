"""The power-law ramp and hold table read (`PowerLawTable`): the time-domain shell's ramp from its
stress-free droplet and the constant-height hold after it, per node, for the tabled simulator of
`cortex afm tension`'s power-law reading (`analysis.afm.tension.powerlaw_tabled`; the table's
units and scaling: `analysis.afm.tension.powerlaw_grid`, which builds it by a campaign).

q (over the ramp's deformations e) and r (over d_max and the hold's τ) are read at a cell's
(ln R_b, ln γ̃, ln K̃_S, β) by local Lagrange polynomials through the POINTS nearest nodes of each
axis (cubic; quadratic on an axis of three nodes), one contraction of the POINTS^4 nodes around
it (scipy's RegularGridInterpolator is cubic only with four nodes an axis and builds its splines
over the whole grid at each call). Outside an axis (EDGE_TOL beyond its end, in its coordinate)
or where a node it reads failed, the table holds no value.

The shipped table is `data/powerlaw_table.json` (`NAME`), a part of the calibration bundle
(`analysis.calibration.file`, part `powerlaw_table`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt
from scipy.interpolate import CubicSpline

from common.errors import InputError

Array = npt.NDArray[np.float64]
NAME = "powerlaw_table.json"
FORMAT = "cortex-powerlaw-ramp-hold-table"
POINTS = 4              # nodes of each axis's local polynomial
EDGE_TOL = 1e-6         # how far beyond an axis's end (in its coordinate) still reads as inside
AXES = ("radius_um", "gamma_tilde", "shear_tilde", "beta", "depth_over_radius")
REFINE = 16             # the cubic spline of q over the depths read on this many times finer depths (`refined`)


@dataclass(frozen=True)
class PowerLawTable:
    """The table's axes (coordinates: ln R_b, ln γ̃, ln K̃_S, β, ln d_max), its ramp depths e and hold
    times τ, q (R_b, γ̃, K̃_S, β, d) and r (R_b, γ̃, K̃_S, β, d_max, τ), and its ρ_0 (1/s)."""

    axes: tuple[Array, Array, Array, Array, Array]
    depths: Array
    taus: Array
    q: Array
    r: Array
    rate_per_s: float
    fine_depths: Array = field(init=False, repr=False, compare=False)
    spline_map: Array = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        d = self.depths
        fine = np.unique(np.concatenate([np.linspace(a, b, REFINE + 1) for a, b in zip(d[:-1], d[1:])])) \
            if d.size > 1 else d.copy()
        object.__setattr__(self, "fine_depths", fine)
        object.__setattr__(self, "spline_map", CubicSpline(d, np.eye(d.size))(fine) if d.size > 1
                           else np.ones((fine.size, 1)))

    def refined(self, q_depths: Array) -> Array:
        """q's cubic spline (not-a-knot, scipy's `CubicSpline`) over the depths, at `fine_depths`:
        a spline is linear in its values, so one product with `spline_map`."""
        return np.asarray(self.spline_map @ q_depths, float)

    def at(self, coords: Array) -> tuple[Array, Array] | None:
        """(q over the depths, r over (d_max, τ)) at (ln R_b, ln γ̃, ln K̃_S, β); None outside the axes
        or where a node it reads failed."""
        parts = [weights(a, x) for a, x in zip(self.axes[:4], coords)]
        if any(p is None for p in parts):
            return None
        cut = tuple(slice(i, i + w.size) for i, w in parts)      # type: ignore[misc]
        ws = [w for _, w in parts]                                   # type: ignore[misc]
        w = ws[0]
        for wk in ws[1:]:
            w = np.multiply.outer(w, wk)                              # the nodes' weights, (4, 4, 4, 4)
        q, r = np.tensordot(w, self.q[cut], axes=4), np.tensordot(w, self.r[cut], axes=4)
        return (q, r) if np.all(np.isfinite(q)) and np.all(np.isfinite(r)) else None


def weights(nodes: Array, x: float) -> tuple[int, Array] | None:
    """(first node, Lagrange weights) of the local polynomial through the POINTS nodes nearest x
    (all of a shorter axis); None beyond the axis (EDGE_TOL)."""
    if not nodes[0] - EDGE_TOL <= x <= nodes[-1] + EDGE_TOL:
        return None
    m = min(POINTS, nodes.size)
    i = int(np.clip(np.searchsorted(nodes, x) - m // 2, 0, nodes.size - m))
    xs = nodes[i:i + m]
    gap = xs[:, None] - xs[None, :] + np.eye(m)                   # x_j - x_k, 1 on the diagonal
    factors = np.where(np.eye(m, dtype=bool), 1.0, (x - xs[None, :]) / gap)
    return i, factors.prod(axis=1)                                # w_j = Π_{k≠j} (x - x_k)/(x_j - x_k)


def from_document(doc: dict[str, Any], where: str = "power-law table") -> PowerLawTable:
    """The table of its JSON document (`powerlaw_grid.table_document`); InputError (one line) if it
    is not one, an axis is not increasing (positive but β), or q and r do not fill the axes."""
    keys = AXES + ("ramp_depths", "hold_taus", "ramp_q", "hold_ratio", "rate_per_s")
    if doc.get("format") != FORMAT or any(k not in doc for k in keys):
        raise InputError(f"{where}: not a power-law ramp and hold table (rebuild: make powerlaw-table)")
    try:
        raw = [np.asarray(doc[k], float) for k in AXES + ("ramp_depths", "hold_taus")]
        q, r = (np.asarray(doc[k], dtype=float) for k in ("ramp_q", "hold_ratio"))     # null: NaN
        rate = float(doc["rate_per_s"])
    except (TypeError, ValueError):
        raise InputError(f"{where}: the power-law table's axes and values must be numbers") from None
    if any(a.ndim != 1 or a.size < 1 or not np.all(np.diff(a) > 0) for a in raw) \
            or min(a[0] for k, a in zip(AXES, raw) if k != "beta") <= 0 or raw[3][0] < 0 or rate <= 0:
        raise InputError(f"{where}: the power-law table's axes must be increasing, positive (beta from 0)")
    sizes = tuple(a.size for a in raw)
    if q.shape != sizes[:4] + sizes[5:6] or r.shape != sizes[:5] + sizes[6:]:
        raise InputError(f"{where}: the power-law table's values do not fill its axes")
    axes = (np.log(raw[0]), np.log(raw[1]), np.log(raw[2]), raw[3], np.log(raw[4]))
    return PowerLawTable(axes, raw[5], raw[6], q, r, rate)
