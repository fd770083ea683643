"""The table behind the shell ramp model (`shell_ramp`; read by
`analysis.calibration.ramp_table`): the force of the shell of SPEC 2 pressed
from its free sphere, in units of K_B R.

A cell of radius R with active tension γ_a and moduli K_B, K_S = K̃_S K_B,
stress-free as the free sphere, pressed to the gap h = 2R - δ:

    F(δ) = K_B R f(δ/R, γ̃_a, K̃_S, R),   γ̃_a = γ_a / K_B,

one continuation over the grid's depths per cell and mesh (`solver.ramp.ramp_forces_nN`,
the fast solver). The scaling is exact but for the bending stiffness
B = t_c² (K_B + K_S)/24 with t_c = 0.2 µm, whose weight B/(K_B R²) falls with
R, and it is not small on a ramp: near the contact the boundary layer
sqrt(B/γ_a) is as wide as the contact itself (the force of R = 5 µm differs
from that of R = 6.8 µm by 15 % at δ/R = 0.02 and 4 % at 0.15, standard
bending). So f has a fourth axis, RADII R (µm, at t_c = 0.2 µm).

The mesh: near the sphere the contact spans few elements, and the solver at the
ramp's resolution r = 2 reads f low (up to 14.9 % below r = 8 at δ/R = 0.0013,
0.6 % at 0.0126). Each node is therefore computed at r and at MESH_RATIO r = 4,
and the table holds their Richardson extrapolation

    f = f(2r) + (f(2r) - f(r)) / (2^p - 1),   p = ORDER = 2,

the error falling as r^(-p). The order was measured with r = 2, 4, 8 at the
table's corners (`bench/ramp_table.py solver`: p = log2((f4 - f2)/(f8 - f4))
at the depths δ/R 0.0013-0.024, over the 32 corners where r = 8 converges and
r = 2 is more than 0.1 % off: median 2.0-2.3 at every depth; the error of r = 2
falls about fourfold per doubling). With it the extrapolation of 2 and 4 is
within 1.3 % of r = 8 at δ/R = 0.0013, 0.65 % at 0.0035, 0.16 % at 0.006 and
0.09 % deeper, and a tension-only shell within 0.37 % of the exact droplet at
0.0013 (docs/ramp.md). A depth that either mesh does not solve is NaN (filled
by `fill`).

The grid: DEPTHS δ/R to 0.3 (48, denser near the sphere, where the force bends
most), GAMMAS γ̃_a 0.003-0.5, SHEARS K̃_S 0.08-2.5, both log-spaced, RADII
4-13.5 µm. The table is built by the campaign engine: `campaigns/ramp.toml`
(`[campaign] task = "analysis.afm.tension.shell_table:ramp_table"`, the kind `KIND`) runs one
task per node (γ̃_a, K̃_S, R) over any number of ranks, resumably (`node_results`: f at every
depth, a depth whose continuation stalls filled in along depth by `fill`), and `from_store`
(`cortex analysis build-ramp-table`) makes the table's document
(f[depth][gamma][shear][radius]) from the finished store.
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from campaign.kinds import Kind, register
from common.errors import InputError, SolverError

if TYPE_CHECKING:
    from solver.model import Shell

D0 = 0.0        # the reference: the free sphere itself
RADII_UM = np.geomspace(4.0, 13.5, 5)
BULK_MN_PER_M = 10.0
RAMP_DEPTHS = 48
DEPTHS = 0.3 * np.linspace(0.0, 1.0, RAMP_DEPTHS + 1)[1:] ** 1.4
GAMMAS = np.geomspace(0.003, 0.5, 12)
SHEARS = np.geomspace(0.08, 2.5, 9)
MESH_RATIO = 2.0        # the second mesh: MESH_RATIO times the node's resolution
ORDER = 2.0             # the mesh error's order p, measured (module doc)
FORMAT = "cortex-shell-ramp-table"
TASK = "ramp_table"        # the task kind (`campaign.kinds`, `KIND`) that computes a node
# a node's results, the store's columns: F/(K_B R) at each depth δ/R as force_over_kb_r_d{i:02d}
# (dimensionless, a stalled depth filled along depth), and `filled_depths`, how many were filled
RAMP_RESULTS = tuple(f"force_over_kb_r_d{i:02d}" for i in range(RAMP_DEPTHS)) + ("filled_depths",)


def radius_um(volume_um3: float) -> float:
    """The free sphere's radius R (µm) of volume V: (3 V / 4π)^(1/3)."""
    return float(np.cbrt(3.0 * volume_um3 / (4.0 * np.pi)))


def unit_forces(gamma_tilde: float, shear_tilde: float, depths: np.ndarray = DEPTHS,
                radius_um: float = 6.8, bending: str = "standard") -> np.ndarray:
    """F/(K_B R) of one cell at deformations δ/R = `depths` (increasing) of its
    free sphere, as the table holds it: the Richardson extrapolation of two
    continuations (`extrapolated_forces`); NaN where either stalls."""
    volume = 4.0 * np.pi * radius_um ** 3 / 3.0
    return extrapolated_forces(volume, radius_um, np.asarray(depths, float), BULK_MN_PER_M,
                               shear_tilde * BULK_MN_PER_M, gamma_tilde * BULK_MN_PER_M, bending)


def richardson(coarse: npt.ArrayLike, fine: npt.ArrayLike, ratio: float = MESH_RATIO,
               order: float = ORDER) -> np.ndarray:
    """The Richardson extrapolation f(2r) + (f(2r) - f(r)) / (ratio^p - 1) of values on a
    coarse and a `ratio` times finer mesh whose error falls as r^(-p) (module doc)."""
    fine = np.asarray(fine, float)
    return fine + (fine - np.asarray(coarse, float)) / (ratio ** order - 1.0)


def extrapolated_forces(volume_um3: float, radius_um: float, depths: np.ndarray, bulk: float, shear: float,
                        tension: float, bending: str, thickness_um: float = 0.2,
                        resolution: float | None = None) -> np.ndarray:
    """F/(K_B R) at δ/R = `depths` extrapolated (`richardson`) from the continuations at
    `resolution` (default the ramp's) and MESH_RATIO times it; NaN where either stalls."""
    from solver.ramp import RESOLUTION
    coarse = RESOLUTION if resolution is None else resolution
    args = (volume_um3, radius_um, depths, bulk, shear, tension, bending, thickness_um)
    return richardson(forces(*args, coarse), forces(*args, MESH_RATIO * coarse))


def forces(volume_um3: float, radius_um: float, depths: np.ndarray, bulk: float, shear: float,
           tension: float, bending: str, thickness_um: float = 0.2, resolution: float | None = None) -> np.ndarray:
    """F/(K_B R) at δ/R = `depths` of one continuation at `resolution` (default the ramp's);
    all NaN if it stalls."""
    from solver.ramp import RESOLUTION, ramp_forces_nN
    try:
        f = ramp_forces_nN(volume_um3, depths * radius_um, bulk, shear, tension, bending, thickness_um,
                           RESOLUTION if resolution is None else resolution)
    except SolverError:
        return np.full(len(depths), np.nan)
    return f / (bulk * radius_um)


def fill(f: np.ndarray, gamma_tilde: float) -> tuple[np.ndarray, int]:
    """One node's f over DEPTHS with each depth no mesh solved interpolated along
    depth from the solved ones (these kept as they are), and how many there were:
    the elastic share q = (f - γ̃ ĝ)/(δ/R - D0) is smooth in δ/R (`ramp_table`)."""
    from analysis.calibration.ramp_table import elastic_scale
    from solver.droplet_table import unit_force_per_tension
    missing = ~np.isfinite(f)
    if not missing.any():
        return f, 0
    tension = gamma_tilde * unit_force_per_tension(DEPTHS)
    scale = np.maximum(elastic_scale(DEPTHS, D0), 1e-12)
    q = (f - tension) / scale
    out = f.copy()
    out[missing] = tension[missing] + np.interp(DEPTHS[missing], DEPTHS[~missing], q[~missing]) * scale[missing]
    return out, int(missing.sum())


def node_results(shell: Shell) -> dict[str, float]:
    """One campaign task: the node (γ̃_a = γ_a/K_B, K̃_S = K_S/K_B, R of V, bending) of
    `shell` (its h0 and dh play no part), f at every depth extrapolated from the
    node's resolution and MESH_RATIO times it (`extrapolated_forces`) and filled
    (`fill`), as the store's result columns RAMP_RESULTS."""
    radius = radius_um(shell.volume_um3)
    f = extrapolated_forces(shell.volume_um3, radius, DEPTHS, shell.bulk_mN_per_m, shell.shear_mN_per_m,
                shell.tension_mN_per_m, shell.bending, shell.thickness_um, shell.resolution)
    if not np.isfinite(f).any():
        raise SolverError("the continuation stalled at every depth")
    f, filled = fill(f, shell.tension_mN_per_m / shell.bulk_mN_per_m)
    return dict(zip(RAMP_RESULTS, [*map(float, f), float(filled)]))


def table_document(radii_um: npt.ArrayLike, gammas: npt.ArrayLike, shears: npt.ArrayLike,
                   f: np.ndarray, filled: int, bending: str = "standard", resolution: float = 2.0) -> dict[str, Any]:
    """The table's JSON document (`analysis.calibration.ramp_table.ShellTable`) from its axes and f of shape
    (depth, gamma, shear, radius), extrapolated from the mesh `resolution` and MESH_RATIO times it."""
    mesh = {"resolutions": [resolution, MESH_RATIO * resolution], "extrapolation": "richardson", "order": ORDER}
    return {"format": FORMAT, "bending": bending, "d0": D0, "mesh": mesh,
            "radius_um": np.asarray(radii_um, float).tolist(),
            "depth_over_radius": DEPTHS.tolist(), "gamma_tilde": np.asarray(gammas, float).tolist(),
            "shear_tilde": np.asarray(shears, float).tolist(), "force_over_kb_r": f.tolist(), "filled": filled}


def from_store(path: str | os.PathLike[str]) -> dict[str, Any]:
    """The table's document from a finished ramp-table campaign store
    (`campaigns/ramp.toml`): the axes γ̃_a, K̃_S and R (of V) from the campaign file the
    store keeps, each node's forces from the row of its parameters. InputError for a
    store of another campaign, or unless every node is done."""
    import tomllib

    from campaign.config import DEFAULTS
    from campaign.store.reader import read_provenance, read_results
    text = read_provenance(path).get("config_text", "")        # the campaign file, as run
    doc = tomllib.loads(text) if text else {}
    grid = {**DEFAULTS, **doc.get("grid", {})}
    keys = ("volume_um3", "gamma_tilde", "ks_tilde")
    if str(doc.get("campaign", {}).get("task", "")).rpartition(":")[2] != TASK or not isinstance(grid["bending"], str) \
            or not set(keys) <= set(grid):
        raise InputError(f"{path}: not a store of a ramp-table campaign over volume_um3, gamma_tilde and "
                         f"ks_tilde, one bending ([campaign] task = \"analysis.afm.tension.shell_table:{TASK}\": "
                         "campaigns/ramp.toml)")
    volumes, gammas, shears = (np.atleast_1d(np.asarray(grid[k], float)) for k in keys)
    rows = read_results(path)
    undone = int((rows["state"] != "done").sum())
    if undone:
        raise InputError(f"{path}: {undone} of {len(rows)} nodes not done; finish the campaign "
                         "(run it again: it resumes)")
    bulk = rows["bulk_mN_per_m"].to_numpy()
    at = [_index(volumes, rows["volume_um3"]), _index(gammas, rows["tension_mN_per_m"] / bulk),
          _index(shears, rows["shear_mN_per_m"] / bulk)]
    f = np.full((DEPTHS.size, gammas.size, shears.size, volumes.size), np.nan)
    f[:, at[1], at[2], at[0]] = rows[list(RAMP_RESULTS[:-1])].to_numpy().T
    radii = [radius_um(v) for v in volumes]
    resolution = float(doc.get("solver", {}).get("resolution", 1.0))       # campaign.config's default
    return table_document(radii, gammas, shears, f, int(rows["filled_depths"].sum()), grid["bending"], resolution)


def _index(axis: np.ndarray, values: Any) -> np.ndarray:
    """Each value's position on `axis` (its nearest node, relative)."""
    values = np.asarray(values, float)
    return np.abs(values[:, None] / axis[None, :] - 1.0).argmin(axis=1)


if __name__ == "__main__":
    import sys
    print("the shell ramp table is built by the campaign engine: make ramp-table "
          "(campaigns/ramp.toml, then cortex analysis build-ramp-table; docs/ramp.md)", file=sys.stderr)
    sys.exit(2)


KIND = register(Kind(TASK, 1, dict.fromkeys(RAMP_RESULTS, "1"), node_results,
                     doc="one node of the shell ramp table: F/(K_B R) over its depths, two meshes extrapolated"))
