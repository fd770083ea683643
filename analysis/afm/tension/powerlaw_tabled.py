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

and before t_c the tension's alone, γ_a R ĝ(δ/R) at the recorded δ. q and r are read at the
parameters (`analysis.calibration.powerlaw_table.PowerLawTable.at`, local polynomials over the
nodes), then along e by a cubic spline (`PowerLawTable.refined`: its values on REFINE times finer
depths, linear between them; q held at its first node, 0 before the contact), r over d_max by the same local polynomial and along τ linearly in ln τ (linearly
in τ below the first τ node, r(0) = 1).

The table holds a recording (`TabledForce.inside`) where every parameter lies within its axes
(EDGE_TOL beyond an end in its coordinate), the ramp within the deepest e, a hold at constant height within
d_max's axis and its longest τ, and no node it reads failed; elsewhere (and for constant-force holds)
`powerlaw_fit` simulates; so it does where a fit ends within EDGE_MARGIN of an axis's end
(`interior`; β = 0 aside), where the table's wall (no value beyond) and not the recording stopped
it. `bench/powerlaw_ramp_hold.py --table` measures it against the simulator.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from analysis.afm.tension.powerlaw_simulated import START_UM
from analysis.calibration.powerlaw_table import EDGE_TOL, PowerLawTable, weights
from common.errors import InputError, SolverError
from solver.droplet_table import DEPTH_MAX, unit_force_per_tension

if TYPE_CHECKING:
    from analysis.afm.tension.powerlaw_simulated import RampHold

Array = npt.NDArray[np.float64]
EDGE_MARGIN = 0.01      # how far inside an axis's ends (its coordinate) a fit must end to be the table's


class TabledForce:
    """The force (nN) at a recording's raw samples for q = (x0, γ_a, K_B(1 s), β) from `table`
    (module doc), K̃_S `shear_tilde`, radius R; SolverError where the table does not hold q
    (`inside`, of the last q)."""

    def __init__(self, history: RampHold, radius_um: float, shear_tilde: float, table: PowerLawTable):
        self.history, self.radius, self.shear, self.table = history, radius_um, shear_tilde, table
        self.inside = False
        self.interior = False
        self._line: tuple[float, tuple[float, float]] | None = None      # the last x0 and its (v, t_c)
        self._read: tuple[bytes, tuple[Array, Array] | None] | None = None   # the last coordinates and their curves

    def __call__(self, q: Array) -> Array:
        h, R = self.history, self.radius
        x0, gamma, bulk, beta = (float(v) for v in q)
        v, t_c = self._speed(x0)
        t = h.time_s
        t_end = float(t[h.ramp_samples - 1])
        d_max = (START_UM + v * (t_end - t_c)) / R
        rho = v / R
        k_eff = bulk * rho ** beta
        coords = np.array([np.log(R * (rho / self.table.rate_per_s) ** (beta / 2)), np.log(max(gamma / k_eff, 1e-300)),
                           np.log(self.shear), beta])
        e_max = d_max - START_UM / R
        curves = self._curves(coords) if 0 < e_max <= self.table.depths[-1] + EDGE_TOL else None
        held = t.size > h.ramp_samples
        self.inside = curves is not None and (not held or self._holds(d_max, t[-1] - t_end, t_end - t_c))
        self.interior = self.inside and self._interior(coords)
        if curves is None or not self.inside:
            raise SolverError("outside the power-law table")
        q_d, r = curves
        fine = self.table.refined(q_d)
        force = np.empty(t.size)
        n = h.ramp_samples
        free = np.nonzero(t[:n] <= t_c)[0]                                # before the contact: the tension's
        force[free] = gamma * R * unit_force_per_tension(np.minimum(np.clip(x0 - h.x_um[free], 0.0, None) / R,
                                                                    DEPTH_MAX))
        on = slice(free.size, n)                                          # t > t_c: the ramp in contact
        e = v * (t[on] - t_c) / R
        force[on] = R * k_eff * (gamma / k_eff * unit_force_per_tension(e + START_UM / R) + e * self._q(fine, e))
        if held:
            tau = (t[n:] - t_end) / (t_end - t_c)
            end = e_max * float(self._q(fine, np.array([e_max]))[0])
            force[n:] = R * k_eff * (gamma / k_eff * float(unit_force_per_tension(d_max)) + end * self._r(r, d_max, tau))
        return force

    def _speed(self, x0: float) -> tuple[float, float]:
        """The ramp's (v, t_c) at the contact x0 (`RampHold.speed_um_per_s`), the last kept: a
        finite-difference step in γ_a, K_B(1 s) or β does not move it."""
        if self._line is None or self._line[0] != x0:
            try:
                self._line = (x0, self.history.speed_um_per_s(x0))
            except InputError:
                raise SolverError("the ramp has no line in contact at this contact point") from None
        return self._line[1]

    def _curves(self, coords: Array) -> tuple[Array, Array] | None:
        """`PowerLawTable.at` the coordinates, the last kept (a step in x0 alone moves none)."""
        key = coords.tobytes()
        if self._read is None or self._read[0] != key:
            self._read = (key, self.table.at(coords))
        return self._read[1]

    def _interior(self, coords: Array) -> bool:
        """Whether (ln R_b, ln γ̃, ln K̃_S, β) lie EDGE_MARGIN inside the table's axes (β = 0, the
        elastic shell and β's own bound, counts as inside): a fit stopped at an edge is not the
        table's to read."""
        for k, (axis, x) in enumerate(zip(self.table.axes[:4], coords)):
            low = axis[0] + (0.0 if k == 3 and axis[0] == 0.0 else EDGE_MARGIN)
            if not low - EDGE_TOL <= x <= axis[-1] - EDGE_MARGIN:
                return False
        return True

    def _holds(self, d_max: float, hold_s: float, ramp_s: float) -> bool:
        """Whether the table holds the hold: at constant height, d_max within its axis, τ within its longest."""
        axis = self.table.axes[4]
        return (self.history.hold == "height" and axis[0] - EDGE_TOL <= np.log(d_max) <= axis[-1] + EDGE_TOL
                and hold_s / max(ramp_s, 1e-12) <= self.table.taus[-1] * (1 + 1e-9))

    def _q(self, fine: Array, e: Array) -> Array:
        """q at the deformations e from its values on the table's refined depths (`PowerLawTable.refined`),
        held at the first below them."""
        return np.interp(e, self.table.fine_depths, fine)

    def _r(self, r: Array, d_max: float, tau: Array) -> Array:
        """r at d_max over τ (module doc)."""
        part = weights(self.table.axes[4], float(np.log(d_max)))
        assert part is not None
        i, w = part
        row = w @ r[i:i + w.size]
        taus = self.table.taus
        out = np.interp(np.log(np.maximum(tau, taus[1])), np.log(taus[1:]), row[1:])
        early = tau < taus[1]
        out[early] = row[0] + (row[1] - row[0]) * tau[early] / taus[1]
        return out


def resolve(table: PowerLawTable | None) -> PowerLawTable:
    """`table`, or where None the shipped bundle's: the one place the default is read."""
    if table is not None:
        return table
    from analysis.afm.tension.calibration_parts import shipped_parts
    return shipped_parts().powerlaw
