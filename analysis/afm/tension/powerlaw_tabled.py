"""The time-domain shell's force on a recorded ramp and constant-height hold read from the
power-law table (`powerlaw_grid`, built by a campaign) instead of simulated: the model of
`powerlaw_fit` wherever the table holds the recording (SPEC 11-12).

At q = (x0, γ_a, K_B(1 s), β), K̃_S and R, the protocol is the simulator's
(`powerlaw_simulated.force_nN`): the ramp's speed v and contact time t_c from the line of the
recorded heights over the contact, its end t_end at depth δ_max = START_UM + v (t_end - t_c). With
ρ = v/R, K_eff = K_B(1 s) ρ^β, γ̃ = γ_a/K_eff, R_b = R (ρ/ρ_0)^(β/2) (`powerlaw_grid`):

    ramp, t_c < t ≤ t_end, e = v (t - t_c)/R, d = e + START_UM/R:
        F = R K_eff [γ̃ ĝ(d) + e q(e)]
    hold, τ = (t - t_end)/(t_end - t_c), d_max = δ_max/R, e_max = d_max - START_UM/R:
        F = R K_eff [γ̃ ĝ(d_max) + e_max q(e_max) r(τ; d_max)]

and before t_c the tension's alone, γ_a R ĝ(δ/R) at the recorded δ. q and r are interpolated over
the nodes (ln R_b, ln γ̃, ln K̃_S, β and, for r, ln d_max) by local Lagrange polynomials through
the POINTS nearest nodes of each axis (cubic; quadratic on an axis of three nodes), then along
e by a cubic spline (scipy's `CubicSpline`; q held at its first node above the sphere, 0 before
the contact) and along τ linearly in ln τ (linearly in τ below the first τ node, r(0) = 1).
scipy's RegularGridInterpolator is cubic only with four nodes an axis and builds its splines
over the whole grid at each call; the local weights are a contraction of 4^5 nodes.

The table holds a recording (`TabledForce.inside`) where every parameter lies within its axes
(EDGE_TOL beyond an end in its coordinate), the ramp within the deepest e, a hold at constant height within
d_max's axis and TAU_MAX, and no node it reads failed; elsewhere (and for constant-force holds)
`powerlaw_fit` simulates. `bench/powerlaw_ramp_hold.py --table` measures it against the simulator.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from functools import lru_cache
from importlib import resources
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt
from scipy.interpolate import CubicSpline

from analysis.afm.tension.powerlaw_grid import FORMAT
from analysis.afm.tension.powerlaw_simulated import START_UM
from common.errors import InputError, SolverError
from solver.droplet_table import DEPTH_MAX, unit_force_per_tension

if TYPE_CHECKING:
    from analysis.afm.tension.powerlaw_simulated import RampHold

Array = npt.NDArray[np.float64]
NAME = "powerlaw_table.json"
POINTS = 4              # nodes of each axis's local polynomial
EDGE_TOL = 1e-6         # how far beyond an axis's end (in its coordinate) still reads as inside


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

    @classmethod
    def from_document(cls, doc: dict[str, Any]) -> PowerLawTable:
        """The table of its JSON document (`powerlaw_grid.table_document`); InputError if it is not one."""
        if doc.get("format") != FORMAT:
            raise InputError(f"not a power-law ramp and hold table (format {doc.get('format')!r}, want {FORMAT!r})")
        axes = (np.log(doc["radius_um"]), np.log(doc["gamma_tilde"]), np.log(doc["shear_tilde"]),
                np.asarray(doc["beta"], float), np.log(doc["depth_over_radius"]))
        grid = tuple(np.asarray(a, float) for a in axes)
        q, r = (np.asarray(doc[k], dtype=float) for k in ("ramp_q", "hold_ratio"))    # null: NaN
        return cls(grid, np.asarray(doc["ramp_depths"], float), np.asarray(doc["hold_taus"], float), q, r,
                   float(doc["rate_per_s"]))

    def at(self, coords: Array) -> tuple[Array, Array] | None:
        """(q over the depths, r over (d_max, τ)) at (ln R_b, ln γ̃, ln K̃_S, β); None outside the axes
        or where a node it reads failed."""
        parts = [_weights(a, x) for a, x in zip(self.axes[:4], coords)]
        if any(p is None for p in parts):
            return None
        cut = tuple(slice(i, i + w.size) for i, w in parts)      # type: ignore[misc]
        ws = [w for _, w in parts]                                   # type: ignore[misc]
        q = np.einsum("a,b,c,d,abcde->e", *ws, self.q[cut])
        r = np.einsum("a,b,c,d,abcdef->ef", *ws, self.r[cut])
        return (q, r) if np.all(np.isfinite(q)) and np.all(np.isfinite(r)) else None


def _weights(nodes: Array, x: float) -> tuple[int, Array] | None:
    """(first node, Lagrange weights) of the local polynomial through the POINTS nodes nearest x
    (all of a shorter axis); None beyond the axis (EDGE_TOL)."""
    if not nodes[0] - EDGE_TOL <= x <= nodes[-1] + EDGE_TOL:
        return None
    m = min(POINTS, nodes.size)
    i = int(np.clip(np.searchsorted(nodes, x) - m // 2, 0, nodes.size - m))
    xs = nodes[i:i + m]
    w = np.array([np.prod([(x - xs[k]) / (xs[j] - xs[k]) for k in range(m) if k != j]) for j in range(m)])
    return i, w


@lru_cache(maxsize=1)
def shipped() -> PowerLawTable | None:
    """The shipped table (`analysis/calibration/data`), None where it is not there (the fit then
    simulates)."""
    source = resources.files("analysis.calibration") / "data" / NAME
    if not source.is_file():
        return None
    return PowerLawTable.from_document(json.loads(source.read_text()))


class TabledForce:
    """The force (nN) at a recording's raw samples for q = (x0, γ_a, K_B(1 s), β) from `table`
    (module doc), K̃_S `shear_tilde`, radius R; SolverError where the table does not hold q
    (`inside`, of the last q)."""

    def __init__(self, history: RampHold, radius_um: float, shear_tilde: float, table: PowerLawTable):
        self.history, self.radius, self.shear, self.table = history, radius_um, shear_tilde, table
        self.inside = False

    def __call__(self, q: Array) -> Array:
        h, R = self.history, self.radius
        x0, gamma, bulk, beta = (float(v) for v in q)
        try:
            v, t_c = h.speed_um_per_s(x0)
        except InputError:
            raise SolverError("the ramp has no line in contact at this contact point") from None
        t = h.time_s
        t_end = float(t[h.ramp_samples - 1])
        d_max = (START_UM + v * (t_end - t_c)) / R
        rho = v / R
        k_eff = bulk * rho ** beta
        coords = np.array([np.log(R * (rho / self.table.rate_per_s) ** (beta / 2)), np.log(max(gamma / k_eff, 1e-300)),
                           np.log(self.shear), beta])
        e_max = d_max - START_UM / R
        curves = self.table.at(coords) if 0 < e_max <= self.table.depths[-1] + EDGE_TOL else None
        held = t.size > h.ramp_samples
        self.inside = curves is not None and (not held or self._holds(d_max, t[-1] - t_end, t_end - t_c))
        if curves is None or not self.inside:
            raise SolverError("outside the power-law table")
        q_d, r = curves
        force = gamma * R * unit_force_per_tension(np.minimum(np.clip(x0 - h.x_um, 0.0, None) / R, DEPTH_MAX))
        ramp = (t > t_c) & (np.arange(t.size) < h.ramp_samples)
        e = v * (t[ramp] - t_c) / R
        force[ramp] = R * k_eff * (gamma / k_eff * unit_force_per_tension(e + START_UM / R) + e * self._q(q_d, e))
        if held:
            tau = (t[h.ramp_samples:] - t_end) / (t_end - t_c)
            ratio = self._r(r, d_max, tau)
            end = e_max * float(self._q(q_d, np.array([e_max]))[0])
            force[h.ramp_samples:] = R * k_eff * (gamma / k_eff * float(unit_force_per_tension(d_max)) + end * ratio)
        return force

    def _holds(self, d_max: float, hold_s: float, ramp_s: float) -> bool:
        """Whether the table holds the hold: at constant height, d_max within its axis, τ within TAU_MAX."""
        axis = self.table.axes[4]
        return (self.history.hold == "height" and axis[0] - EDGE_TOL <= np.log(d_max) <= axis[-1] + EDGE_TOL
                and hold_s / max(ramp_s, 1e-12) <= self.table.taus[-1] * (1 + 1e-9))

    def _q(self, q_e: Array, e: Array) -> Array:
        """q at the deformations e: a cubic spline over the table's, held at the first below it."""
        return CubicSpline(self.table.depths, q_e)(np.clip(e, self.table.depths[0], self.table.depths[-1]))

    def _r(self, r: Array, d_max: float, tau: Array) -> Array:
        """r at d_max over τ (module doc)."""
        part = _weights(self.table.axes[4], float(np.log(d_max)))
        assert part is not None
        i, w = part
        row = w @ r[i:i + w.size]
        taus = self.table.taus
        out = np.interp(np.log(np.maximum(tau, taus[1])), np.log(taus[1:]), row[1:])
        early = tau < taus[1]
        out[early] = row[0] + (row[1] - row[0]) * tau[early] / taus[1]
        return out
