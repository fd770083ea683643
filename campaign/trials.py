"""Monte-Carlo error trials (SPEC section 5): the K(h̃) curve an experimenter
would have seen of a simulated cell whose volume and heights were measured
with errors.

A model cell is one grid point except h0: (V, Δh, K_B, K_S, γ_a, bending) at
every height h0_j of the grid, with the simulated plate forces F_j at
h1_j = h0_j - Δh (the campaign's compressions). Its true Poisson ratio is
ν = (K_B - K_S)/(K_B + K_S) (`solver.elasticity`); a configured ν uses the grid's K_S closest to
K_B (1 - ν)/(1 + ν) (`grid_shear`).

One trial task is one *study*: N cells of one (bending, ν, height-error
mode), repetition s. Cell c has its own id (`trial_ids`: a hash of the
study's parameters, the seed and c) and its own generator
`default_rng(SeedSequence(int(trial_id, 16)))`, from which it draws, in
this order:

    i       index of its γ_a among the configured tensions (uniform),
    ε_V     ~ N(0, 1):  Ṽ = V (1 + σ_V ε_V),
    ε_h     ~ N(0, 1), one per cell (`per_cell`: one offset at every height,
            an uneven wedge) or one per height (`per_height`):
            ĥ0_j = h0_j + σ_h ε_h(j),  ĥ1_j = ĥ0_j - Δh (the piezo's Δh is exact).

The experimenter's numbers (SPEC 3 with Ṽ, ĥ0, ĥ1 instead of V, h0, h1;
g(V, h) = 2 H A_c, the force per tension of the droplet shape):

    γ_seen_j = γ_a g(V, h0_j) / g(Ṽ, ĥ0_j)    the resting force F_a(h0_j) read as a tension,
    γ_eff_j  = F_j / g(Ṽ, ĥ1_j),
    ε_A,j    = (A(Ṽ, ĥ1_j) - A(Ṽ, ĥ0_j)) / A(Ṽ, ĥ0_j),
    K_j      = (γ_eff_j - γ_seen_j) / ε_A,j    at  h̃_j = (ĥ0_j + ĥ1_j) / 2 / (2 R_cell(Ṽ)).

With σ_V = σ_h = 0 these are the compressions' own K and h̃, bit for bit.
A draw that makes a height impossible (Ṽ ≤ 0, ĥ1 ≤ 0, ĥ0 above the free
sphere of Ṽ) gives NaN at that height; the inversion skips it. A cell whose
γ_a has a failed compression is failed, with that compression's message.
Each study is computed as one (N, heights) array, so its numbers depend on
nothing but its parameters: not on ranks, batches or order.

The trials are a task kind of the engine's own (`TRIAL_KIND`, `campaign.kinds`): their results per
cell and height with units, and a version that the trials' fingerprint holds
(`campaign.config.Campaign.trials_fingerprint`). `run_study` computes one; the scheduler hands it
the compressions' forces (`campaign.trial_inputs`).
"""

import hashlib
import json
from dataclasses import dataclass, fields
from functools import cached_property

import numpy as np

from campaign.cell_streams import streams
from campaign.kinds import Kind, register
from solver.elasticity import poisson_ratio
from solver.geometry import droplet, sphere_height

MODES = ("per_cell", "per_height")
TRIAL_KIND = register(Kind("trial", 1, {
    "tension_mN_per_m": "mN/m", "volume_used_um3": "µm³",                       # per cell
    "h0_used_um": "µm", "h1_used_um": "µm", "force_nN": "nN", "h_tilde": "1", "modulus_mN_per_m": "mN/m",
    "gamma_eff_mN_per_m": "mN/m", "tension_seen_mN_per_m": "mN/m"},             # per cell and height
    doc="one Monte-Carlo study: N model cells' K(h̃) curves as an experimenter reads them (SPEC 5)"))
NU_TOLERANCE = 0.01     # |ν of the grid's K_S - ν asked| allowed


def grid_shear(nu, bulk, shears):
    """The grid's K_S whose ν is closest to `nu`, and that ν; None if none is
    within NU_TOLERANCE."""
    best = min(shears, key=lambda s: abs(poisson_ratio(bulk, s) - nu))
    nu_best = poisson_ratio(bulk, best)
    return (best, nu_best) if abs(nu_best - nu) <= NU_TOLERANCE else None


@dataclass(frozen=True)
class Study:
    """One trial task: N cells of one (bending, ν, height-error mode), repetition `study`.

    `rows[i][j]`: the campaign's compression row of tensions[i] at heights[j]."""

    bending: str
    nu_true: float
    height_error_mode: str
    study: int
    n_cells: int
    volume_um3: float
    dh_um: float
    bulk_mN_per_m: float
    shear_mN_per_m: float
    heights_um: tuple
    tensions_mN_per_m: tuple
    volume_error_rel_sd: float
    height_error_sd_um: float
    seed: int
    rows: tuple

    @cached_property
    def _key(self):
        """The study's parameters and seed (not `rows`) as canonical JSON."""
        params = {f.name: getattr(self, f.name) for f in fields(self) if f.name != "rows"}
        return json.dumps(params, sort_keys=True)

    @property
    def task_id(self):
        """The study's id: a hash of its parameters and seed."""
        return hashlib.sha256(self._key.encode()).hexdigest()[:16]

    def trial_ids(self):
        """One id per cell: a hash of the study's parameters, the seed and the cell."""
        base = hashlib.sha256(f"{self._key}|cell=".encode())
        return [_extended(base, str(c)) for c in range(self.n_cells)]

    def dependencies(self):
        """Every compression row the study uses."""
        return sorted({r for line in self.rows for r in line})


def _extended(base, tail):
    """sha256(key + tail)[:16] from the hash of key (the same digest, hashed once)."""
    h = base.copy()
    h.update(tail.encode())
    return h.hexdigest()[:16]


def draws(study):
    """(γ_a index (N,), ε_V (N,), ε_h (N, heights)) from each cell's own
    generator (`campaign.cell_streams`: numpy's, without building one per cell)."""
    m, n_tensions = len(study.heights_um), len(study.tensions_mN_per_m)
    per_cell = study.height_error_mode == "per_cell"
    index, eps_v, eps_h = [], [], []
    for rng in streams([int(tid, 16) for tid in study.trial_ids()]):
        index.append(int(rng.integers(n_tensions)))
        eps_v.append(rng.standard_normal())
        eps_h.append(rng.standard_normal(1 if per_cell else m))
    eps = np.array(eps_h).reshape(len(index), -1)
    return np.array(index), np.array(eps_v), np.broadcast_to(eps, (len(index), m)).copy()


def run_study(study, forces, errors):
    """The curves of a study's N cells.

    forces: (tensions, heights) simulated F_tot (nN), NaN where not done;
    errors: per tension, the message of a failed compression ('' if none).
    Returns a dict of arrays: per cell `state`, `error`, `tension_mN_per_m`,
    `volume_used_um3`; per cell and height `h0_used_um`, `h1_used_um`,
    `h_tilde`, `modulus_mN_per_m`, `gamma_eff_mN_per_m`,
    `tension_seen_mN_per_m`, `force_nN`."""
    index, eps_v, eps_h = draws(study)
    n = len(index)
    V = study.volume_um3
    h0 = np.asarray(study.heights_um, float)[None, :]
    tension = np.asarray(study.tensions_mN_per_m, float)[index]
    force = np.asarray(forces, float)[index]                      # (N, heights)
    v_used = V * (1.0 + study.volume_error_rel_sd * eps_v)
    h0_used = h0 + study.height_error_sd_um * eps_h
    h1_used = h0_used - study.dh_um
    vol = np.broadcast_to(v_used[:, None], h0_used.shape)
    ok = (vol > 0) & (h1_used > 0) & (h0_used < sphere_height(np.where(vol > 0, vol, V)))
    vol_s, h0_s = np.where(ok, vol, V), np.where(ok, h0_used, h0)   # stand-ins where impossible
    seen, em = _seen(vol_s, h0_s, h0_s - study.dh_um, tension[:, None], _resting_g(V, study.heights_um),
                     np.where(ok, force, 0.0))
    nan = lambda x: np.where(ok, x, np.nan)  # noqa: E731
    failed = np.array([bool(errors[i]) for i in index], bool)
    out = {"state": np.where(failed, "failed", "done"),
           "error": np.array([errors[i] for i in index], object),
           "tension_mN_per_m": tension, "volume_used_um3": v_used,
           "h0_used_um": h0_used, "h1_used_um": h1_used, "force_nN": force,
           "h_tilde": nan(em["h_tilde"]), "modulus_mN_per_m": nan(em["modulus_mN_per_m"]),
           "gamma_eff_mN_per_m": nan(em["gamma_eff_mN_per_m"]), "tension_seen_mN_per_m": nan(seen)}
    for key in ("h_tilde", "modulus_mN_per_m", "gamma_eff_mN_per_m", "tension_seen_mN_per_m"):
        out[key][failed] = np.nan
    assert out["h_tilde"].shape == (n, len(study.heights_um))
    return out


def _resting_g(volume, heights):
    """g(V, h0_j) of the true cell at every height (1, heights), from the
    per-process kept shapes (`droplet` of scalars): the same numbers as one
    array solve, without solving them again for every study."""
    return np.array([[droplet(volume, h).force_per_tension_um for h in heights]])


def _seen(volume, h0, h1, tension, g_true, force):
    """γ_seen = γ_a (g(V, h0) / g(Ṽ, ĥ0)) and what
    `solver.modulus.effective_modulus(Ṽ, ĥ0, ĥ1, γ_seen, F)` returns, from two
    droplet solves instead of three (the one at ĥ0 gives both g and A(ĥ0)):
    the same operations in the same order, so the same bits (tested)."""
    d0, d1 = droplet(volume, h0), droplet(volume, h1)
    seen = tension * (g_true / d0.force_per_tension_um)
    gamma_eff = force / d1.force_per_tension_um
    strain = (d1.surface_area_um2 - d0.surface_area_um2) / d0.surface_area_um2
    with np.errstate(divide="ignore", invalid="ignore"):
        modulus = (gamma_eff - seen) / strain
    h_tilde = 0.5 * (h0 + h1) / (2.0 * d0.cell_radius_um)
    return seen, {"gamma_eff_mN_per_m": gamma_eff, "modulus_mN_per_m": modulus, "h_tilde": h_tilde}
