"""Store tables generated from the calibration laws themselves, for tests and
benchmarks of the analysis (no solver needed).

`reference_law(bending)` is a made-up but plausible law (λ, cubic C and D:
K rises towards K_B as the cell flattens, faster for small ν).
`results_table` builds the rows `campaign.store.reader.read_results` returns for a
grid, with K(h̃) = K_B (1 + α(K̃_S, γ̃_a) exp(h̃/λ)) and the force consistent
with it through the droplet geometry (SPEC 3): F = (γ_a + K ε_A) 2 H A_c(h1).
`trials_table` builds the rows of `campaign.store.reader.read_trials`: cells of true
ν whose true forces are re-analysed with a volume and heights drawn around
the true ones (SPEC 5).
"""

import itertools
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import pandas as pd

from analysis.calibration.law import Law
from solver.elasticity import poisson_of_ratio, shear_ratio
from solver.geometry import droplet
from solver.modulus import effective_modulus

PAPER_GRID = {"volume_um3": [4300.0], "bulk_mN_per_m": [25.0],
              "shear_mN_per_m": [8.33, 10.0, 15.0, 20.0, 25.0],
              "h0_um": [15.0, 14.0, 13.0, 12.0, 11.0, 10.0],
              "tension_mN_per_m": [0.5, 1.0, 1.5, 2.0, 2.5, 3.0], "dh_um": [0.5]}
SCALE = {"standard": 1.0, "double": 1.15, "none": 0.85}

# The made-up law of `reference_law`, its one home (a campaign's `[test]
# fake_law` of the test suite answers with it too; a test checks the two
# forces agree): K = K_B (1 + α exp(h̃/λ)), α = C(γ̃_a) ln K̃_S + D(γ̃_a) with
# K̃_S = K_S/K_B, γ̃_a = γ_a/K_B (SPEC 4). Plausible in shape, not fitted to
# anything: α between -0.02 and -0.006 over the test grids, so K approaches
# K_B as the cell flattens; λ = 0.2 is twice the published ~0.1, so this law
# is never mistaken for a real calibration. Lowest order first.
REFERENCE_LAMBDA = 0.2
REFERENCE_C = (-0.012, 0.03, -0.2, 0.6)
REFERENCE_D = (-0.018, -0.04, 0.3, -1.0)


def reference_law(bending: str = "standard") -> Law:
    """A plausible calibration law for one bending variant (made up): the law that
    a campaign's `[test] fake_law` of the test suite answers with (REFERENCE_*),
    for `standard`; the other variants scale its λ and the constant terms of C, D."""
    s = SCALE[bending]
    C, D = list(REFERENCE_C), list(REFERENCE_D)
    C[0], D[0] = C[0] * s, D[0] * s
    return Law(bending=bending, lam=REFERENCE_LAMBDA * (1.0 + 0.05 * (s - 1.0)), C=C, D=D)


def results_table(laws: dict[str, Law], grid: dict[str, Any] = PAPER_GRID, noise: float = 0.0,
                  rng: Any = None) -> pd.DataFrame:
    """Rows of `read_results` for every grid point and variant in `laws`
    (dict bending -> Law); relative Gaussian noise of SD `noise` on K."""
    rng = np.random.default_rng(rng)
    keys = ("volume_um3", "bulk_mN_per_m", "shear_mN_per_m", "h0_um", "tension_mN_per_m", "dh_um")
    combos = list(itertools.product(laws, *(grid[k] for k in keys)))
    df = pd.DataFrame(combos, columns=("bending",) + keys)
    V, h0, dh = df["volume_um3"].to_numpy(), df["h0_um"].to_numpy(), df["dh_um"].to_numpy()
    geo = effective_modulus(V, h0, h0 - dh, df["tension_mN_per_m"].to_numpy(), 0.0)
    ks = df["shear_mN_per_m"] / df["bulk_mN_per_m"]
    gt = df["tension_mN_per_m"] / df["bulk_mN_per_m"]
    alpha = np.array([laws[b].alpha_of(k, g) for b, k, g in zip(df["bending"], ks, gt)])
    lam = np.array([laws[b].lam for b in df["bending"]])
    K = df["bulk_mN_per_m"].to_numpy() * (1.0 + alpha * np.exp(geo["h_tilde"] / lam))
    K = K * (1.0 + noise * rng.standard_normal(K.size))
    fpt = droplet(V, h0 - dh).force_per_tension_um
    dgamma = K * geo["area_strain"]
    gamma_eff = df["tension_mN_per_m"].to_numpy() + dgamma
    nu = poisson_of_ratio(ks)
    df["task_id"] = [f"c{i:05d}" for i in range(len(df))]
    df["state"] = "done"
    df["thickness_um"] = 0.2
    df["force_nN"] = gamma_eff * fpt
    df["active_force_nN"] = df["tension_mN_per_m"] * fpt
    df["gamma_eff_mN_per_m"] = gamma_eff
    df["delta_gamma_mN_per_m"] = dgamma
    df["area_strain"] = geo["area_strain"]
    df["area_strain_shell"] = geo["area_strain"] * 1.02
    df["modulus_mN_per_m"] = K
    df["h_mean_um"] = geo["h_mean_um"]
    df["h_tilde"] = geo["h_tilde"]
    df["volume_error"] = 1e-7
    df["equator_shear_ratio"] = (1.0 - geo["h_tilde"]) * (0.2 + nu)  # a made-up smooth trend
    df["converged"] = True
    df["iterations"] = 100
    df["wall_s"] = 0.05
    df["attempts"] = 1
    df["rank"] = 0
    df["error"] = ""
    return df


def trials_table(law: Law, *, nu_values: Sequence[float] = (0.5, 0.43, 0.25),
                 modes: Sequence[str] = ("per_cell", "per_height"), n_cells: int = 55, n_studies: int = 10,
                 volume_rel_sd: float = 0.075, height_sd_um: float = 0.5, volume: float = 4300.0,
                 bulk: float = 25.0, heights: Sequence[float] = (15.0, 14.0, 13.0, 12.0, 11.0, 10.0),
                 tensions: Sequence[float] = (0.5, 1.0, 1.5, 2.0, 2.5, 3.0), dh: float = 0.5,
                 seed: int = 0) -> pd.DataFrame:
    """Rows of `read_trials` (one per trial and height) for cells of the given
    true ν, γ_a drawn from `tensions`, errors drawn per cell (`per_cell`: one
    height offset for all heights) or per height (`per_height`)."""
    rng = np.random.default_rng(seed)
    heights_um = np.asarray(heights, float)
    cells = list(itertools.product(nu_values, modes, range(n_studies), range(n_cells)))
    n, m = len(cells), heights_um.size
    nu = np.array([c[0] for c in cells])
    mode = np.array([c[1] for c in cells])
    tension = rng.choice(np.asarray(tensions, float), n)
    shear = bulk * shear_ratio(nu)
    vol_used = volume * (1.0 + volume_rel_sd * rng.standard_normal(n))
    offset = np.where((mode == "per_cell")[:, None], rng.standard_normal(n)[:, None], rng.standard_normal((n, m)))
    h0_used = heights_um[None, :] + height_sd_um * offset
    h0_true = np.broadcast_to(heights_um, (n, m))
    true = effective_modulus(volume, heights_um, heights_um - dh, 0.0, 0.0)           # (m,)
    K = bulk * (1.0 + law.alpha_of(shear / bulk, tension / bulk)[:, None] * np.exp(true["h_tilde"] / law.lam))
    force = (tension[:, None] + K * true["area_strain"]) * droplet(volume, heights_um - dh).force_per_tension_um
    fa0 = tension[:, None] * droplet(volume, heights_um).force_per_tension_um     # F_a(h0), true shape
    tension_seen = fa0 / droplet(vol_used[:, None], h0_used).force_per_tension_um
    seen = effective_modulus(vol_used[:, None], h0_used, h0_used - dh, tension_seen, force)
    rep = lambda x: np.repeat(np.asarray(x), m)   # noqa: E731
    return pd.DataFrame({
        "trial_id": rep([f"t{i:06d}" for i in range(n)]), "state": "done", "nu_true": rep(nu),
        "bending": law.bending, "height_error_mode": rep(mode),
        "study": rep([c[2] for c in cells]), "cell": rep([c[3] for c in cells]),
        "bulk_mN_per_m": bulk, "shear_mN_per_m": rep(shear), "tension_mN_per_m": rep(tension),
        "volume_true_um3": volume, "volume_used_um3": rep(vol_used),
        "h0_true_um": h0_true.ravel(), "h0_used_um": h0_used.ravel(),
        "h1_used_um": (h0_used - dh).ravel(), "h_tilde": seen["h_tilde"].ravel(),
        "modulus_mN_per_m": seen["modulus_mN_per_m"].ravel(),
        "gamma_eff_mN_per_m": seen["gamma_eff_mN_per_m"].ravel(),
        "tension_seen_mN_per_m": tension_seen.ravel()})


def solver_results(variants: Sequence[str] = ("standard",), grid: dict[str, Any] = PAPER_GRID,
                   method: str = "fast", progress: Callable[[str], None] | None = None) -> pd.DataFrame:
    """Rows of `read_results` computed directly with the solver
    (`solver.compression.compress`), no campaign: for tests and checks where
    no store exists. Slow: one solve per grid point and variant."""
    from solver.compression import compress
    from common.errors import SolverError
    from solver.model import Shell
    keys = ("volume_um3", "bulk_mN_per_m", "shear_mN_per_m", "h0_um", "tension_mN_per_m", "dh_um")
    rows = []
    for i, (bending, *values) in enumerate(itertools.product(variants, *(grid[k] for k in keys))):
        params = dict(zip(keys, values))
        shell = Shell(bending=bending, **params)
        row = {"task_id": f"s{i:05d}", "state": "done", "bending": bending, **params,
               "thickness_um": shell.thickness_um}
        try:
            row.update(compress(shell, method).to_dict())
        except SolverError as err:                 # recorded like a failed campaign task
            row.update(state="failed", error=str(err), h_tilde=np.nan, modulus_mN_per_m=np.nan)
        rows.append(row)
        if progress and (i + 1) % 50 == 0:
            progress(f"{i + 1} solves")
    return pd.DataFrame(rows)
