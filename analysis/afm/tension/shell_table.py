"""The table behind the shell ramp model (`shell_ramp`): the force of the shell of
SPEC 2 pressed from its free sphere, in units of K_B R.

A cell of radius R with active tension γ_a and moduli K_B, K_S = K̃_S K_B,
stress-free as the free sphere, pressed to the gap h = 2R - δ:

    F(δ) = K_B R f(δ/R, γ̃_a, K̃_S, R),   γ̃_a = γ_a / K_B,

one continuation over the grid's depths per cell (`solver.ramp.ramp_forces_nN`,
the fast solver). The scaling is exact but for the bending stiffness
B = t_c² (K_B + K_S)/24 with t_c = 0.2 µm, whose weight B/(K_B R²) falls with
R, and it is not small on a ramp: near the contact the boundary layer
sqrt(B/γ_a) is as wide as the contact itself (the force of R = 5 µm differs
from that of R = 6.8 µm by 15 % at δ/R = 0.02 and 4 % at 0.15, standard
bending). So f has a fourth axis, RADII R (µm, at t_c = 0.2 µm).

The grid: DEPTHS δ/R to 0.3 (48, denser near the sphere, where the force bends
most), GAMMAS γ̃_a 0.003-0.5, SHEARS K̃_S 0.08-2.5, both log-spaced, RADII
4-13.5 µm. `build` returns the table as a JSON-ready dict
(f[depth][gamma][shear][radius]; a cell whose continuation stalls is filled in
along depth by `fill`); `python -m analysis.afm.tension.shell_table FILE`
writes it.
"""

import json
import sys
import time
from typing import Any

import numpy as np

from common.errors import SolverError

D0 = 0.0        # the reference: the free sphere itself
RADII_UM = np.geomspace(4.0, 13.5, 5)
BULK_MN_PER_M = 10.0
DEPTHS = 0.3 * np.linspace(0.0, 1.0, 49)[1:] ** 1.4
GAMMAS = np.geomspace(0.003, 0.5, 12)
SHEARS = np.geomspace(0.08, 2.5, 9)
FORMAT = "cortex-shell-ramp-table"


def unit_forces(gamma_tilde: float, shear_tilde: float, depths: np.ndarray = DEPTHS,
                radius_um: float = 6.8, bending: str = "standard") -> np.ndarray:
    """F/(K_B R) of one cell at deformations δ/R = `depths` (increasing) of its
    free sphere: one continuation of `solver.ramp.ramp_forces_nN`; NaN where it stalls."""
    from solver.ramp import ramp_forces_nN
    volume = 4.0 * np.pi * radius_um ** 3 / 3.0
    try:
        forces = ramp_forces_nN(volume, np.asarray(depths, float) * radius_um, BULK_MN_PER_M,
                                shear_tilde * BULK_MN_PER_M, gamma_tilde * BULK_MN_PER_M, bending)
    except SolverError:
        return np.full(len(depths), np.nan)
    return forces / (BULK_MN_PER_M * radius_um)


def fill(f: np.ndarray) -> tuple[np.ndarray, int]:
    """f with each depth no mesh solved interpolated along the depth axis from its
    column's solved ones (f[depth][gamma][shear][radius]), and how many there were:
    the elastic share q = (f - γ̃ ĝ)/(δ/R - D0)² is smooth in δ/R (`shell_ramp`)."""
    from solver.droplet_table import unit_force_per_tension
    tension = GAMMAS[None, :, None, None] * unit_force_per_tension(DEPTHS)[:, None, None, None]
    scale = np.maximum(DEPTHS - D0, 1e-12)[:, None, None, None] ** 2
    q = (f - tension) / scale
    missing = ~np.isfinite(q)
    for j, k, m in zip(*np.nonzero(missing.any(axis=0))):
        col = q[:, j, k, m]
        ok = np.isfinite(col)
        col[~ok] = np.interp(DEPTHS[~ok], DEPTHS[ok], col[ok])
    return tension + q * scale, int(missing.sum())


def build(bending: str = "standard") -> dict[str, Any]:
    """The table (module doc) as a dict: its axes and f."""
    f = np.full((DEPTHS.size, GAMMAS.size, SHEARS.size, RADII_UM.size), np.nan)
    for j, g in enumerate(GAMMAS):
        for k, s in enumerate(SHEARS):
            for m, r in enumerate(RADII_UM):
                f[:, j, k, m] = unit_forces(float(g), float(s), radius_um=float(r), bending=bending)
    f, filled = fill(f)
    return {"format": FORMAT, "bending": bending, "d0": D0, "radius_um": RADII_UM.tolist(),
            "depth_over_radius": DEPTHS.tolist(), "gamma_tilde": GAMMAS.tolist(), "shear_tilde": SHEARS.tolist(),
            "force_over_kb_r": f.tolist(), "filled": filled,
            "built": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}


if __name__ == "__main__":
    with open(sys.argv[1], "w") as fh:
        json.dump(build(), fh)
