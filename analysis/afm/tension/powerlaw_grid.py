"""The table behind the tabled power-law shell (`powerlaw_tabled`): the time-domain shell's
force (`powerlaw_simulated.simulated`, the model of `powerlaw_fit`) on a ramp from its
stress-free droplet at constant speed and the constant-height hold after it, in the units in
which a pure power law's ramp has no time scale (SPEC 11-12).

Scaling. A cell of radius R pressed at speed v, ρ = v/R: at the deformation d = δ/R the time
since the contact is d/ρ, so K_B(t) = K_B(1 s) t^-β = K_eff (ρ t)^-β with
K_eff = K_B(1 s) ρ^β, and the force is

    F = R K_eff [γ̃ ĝ(d) + e q(e; γ̃, K̃_S, β, R_b)],   γ̃ = γ_a / K_eff,   e = d - START_UM/R,

ĝ the droplet's unit force (`solver.droplet_table`, the tension alone), e the deformation
since the cortex was stress-free (the droplet at START_UM, `powerlaw_simulated`) and q the
elastic share over it (finite as e → 0: `analysis.calibration.ramp_table`; taken over d, the
start's START_UM/R would differ between R and R_b, which moves the force at δ = 0.02 µm by
10-30 %). A hold at constant height after a ramp to d_max (e_max), at τ = (t - t_end)/T since
it began (T the ramp's time in contact):

    F = R K_eff [γ̃ ĝ(d_max) + e_max q(e_max) r(τ; d_max, γ̃, K̃_S, β, R_b)],   r(0) = 1.

The bending stiffness B = t_c² (K_B(1 s) + K_S(1 s))/24 is elastic at K(1 s) (`solver.time_domain`),
so its weight B/(K_eff R²) ∝ ρ^-β/R²: the table, made at RATE_PER_S = ρ_0, holds it at the
radius R_b = R (ρ/ρ_0)^(β/2). The scaling is not exact (the cortex's Prony series and the
simulator's steps are in seconds and µm): on the shipped table, a cell at ρ = 0.05/s and 1/s
against ρ_0 = 0.15/s (R_b 7.35 µm, β 0.3) reads 0.1-0.3 % off on the hold, the ramp 0.1 % and
0.75-1.6 % (`bench/powerlaw_ramp_hold.py --table`: the 40 bench cells within 0.20 % of their peak
force on the ramp and 0.19 % on the hold, median).

A node (`node_results`, one campaign task: `campaigns/powerlaw-table.toml`, the kind `KIND`, its
`[params]` beta and depth_over_radius, the grid's volume_um3 (R_b), gamma_tilde (γ̃),
ks_tilde (K̃_S) and bulk_mN_per_m (K_eff)) simulates the ramp at ρ_0 to d_max and a hold of
TAU_MAX T, sampled at SAMPLE_HZ, and returns q at the RAMP_DEPTHS not deeper than d_max (0
beyond) and r at the HOLD_TAUS; RAMP_DEPTHS are values of e. `from_store` (`cortex analysis build-powerlaw-table`) makes
the table's document: q from each node's deepest d_max, r from every d_max; a node whose task
failed is NaN (outside the table: `powerlaw_tabled`).
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np
import numpy.typing as npt

from analysis.calibration.powerlaw_table import FORMAT
from campaign.kinds import Kind, register
from common.errors import InputError, SolverError

RATE_PER_S = 0.15         # ρ_0 = v/R of the table's ramps (1/s)
TAU_MAX = 150.0           # the hold's length in ramp times T
SAMPLE_HZ = 1000.0        # the simulation's samples (its hold's first step 1/SAMPLE_HZ)
RAMP_DEPTHS = 0.295 * np.linspace(0.0, 1.0, 33)[1:] ** 1.4         # e of q, to the shell table's deepest d
HOLD_TAUS = np.r_[0.0, np.geomspace(1e-3, TAU_MAX, 40)]             # τ of r
TASK = "powerlaw_table"
PARAMS = {"beta": "1", "depth_over_radius": "1"}
RESULTS = tuple(f"ramp_q_d{i:02d}" for i in range(RAMP_DEPTHS.size)) + \
    tuple(f"hold_ratio_t{j:02d}" for j in range(HOLD_TAUS.size))


def node_curves(radius_um: float, gamma_tilde: float, shear_tilde: float, beta: float, depth_over_radius: float,
                bulk_eff_mN_per_m: float = 10.0) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """(q at RAMP_DEPTHS, NaN deeper than e_max; r at HOLD_TAUS) of one node (module doc)."""
    from analysis.afm.tension.powerlaw_simulated import START_UM, simulated
    from solver.droplet_table import unit_force_per_tension
    from solver.protocol import Hold
    if not (0.0 <= beta < 1.0 and 2 * START_UM / radius_um < depth_over_radius <= 0.3):
        raise InputError(f"a power-law table node needs 0 <= beta < 1 and 2 START_UM/R < depth_over_radius <= 0.3 "
                         f"(got {beta:g}, {depth_over_radius:g})")
    v = RATE_PER_S * radius_um
    depth = depth_over_radius * radius_um
    ramp_time = (depth - START_UM) / v
    rec = simulated(radius_um, gamma_tilde * bulk_eff_mN_per_m, bulk_eff_mN_per_m * RATE_PER_S ** -beta, beta,
                    shear_tilde, v, depth, (Hold(TAU_MAX * ramp_time),), 0.0, SAMPLE_HZ)
    unit = radius_um * bulk_eff_mN_per_m
    on = rec.time_s <= ramp_time + 1e-9
    d = (2.0 * radius_um - rec.height_um[on]) / radius_um
    phi = rec.force_nN[on] / unit - gamma_tilde * unit_force_per_tension(d)
    e = d - START_UM / radius_um
    reach = RAMP_DEPTHS <= e[-1] + 1e-12
    q = np.full(RAMP_DEPTHS.size, np.nan)
    q[reach] = np.interp(RAMP_DEPTHS[reach], e, phi) / RAMP_DEPTHS[reach]
    end = float(phi[-1])
    held = rec.force_nN[~on] / unit - gamma_tilde * float(unit_force_per_tension(depth_over_radius))
    tau = np.r_[0.0, (rec.time_s[~on] - ramp_time) / ramp_time]
    r = np.asarray(np.interp(HOLD_TAUS, tau, np.r_[end, held]), float) / end
    return q, r


def node_results(point: Any) -> dict[str, float]:
    """One campaign task (`campaign.params_grid.ParamPoint`): the node's q (0 deeper than its d_max)
    and r as the store's result columns RESULTS."""
    shell, values = point.shell, point.values
    radius = float(np.cbrt(3.0 * shell.volume_um3 / (4.0 * np.pi)))
    q, r = node_curves(radius, shell.tension_mN_per_m / shell.bulk_mN_per_m, shell.shear_mN_per_m / shell.bulk_mN_per_m,
                       float(values["beta"]), float(values["depth_over_radius"]), shell.bulk_mN_per_m)
    if not np.all(np.isfinite(r)):
        raise SolverError("the hold's relaxation is not finite (no elastic share at the ramp's end)")
    return dict(zip(RESULTS, map(float, np.r_[np.nan_to_num(q, nan=0.0), r])))


def table_document(radii_um: npt.ArrayLike, gammas: npt.ArrayLike, shears: npt.ArrayLike, betas: npt.ArrayLike,
                   depths: npt.ArrayLike, q: np.ndarray, r: np.ndarray) -> dict[str, Any]:
    """The table's JSON document (`analysis.calibration.powerlaw_table.PowerLawTable`): its axes, q of shape
    (radius, gamma, shear, beta, RAMP_DEPTHS) and r of shape (radius, gamma, shear, beta, d_max,
    HOLD_TAUS), NaN (null) where a node failed."""
    def plain(a: np.ndarray) -> Any:           # six significant digits (the table's error is 1e-3), null: NaN
        return np.vectorize(lambda v: float(f"{v:.6g}") if np.isfinite(v) else None, otypes=[object])(a).tolist()
    return {"format": FORMAT, "rate_per_s": RATE_PER_S, "bending": "standard", "thickness_um": 0.2,
            "radius_um": np.asarray(radii_um, float).tolist(), "gamma_tilde": np.asarray(gammas, float).tolist(),
            "shear_tilde": np.asarray(shears, float).tolist(), "beta": np.asarray(betas, float).tolist(),
            "depth_over_radius": np.asarray(depths, float).tolist(), "ramp_depths": RAMP_DEPTHS.tolist(),
            "hold_taus": HOLD_TAUS.tolist(), "ramp_q": plain(q), "hold_ratio": plain(r)}


def from_store(path: str | os.PathLike[str]) -> dict[str, Any]:
    """The table's document from a finished power-law table campaign's store: the axes from the
    campaign file it keeps, each node's curves from its row (a failed node NaN). InputError for a
    store of another campaign, or while nodes are not done."""
    import tomllib

    from campaign.store.reader import read_provenance, read_results
    text = read_provenance(path).get("config_text", "")
    doc = tomllib.loads(text) if text else {}
    grid, params = doc.get("grid", {}), doc.get("params", {})
    keys = ("volume_um3", "gamma_tilde", "ks_tilde")
    if str(doc.get("campaign", {}).get("task", "")).rpartition(":")[2] != TASK or not set(keys) <= set(grid):
        raise InputError(f"{path}: not a store of a power-law table campaign over volume_um3, gamma_tilde and "
                         f"ks_tilde ([campaign] task = \"analysis.afm.tension.powerlaw_grid:{TASK}\": "
                         "campaigns/powerlaw-table.toml)")
    volumes, gammas, shears = (np.atleast_1d(np.asarray(grid[k], float)) for k in keys)
    betas, depths = (np.atleast_1d(np.asarray(params[k], float)) for k in PARAMS)
    rows = read_results(path)
    pending = int(rows["state"].isin(["pending", "running"]).sum()) if "state" in rows else 0
    if pending or (rows["state"] != "done").sum() > (rows["state"] == "failed").sum():
        raise InputError(f"{path}: {pending} of {len(rows)} nodes not done; finish the campaign "
                         "(run it again: it resumes)")
    bulk = rows["bulk_mN_per_m"].to_numpy()
    at = (_index(volumes, rows["volume_um3"]), _index(gammas, rows["tension_mN_per_m"] / bulk),
          _index(shears, rows["shear_mN_per_m"] / bulk), _index(betas, rows["beta"], absolute=True),
          _index(depths, rows["depth_over_radius"]))
    done = (rows["state"] == "done").to_numpy()
    values = rows[list(RESULTS)].to_numpy()
    r = np.full((volumes.size, gammas.size, shears.size, betas.size, depths.size, HOLD_TAUS.size), np.nan)
    r[tuple(a[done] for a in at)] = values[done, RAMP_DEPTHS.size:]
    q = np.full((volumes.size, gammas.size, shears.size, betas.size, RAMP_DEPTHS.size), np.nan)
    deepest = done & (at[4] == depths.size - 1)
    q[tuple(a[deepest] for a in at[:4])] = values[deepest, :RAMP_DEPTHS.size]
    radii = np.cbrt(3.0 * volumes / (4.0 * np.pi))
    return table_document(radii, gammas, shears, betas, depths, q, r)


def _index(axis: np.ndarray, values: Any, absolute: bool = False) -> np.ndarray:
    """Each value's nearest node on `axis` (relative distance; `absolute`: absolute, for β, which has 0)."""
    values = np.asarray(values, float)
    gap = values[:, None] - axis[None, :]
    return np.abs(gap if absolute else gap / axis[None, :]).argmin(axis=1)


KIND = register(Kind(TASK, 3, dict.fromkeys(RESULTS, "1"), node_results, params=PARAMS,
                     doc="one node of the power-law ramp and hold table: q over the ramp, r over the hold"))
