"""Oscillation segments -> moduli (SPEC 6, steps 1-3).

For samples (t, h(t), F(t)) of one cell of volume V:

1. γ_eff(t) = F(t) / (2 H(h(t)) A_c(h(t))),  A(t) = A(h(t))  (droplet shape at V,
   `droplet(V, h)` on a height grid per cell, cubic splines to every sample).
2. Per segment at frequency f, linear least squares of
   x(t) = a cos(2πft) + b sin(2πft) + c t + d  to γ_eff and to A
   (t measured from the segment's start). Amplitude x̂ = sqrt(a² + b²), phase
   φ = atan2(a, b) (x ≈ x̂ sin(2πft + φ) + ...).
3. ε̂_A = Â / <A>, |K| = γ̂_eff / ε̂_A at h̃ = <h> / (2 R_cell); loss angle
   δ = φ_γ - φ_A (wrapped to (-π, π]); A grows when h falls, so the in-phase
   response has δ ≈ 0 relative to the area, not to the height. The segment's
   mean tension is <γ_eff> (the fit's mean over the segment, c·t̄ + d).
"""

from typing import Any

import numpy as np
import numpy.typing as npt
from scipy.interpolate import CubicSpline

from analysis.afm.cell import Cell
from solver.geometry import cell_radius, droplet

TABLE_POINTS = 96   # heights per cell at which the droplet is solved; cubic spline between


def shape_of(volume: float, heights: npt.NDArray[np.float64]) -> tuple[np.ndarray, np.ndarray]:
    """(2 H A_c, A) at `heights` for one volume: the droplet solved on a grid of
    TABLE_POINTS heights over their range and interpolated by cubic splines
    (the exact solve per sample is far too slow for 10⁶ samples)."""
    lo, hi = float(np.min(heights)), float(np.max(heights))
    if hi - lo < 1e-9:
        d = droplet(volume, np.full_like(heights, lo))
        return d.force_per_tension_um, d.surface_area_um2
    grid = np.linspace(lo, hi, TABLE_POINTS)
    d = droplet(volume, grid)
    return (CubicSpline(grid, d.force_per_tension_um)(heights),
            CubicSpline(grid, d.surface_area_um2)(heights))


def fit_sinusoid(t: npt.NDArray[np.float64], x: npt.ArrayLike, f: float) -> dict[str, np.ndarray]:
    """Least squares of x = a cos(ωt) + b sin(ωt) + c t + d; rows of `x` are
    fitted at once. Returns amplitude, phase φ = atan2(a, b), mean over t, R²."""
    w = 2.0 * np.pi * f
    M = np.column_stack([np.cos(w * t), np.sin(w * t), t, np.ones_like(t)])
    coef, *_ = np.linalg.lstsq(M, np.atleast_2d(x).T, rcond=None)
    a, b, c, d = coef
    fit = (M @ coef).T
    xs = np.atleast_2d(x)
    ss_res = ((xs - fit) ** 2).sum(axis=1)
    ss_tot = ((xs - xs.mean(axis=1, keepdims=True)) ** 2).sum(axis=1)
    return {"amplitude": np.hypot(a, b), "phase": np.arctan2(a, b), "mean": c * t.mean() + d,
            "r2": 1.0 - ss_res / np.where(ss_tot > 0, ss_tot, np.nan)}


def segment_moduli(cell: Cell) -> list[dict[str, Any]]:
    """One row per oscillation segment of `cell`: frequency_hz, mean_height_um,
    h_tilde, modulus_mN_per_m (|K|), loss_angle_rad, tension_mN_per_m (<γ_eff>),
    area_strain_amplitude, gamma_amplitude_mN_per_m, fit_r2_gamma, t_mid_s."""
    osc = cell.oscillations()
    idx = np.concatenate([np.arange(s.start, s.stop) for s in osc])
    fpt, area = shape_of(cell.volume_um3, cell.height_um[idx])
    gamma = cell.force_nN[idx] / fpt                               # nN/µm = mN/m
    two_r = 2.0 * float(cell_radius(cell.volume_um3))
    rows, pos = [], 0
    for s in osc:
        n = s.stop - s.start
        sl = slice(pos, pos + n)
        pos += n
        t = cell.time_s[s.start:s.stop] - cell.time_s[s.start]
        fit = fit_sinusoid(t, np.vstack([gamma[sl], area[sl]]), s.frequency_hz)
        g_amp, a_amp = fit["amplitude"]
        strain = a_amp / fit["mean"][1]
        h_mean = float(cell.height_um[s.start:s.stop].mean())
        delta = np.angle(np.exp(1j * (fit["phase"][0] - fit["phase"][1])))
        rows.append({"frequency_hz": s.frequency_hz, "mean_height_um": h_mean, "h_tilde": h_mean / two_r,
                     "modulus_mN_per_m": g_amp / strain, "loss_angle_rad": float(delta),
                     "tension_mN_per_m": float(fit["mean"][0]), "area_strain_amplitude": float(strain),
                     "gamma_amplitude_mN_per_m": float(g_amp), "fit_r2_gamma": float(fit["r2"][0]),
                     "t_mid_s": float(cell.time_s[(s.start + s.stop - 1) // 2])})
    return rows
