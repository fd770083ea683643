"""95 % intervals: per cell by a parametric bootstrap through the emulator, per
frequency for the median ν by resampling cells.

Per cell (fitted θ* = (ln K_B, ln K̃_S), measured V, mean heights h_j = h̃_j 2 R_cell(V),
moduli K_j, tension γ_a, residual RMS s over n used heights), draw m = 1..M:

1. a truth this cell could have had: V_m = V (1 + σ_V ε_m), one height offset
   h_j,m = h_j + σ_h η_m (an uneven wedge), ε, η ~ N(0, 1); h̃_j,m = h_j,m / (2 R_cell(V_m));
   its tension γ_m such that the resting force is the one measured,
   γ_m = γ_a · mean_j g(V, h_j) / g(V_m, h_j,m);
2. the moduli that truth must have had to give the measured ones. What the analysis
   makes of a true cell's K (SPEC 3, h0/h1 = h ± Δh/2, g = 2 H A_c and A from the
   droplet shape, ε_A = (A(h1) - A(h0)) / A(h0)) is affine in K:
   F_j = (γ_m + K ε_A(V_m, h_j,m)) g(V_m, h1_j,m),
   γ_seen,j = γ_m g(V_m, h0_j,m) / g(V, h0_j),
   K_seen,j = (F_j / g(V, h1_j) - γ_seen,j) / ε_A(V, h_j) = c1_j,m K + c0_j,m,
   so K_j,m = (K_j + e_j,m - c0_j,m) / c1_j,m with the fit's residual noise
   e_j,m ~ N(0, s² n/(n-2));
3. refit θ_m to K_j,m at the drawn true h̃_j,m with γ = γ_m, starting from θ*:
   GN_STEPS damped Gauss-Newton steps on the 2 x 2 normal equations (vectorised over all
   cells and draws; from θ* they converge well inside the spread of the draws: 12 steps
   give the same intervals). The emulator is taken at the measured V (one slice per
   cell): at fixed h̃ it changes K by at most 0.2 % over V 3000-6000 µm³;
4. keep the draw only if the protocol admits its truth (`_in_window`): a lab sets its
   heights on the cell it touches, so at the truth's own diameter the highest recorded
   height lies in the published window, H_TILDE_TOP < max_j h̃_j,m ≤ H_TILDE_MAX (0.68,
   0.75], with at least MIN_HEIGHTS heights in use (SPEC 6's height filters read on the
   truth). Only cells whose recording passes those filters are conditioned (the others
   keep every draw); a cell with fewer than MIN_ADMITTED · M admitted draws gets another
   round of M, up to ROUNDS rounds (every draw of the first if none is admitted).

Without step 4 the draws take any offset as likely as the error model has it, but a
recording that passes the filter on its highest h̃ gives its offset partly away (a
highest h̃ just above 0.68 was recorded low), and the draws' spread overstated the
actual errors of the included cells by 1.35x (docs/population.md).
If a draw's offset and noise were the cell's own, its refit would be the truth; the
interval of ln K̃_S is the percentile one, [q_2.5, q_97.5] of the kept refits
l_m = ln K̃_S,m, and ν's is its image through ν = (1 - K̃_S)/(1 + K̃_S) (decreasing:
the ends swap). The standard error of the estimate l* = ln K̃_S* is the RMS deviation of
the same refits from it, se = sqrt(mean_m (l_m - l*)²) (`ln_ks_se` in the cells table):
the admitted truths are centred off l* where the recording gives its offset away, and
that offset is part of the estimate's error.

The droplet numbers scale with the cell: g(V, h) = R_cell ĝ(δ̂), A(V, h) = R_cell² Â(δ̂),
δ̂ = 2 (1 - h̃), with ĝ and Â from the droplet's one table (`solver.droplet_table`), so
every draw costs array arithmetic only.

Per frequency: the median ν of the included cells with a percentile bootstrap
95 % interval (`scipy.stats.bootstrap`, cells resampled; `median_table`).

What an interval includes, the measurement errors and the draws, is
`measurement_errors.MeasurementErrors`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt
import pandas as pd
from scipy.stats import bootstrap

from analysis.invert.emulator_fit import CurveArrays, filled_heights, ks_bounds
from analysis.invert.inversion import H_TILDE_MAX, pass_height_filters
from analysis.invert.measurement_errors import DRAWS, HEIGHT_SD_UM, LEVEL, VOLUME_SD
from solver.elasticity import poisson_of_ratio
from solver.droplet_table import unit_area, unit_force_per_tension
from solver.geometry import cell_radius

if TYPE_CHECKING:
    from analysis.calibration.emulator import Emulator

GN_STEPS = 4
MAX_STEP = 0.5            # largest Gauss-Newton step, in ln K_B and ln K̃_S
DH_UM = 0.5                  # peak to peak of the oscillation (2 x 0.25 um)
ROUNDS = 5                   # rounds of draws at most for a cell whose truths the protocol rarely admits
MIN_ADMITTED = 0.25          # another round while a cell has fewer admitted draws than this share of M


def _shape(radius: Any, heights: Any) -> tuple[Any, Any]:
    """(g, A) = (2 H A_c, A) for cells of radius R_cell at heights (µm), broadcast."""
    depth = np.broadcast_to(2.0 - heights / radius, np.broadcast_shapes(np.shape(radius), np.shape(heights)))
    return radius * unit_force_per_tension(depth), radius**2 * unit_area(depth)


def _seen(true: Any, measured: Any, tension_t: Any, modulus_t: Any, *, dh: float) -> tuple[Any, Any]:
    """What the analysis makes of a true cell (`true` = (radius_t, mean heights h_t),
    tension γ, modulus K) measured at `measured` = (radius_s, heights h_s):
    (K_seen, γ_seen) per height (SPEC 3, see module doc)."""
    (radius_t, h_t), (radius_s, h_s) = true, measured
    g_t0, a_t0 = _shape(radius_t, h_t + dh / 2)
    g_t1, a_t1 = _shape(radius_t, h_t - dh / 2)
    g_s0, a_s0 = _shape(radius_s, h_s + dh / 2)
    g_s1, a_s1 = _shape(radius_s, h_s - dh / 2)
    force = (tension_t + modulus_t * (a_t1 - a_t0) / a_t0) * g_t1
    seen = tension_t * g_t0 / g_s0
    return (force / g_s1 - seen) / ((a_s1 - a_s0) / a_s0), seen


def _draw_truths(rng: np.random.Generator, volume: Any, heights: Any, tension: Any, use: Any, *, draws: int,
                 volume_sd: float, height_sd_um: float) -> tuple[Any, Any, Any]:
    """Step 1: truths the cells (measured volumes (c,), mean heights (c, 1, m) in µm) could
    have had: true radii (c, M, 1), mean heights (c, M, m) and tensions (c, M)."""
    c = volume.shape[0]
    radius = cell_radius(volume)[:, None, None]
    v_true = volume[:, None] * (1.0 + volume_sd * rng.standard_normal((c, draws)))
    h_true = heights + height_sd_um * rng.standard_normal((c, draws))[:, :, None]
    r_true = cell_radius(np.clip(v_true, 1.0, None))[:, :, None]
    g_s, _ = _shape(radius, heights)
    g_t, _ = _shape(r_true, h_true)
    gamma_t = tension[:, None] * np.sum(np.where(use[:, None, :], g_s / g_t, 0), axis=2) / use.sum(axis=1)[:, None]
    return r_true, h_true, gamma_t


def _truth_moduli(k_seen: Any, true: Any, measured: Any, gamma_t: Any, *, dh: float) -> Any:
    """Step 2: the true moduli K_j,m that make the analysis see `k_seen` (rows: cell x draw),
    inverting the affine map K_seen = c1 K + c0 of `_seen` (c0 = K_seen at K = 0);
    `true` = (radii, mean heights) of the drawn truths, `measured` the same as measured."""
    c0 = _seen(true, measured, gamma_t[:, None], 0.0, dh=dh)[0]
    c1 = _seen(true, measured, gamma_t[:, None], 1.0, dh=dh)[0] - c0
    return (k_seen - c0) / c1


# The bootstrap's pieces, public for the viscoelastic intervals (`analysis.viscoelastic_fit`).
droplet_shape = _shape
truth_moduli = _truth_moduli


def _in_window(h: Any, k: Any, radius: Any, r_true: Any, h_true: Any, heights: Any) -> Any:
    """Step 4: (c, M) mask of the drawn truths the protocol admits: at the truth's own
    diameter, the recorded heights h̃_j,m = (h_j + offset_m) / (2 R_m) (`h`, `k`: all the
    cells' recorded h̃ and K, NaN-padded) pass the published height filters
    (`inversion.pass_height_filters`) with none above H_TILDE_MAX. `radius`, `heights`: the
    measured (c, 1, 1) and (c, 1, m) µm; the drawn truths as `_draw_truths` gives them."""
    c, draws = h_true.shape[:2]
    offset = (h_true - heights)[:, :, :1]                                    # one per draw
    true = np.where(np.isfinite(k)[:, None, :], (h[:, None, :] * 2.0 * radius + offset) / (2.0 * r_true), np.nan)
    passes = pass_height_filters(true.reshape(c * draws, -1), np.repeat(k, draws, axis=0)).reshape(c, draws)
    return passes & (np.max(np.nan_to_num(true, nan=-np.inf), axis=2) <= H_TILDE_MAX)   # no height above the window


def _refits(emulator: Emulator, bending: str, rng: np.random.Generator, cells: tuple[Any, ...],
            errors: tuple[float, float, float], draws: int, steps: int) -> tuple[Any, Any]:
    """Steps 1-4 for `cells` = (θ, h, K, use, γ_a, V, rms) rows (`cell_intervals`):
    the refitted l_m (c, M) and whether the protocol admits each draw's truth (c, M)."""
    th, h, k, use, tension, vs, rms = cells
    volume_sd, height_sd_um, dh_um = errors
    hs, ks, n_used, (c, m) = filled_heights(h, use), np.where(use, k, 0.0), use.sum(axis=1), h.shape
    radius = cell_radius(vs)[:, None, None]                                   # (c, 1, 1)
    heights = (hs * 2.0 * cell_radius(vs)[:, None])[:, None, :]                # (c, 1, m)
    r_true, h_true, gamma_t = _draw_truths(rng, vs, heights, tension, use, draws=draws, volume_sd=volume_sd,
                                           height_sd_um=height_sd_um)
    noise_sd = np.nan_to_num(rms) * np.sqrt(n_used / np.maximum(n_used - 2, 1))
    k_seen = ks[:, None, :] + noise_sd[:, None, None] * rng.standard_normal((c, draws, m))
    flat = lambda a: a.reshape(c * draws, *a.shape[2:])                      # noqa: E731
    measured = (flat(np.broadcast_to(radius, (c, draws, 1))), flat(np.broadcast_to(heights, (c, draws, m))))
    K_t = _truth_moduli(flat(k_seen), (flat(r_true), flat(h_true)), measured, gamma_t.ravel(), dh=dh_um)
    drawn = CurveArrays(flat(h_true / (2.0 * r_true)), K_t, np.repeat(use, draws, axis=0), gamma_t.ravel(),
                   np.repeat(vs, draws))
    x = _gauss_newton(emulator[bending], np.repeat(th, draws, axis=0), drawn, steps=steps,
                      bounds=ks_bounds(emulator, bending))
    return x[:, 1].reshape(c, draws), _in_window(h, k, radius, r_true, h_true, heights)


def cell_intervals(emulator: Emulator, bending: str, theta: npt.NDArray[np.float64], curves: CurveArrays,
                   rms: npt.NDArray[np.float64], *, draws: int = DRAWS,
                   volume_sd: float = VOLUME_SD, height_sd_um: float = HEIGHT_SD_UM, dh_um: float = DH_UM,
                   seed: int = 0, steps: int = GN_STEPS) -> tuple[Any, Any, Any, Any, Any]:
    """(ks_lo, ks_hi, nu_lo, nu_hi, ln_ks_se) arrays per cell (rows of `curves`, an
    `analysis.invert.emulator_fit.CurveArrays`, fitted θ and residual RMS `rms` (mN/m) per cell;
    NaN where θ is not finite)."""
    h, k, use, tension, volume = curves
    out = np.full((5, h.shape[0]), np.nan)
    ok = np.isfinite(theta).all(axis=1) & (use.sum(axis=1) >= 3)
    if not ok.any():
        return tuple(out)
    rng = np.random.default_rng(seed)
    cells = (theta[ok], h[ok], k[ok], use[ok], tension[ok], volume[ok], rms[ok])
    errors = (volume_sd, height_sd_um, dh_um)
    lks, admitted = _refits(emulator, bending, rng, cells, errors, draws, steps)
    conditioned = pass_height_filters(h[ok], k[ok])
    kept = [np.where(admitted | ~conditioned[:, None], lks, np.nan)]
    for _ in range(ROUNDS - 1):
        more = conditioned & (np.sum([np.isfinite(a).sum(axis=1) for a in kept], axis=0) < MIN_ADMITTED * draws)
        if not more.any():
            break
        l_more, a_more = _refits(emulator, bending, rng, tuple(a[more] for a in cells), errors, draws, steps)
        kept.append(np.full_like(lks, np.nan))
        kept[-1][more] = np.where(a_more, l_more, np.nan)
    kept_all = np.concatenate(kept, axis=1)
    none = ~np.isfinite(kept_all).any(axis=1)                                 # no truth admitted: every draw
    kept_all[none, :draws] = lks[none]
    lo, hi = np.nanpercentile(kept_all, [100 * (1 - LEVEL) / 2, 100 * (1 + LEVEL) / 2], axis=1)
    out[0, ok], out[1, ok] = np.exp(lo), np.exp(hi)
    out[2, ok], out[3, ok] = poisson_of_ratio(np.exp(hi)), poisson_of_ratio(np.exp(lo))
    out[4, ok] = np.sqrt(np.nanmean((kept_all - theta[ok, 1:2]) ** 2, axis=1))
    return tuple(out)


def _gauss_newton(table: Any, x: Any, curves: CurveArrays, *, steps: int, bounds: Any) -> Any:
    """Refit θ = (ln K_B, ln K̃_S) of every row of `curves` from its start `x`: damped Gauss-Newton
    steps on the 2 x 2 normal equations, each step at most MAX_STEP in ln units and
    ln K̃_S kept within the fit's bounds; rows of one volume share a `VolumeSlice`."""
    h, k, use, tension, volume = curves
    x = x.copy()
    for v in np.unique(volume):
        rows = volume == v
        sl = table.at_volume(v)
        xr, hr, kr, ur, tr = x[rows], h[rows], k[rows], use[rows], tension[rows]
        for _ in range(steps):
            bulk = np.exp(xr[:, 0])[:, None]
            lr, d_ks, d_g = sl.grad_log(hr, np.exp(xr[:, 1])[:, None], tr[:, None] / bulk, where=ur)
            K = bulk * np.exp(lr)
            r = np.nan_to_num(np.where(ur, kr - K, 0.0))
            J = np.stack([np.where(ur, K * (1.0 - d_g), 0.0), np.where(ur, K * d_ks, 0.0)], axis=-1)
            JtJ = np.einsum("nji,njk->nik", J, J) + 1e-9 * np.eye(2)
            step = np.linalg.solve(JtJ, np.einsum("nji,nj->ni", J, r)[..., None])[..., 0]
            xr = xr + np.clip(np.nan_to_num(step), -MAX_STEP, MAX_STEP)
            xr[:, 1] = np.clip(xr[:, 1], *bounds)
        x[rows] = xr
    return x


def median_interval(values: npt.ArrayLike, resamples: int = 2000, seed: int = 0) -> tuple[float, float, float]:
    """(median, lo, hi): the median of ν (`values`, finite ones) and its percentile
    bootstrap 95 % interval; NaN ends with fewer than 2 values."""
    nu = np.asarray(values, float)
    nu = nu[np.isfinite(nu)]
    if nu.size == 0:
        return float("nan"), float("nan"), float("nan")
    if nu.size < 2:
        return float(nu[0]), float("nan"), float("nan")
    res = bootstrap((nu,), np.median, confidence_level=LEVEL, n_resamples=resamples, method="percentile",
                    random_state=np.random.default_rng(seed), vectorized=True)
    return float(np.median(nu)), float(res.confidence_interval.low), float(res.confidence_interval.high)


def median_table(table: pd.DataFrame) -> list[dict[str, Any]]:
    """Per frequency: included cells, median ν and its bootstrap 95 % interval."""
    rows = []
    ok = table[table["excluded_reason"].isna()]
    for f, g in table.groupby(table["frequency_hz"].fillna(-1.0), sort=True):
        nu = ok.loc[ok.index.isin(g.index), "nu"].to_numpy(float)
        med, lo, hi = median_interval(nu)
        rows.append({"frequency_hz": float(f) if f >= 0 else None, "n_cells": int(nu.size),
                     "n_excluded": int(len(g) - nu.size), "median_nu": med, "median_nu_lo95": lo,
                     "median_nu_hi95": hi})
    return rows
