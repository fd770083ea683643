"""The table behind the shell ramp model (`shell_ramp`): the force of the shell of
SPEC 2 pressed from just below its free sphere, in units of K_B R.

A cell of radius R with active tension γ_a and moduli K_B, K_S = K̃_S K_B is
stress-free at the gap h0 = 2R (1 - d0/2), d0 = D0 (the solver's start: the
free sphere itself has no plate contact), and pressed to h = 2R - δ. Its force

    F(δ) = K_B R f(δ/R, γ̃_a, K̃_S),   γ̃_a = γ_a / K_B,

is `solver.compress` (the fast solver) of `Shell(V, h0, dh = δ - d0 R)` at each
grid depth, on its own from h0 (at a finer or coarser mesh, RESOLUTIONS, where
the default one finds no equilibrium: they agree to 0.2 %). The scaling is
exact but for the bending stiffness B = t_c² (K_B + K_S)/24 with t_c = 0.2 µm, whose weight B/(K_B R²)
falls with R, and it is not small on a ramp: near the contact the boundary
layer sqrt(B/γ_a) is as wide as the contact itself, and the force of R = 5 µm
differs from that of R = 6.8 µm by 15 % at δ/R = 0.02 and 4 % at 0.15 (standard
bending). So f has a fourth axis, RADII R (µm, at t_c = 0.2 µm).

The grid: DEPTHS δ/R from D0 to 0.15 (the deepest the solver reaches from h0
for every cell of the grid; denser near D0, where the force bends most), GAMMAS
γ̃_a 0.003-0.5, SHEARS K̃_S 0.08-2.5, both log-spaced. `build` returns the
table as a JSON-ready dict (f[depth][gamma][shear][radius]; the depths no mesh
solves, 23 of 21,600, filled in by `fill`); `python -m
analysis.afm.tension.shell_table FILE` writes it (about 4 minutes).
"""

import json
import sys
import time
from typing import Any

import numpy as np

from common.errors import SolverError

D0 = 0.0075
RADII_UM = np.geomspace(4.0, 13.5, 5)
BULK_MN_PER_M = 10.0
DEPTHS = D0 + (0.15 - D0) * np.linspace(0.0, 1.0, 40) ** 1.4
GAMMAS = np.geomspace(0.003, 0.5, 12)
SHEARS = np.geomspace(0.08, 2.5, 9)
FORMAT = "cortex-shell-ramp-table"
RESOLUTIONS = (1.0, 1.25, 0.8, 1.5)   # a depth the solver misses at one mesh is tried at the next


def shell_forces_nN(radius_um: float, depths_um: np.ndarray, tension_mN_per_m: float, bulk_mN_per_m: float,
                    shear_mN_per_m: float, start_um: float, bending: str = "standard") -> np.ndarray:
    """F (nN) of the shell stress-free at the gap 2R - `start_um`, pressed to the
    deformations δ = `depths_um` (> start_um; the droplet's force at or above it),
    each solved on its own from the start; NaN where no mesh finds an equilibrium."""
    from solver import Shell, compress
    from solver.droplet_table import unit_force_per_tension
    volume = 4.0 * np.pi * radius_um ** 3 / 3.0
    depths = np.asarray(depths_um, float)
    out = tension_mN_per_m * radius_um * unit_force_per_tension(depths / radius_um)
    for i in np.flatnonzero(depths > start_um):
        out[i] = np.nan
        for resolution in RESOLUTIONS:
            shell = Shell(volume_um3=volume, h0_um=2.0 * radius_um - start_um, dh_um=depths[i] - start_um,
                          bulk_mN_per_m=bulk_mN_per_m, shear_mN_per_m=shear_mN_per_m,
                          tension_mN_per_m=tension_mN_per_m, bending=bending, resolution=resolution)
            try:
                out[i] = compress(shell, "fast").solution.force_nN
                break
            except SolverError:
                continue
    return out


def unit_forces(gamma_tilde: float, shear_tilde: float, depths: np.ndarray = DEPTHS,
                radius_um: float = 6.8, bending: str = "standard") -> np.ndarray:
    """F/(K_B R) of one cell at deformations δ/R = `depths` (the table's start D0
    R), NaN where the solver finds no equilibrium."""
    forces = shell_forces_nN(radius_um, np.asarray(depths, float) * radius_um, gamma_tilde * BULK_MN_PER_M,
                             BULK_MN_PER_M, shear_tilde * BULK_MN_PER_M, D0 * radius_um, bending)
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
    from solver.droplet_table import unit_force_per_tension
    f = np.full((DEPTHS.size, GAMMAS.size, SHEARS.size, RADII_UM.size), np.nan)
    for j, g in enumerate(GAMMAS):
        for k, s in enumerate(SHEARS):
            for m, r in enumerate(RADII_UM):
                f[:, j, k, m] = unit_forces(float(g), float(s), radius_um=float(r), bending=bending)
    f[0] = (GAMMAS * unit_force_per_tension(D0))[:, None, None]       # the reference: tension only
    f, filled = fill(f)
    return {"format": FORMAT, "bending": bending, "d0": D0, "radius_um": RADII_UM.tolist(),
            "depth_over_radius": DEPTHS.tolist(), "gamma_tilde": GAMMAS.tolist(), "shear_tilde": SHEARS.tolist(),
            "force_over_kb_r": f.tolist(), "filled": filled,
            "built": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}


if __name__ == "__main__":
    with open(sys.argv[1], "w") as fh:
        json.dump(build(), fh)
