"""Per cell and frequency: K_B, δ_B, K_S, δ_S from the complex K*(h̃) (SPEC 10).

Model of one curve (a cell at one frequency) at its used heights j:

    ln K*_j = ln K_B + ln f(h̃_j, K̃_S, γ_a/K_B; V) + ln C(h̃_j, K̃_S, γ_a/K_B, δ_B, δ_S)

(f: the emulator, `analysis.calibration.emulator`; C: the correspondence factor,
`analysis.calibration.viscoelastic_table`; K_B, K_S the magnitudes |K_B*|, |K_S*|). The
measured K*_j = |K_j| e^{iδ_j} (δ_j the segment's loss angle after the instrument's
lag is removed). Unknowns θ = (ln K_B, ln K̃_S, δ_B, δ_S); residuals the real and
imaginary parts of ln K*_j(measured) - ln K*_j(θ), i.e. relative amplitude and phase,
equally weighted; damped Gauss-Newton on the 4 × 4 normal equations, vectorised
over curves, from the magnitude-only fit's (ln K_B, ln K̃_S) and δ_B = δ_S = the
median measured phase. Then ν* = (K_B* - K_S*)/(K_B* + K_S*) (complex).

Intervals (95 %): the parametric bootstrap of `analysis.invert.intervals` carried to complex
moduli. Per draw m a truth the cell could have had (volume V(1 + σ_V ε_m), one height
offset σ_h η_m, the tension that keeps the resting force), the true K*_j,m that
would make the analysis see the measured K*_j times e^{e_j,m} (e complex, each part
N(0, s²), s² = SS/(2n - 4) the fit's residual variance; the map from a true K to the
seen one is affine with real coefficients, `analysis.invert.intervals.truth_moduli`), and
the refit θ_m. The draws (ε_m, η_m) are given per curve by the caller, so that a cell's
frequencies share them (`analysis.afm.rheology` fits power laws across frequencies
draw by draw). Intervals are percentiles of θ_m.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from analysis.invert import intervals
from analysis.invert.emulator_fit import CurveArrays, filled_heights, ks_bounds
from solver.geometry import cell_radius

if TYPE_CHECKING:
    from analysis.calibration.emulator import Emulator
    from analysis.calibration.viscoelastic_table import ComplexTable

STEPS = 8             # Gauss-Newton steps of the fit
DRAW_STEPS = 4        # ... of each bootstrap refit, from θ*
MAX_STEP = np.array([0.5, 0.5, 0.2, 0.2])
ANGLE_BOUNDS = (-0.3, 1.3)      # rad: δ kept within (the table is fitted over 0-1 rad)


def _model(table: Any, slice_: Any, theta: Any, h: Any, tension: Any, volume_um3: Any, use: Any,
           jacobian: bool = True) -> tuple[Any, Any]:
    """ln K* (rows, m) complex and (with `jacobian`) its Jacobian (rows, m, 4) by θ (tables at
    one volume), at the heights `use` selects (NaN at the others)."""
    bulk = np.exp(theta[:, 0])[:, None]
    ks = np.exp(theta[:, 1])[:, None]
    g = tension[:, None] / bulk
    if not jacobian:
        lr = slice_.grad_log(h, ks, g, values_only=True, where=use)
        return theta[:, :1] + lr + table.log_factor(h, ks, g, theta[:, 2:3], theta[:, 3:4], volume_um3,
                                                   where=use), None
    lr, f_ks, f_g = slice_.grad_log(h, ks, g, where=use)
    lc, c_ks, c_g, c_b, c_s = table.log_factor(h, ks, g, theta[:, 2:3], theta[:, 3:4], volume_um3,
                                                  derivatives=True, where=use)
    value = theta[:, :1] + lr + lc
    jac = np.stack([1.0 - f_g - c_g, f_ks + c_ks, c_b, c_s], axis=-1)
    return value, jac


def gauss_newton(table: ComplexTable, emulator: Emulator, bending: str, theta: npt.NDArray[np.float64], curves: CurveArrays,
                 lnk: npt.NDArray[np.complex128], steps: int = STEPS) -> tuple[Any, Any]:
    """Refit θ per row of `curves` (an `analysis.invert.emulator_fit.CurveArrays`, K unused) to the measured
    ln K* `lnk` (rows, m), starting from `theta` (rows, 4); rows of one volume share an
    emulator slice. Returns θ (rows, 4) and the residual sum of squares (rows,)."""
    h, _, use, tension, volume = curves
    x, ss = theta.copy(), np.full(len(theta), np.nan)
    lo, hi = ks_bounds(emulator, bending)
    for v in np.unique(volume):
        rows = volume == v
        sl, tsl = emulator[bending].at_volume(v), table.at_volume(v)
        xr, hr, ur, tr, kr = x[rows], filled_heights(h[rows], use[rows]), use[rows], tension[rows], lnk[rows]
        for it in range(steps + 1):
            value, jac = _model(tsl, sl, xr, hr, tr, v, ur, jacobian=it < steps)
            r = np.where(ur, np.nan_to_num(kr - value), 0.0)
            if it == steps:
                break
            J = np.where(ur[..., None], jac, 0.0)
            A = np.einsum("nji,njk->nik", J.conj(), J).real + 1e-9 * np.eye(4)
            b = np.einsum("nji,nj->ni", J.conj(), r).real
            step = np.linalg.solve(A, b[..., None])[..., 0]
            xr = xr + np.clip(np.nan_to_num(step), -MAX_STEP, MAX_STEP)
            xr[:, 1] = np.clip(xr[:, 1], lo, hi)
            xr[:, 2:] = np.clip(xr[:, 2:], *ANGLE_BOUNDS)
        x[rows], ss[rows] = xr, np.sum(np.abs(r) ** 2, axis=1)
    return x, ss


def fit(table: ComplexTable, emulator: Emulator, bending: str, curves: CurveArrays, lnk: npt.NDArray[np.complex128],
        start: npt.NDArray[np.float64]) -> tuple[Any, Any]:
    """θ* per curve from `start` (rows, 2: the magnitude-only (ln K_B, ln K̃_S)); NaN where
    `start` is not finite. Returns θ* (rows, 4) and the residual variance s² per component."""
    ok = np.isfinite(start).all(axis=1) & (curves.use.sum(axis=1) >= 3)
    theta = np.full((len(start), 4), np.nan)
    s2 = np.full(len(start), np.nan)
    if not ok.any():
        return theta, s2
    phase = np.nanmedian(np.where(curves.use, lnk.imag, np.nan)[ok], axis=1)
    x0 = np.column_stack([start[ok], phase, phase])
    sub = CurveArrays(*(a[ok] for a in curves))
    theta[ok], ss = gauss_newton(table, emulator, bending, x0, sub, lnk[ok])
    n = sub.use.sum(axis=1)
    s2[ok] = ss / np.maximum(2 * n - 4, 1)
    return theta, s2


def draws(table: ComplexTable, emulator: Emulator, bending: str, theta: npt.NDArray[np.float64],
          s2: npt.NDArray[np.float64],
          curves: CurveArrays, lnk: npt.NDArray[np.complex128], normals: npt.NDArray[np.float64], *,
          volume_sd: float = intervals.VOLUME_SD, height_sd_um: float = intervals.HEIGHT_SD_UM,
          dh_um: float = intervals.DH_UM, seed: int = 0) -> npt.NDArray[np.float64]:
    """θ_m (rows, M, 4) of the bootstrap; `normals` (rows, M, 2): each row's (ε_m, η_m)."""
    h, _, use, tension, volume = curves
    rows, M = normals.shape[:2]
    out = np.full((rows, M, 4), np.nan)
    ok = np.isfinite(theta).all(axis=1)
    if not ok.any():
        return out
    rng = np.random.default_rng(seed)
    th, us, vs, nrm = theta[ok], use[ok], volume[ok], normals[ok]
    hs = filled_heights(h[ok], us)
    c, m = hs.shape
    radius = cell_radius(vs)[:, None, None]
    heights = (hs * 2.0 * cell_radius(vs)[:, None])[:, None, :]
    v_true = vs[:, None] * (1.0 + volume_sd * nrm[..., 0])
    h_true = heights + height_sd_um * nrm[..., 1][:, :, None]
    r_true = cell_radius(np.clip(v_true, 1.0, None))[:, :, None]
    g_s, _ = intervals.droplet_shape(radius, heights)
    g_t, _ = intervals.droplet_shape(r_true, h_true)
    gamma_t = tension[ok][:, None] * np.sum(np.where(us[:, None, :], g_s / g_t, 0), axis=2) / us.sum(axis=1)[:, None]
    sd = np.sqrt(np.nan_to_num(s2[ok]))[:, None, None]
    noise = sd * (rng.standard_normal((c, M, m)) + 1j * rng.standard_normal((c, M, m)))
    k_seen = np.exp(np.where(us, lnk[ok], 0.0)[:, None, :] + noise)
    flat = lambda a: a.reshape(c * M, *a.shape[2:])                      # noqa: E731
    measured = (flat(np.broadcast_to(radius, (c, M, 1))), flat(np.broadcast_to(heights, (c, M, m))))
    K_t = intervals.truth_moduli(flat(k_seen), (flat(r_true), flat(h_true)), measured, gamma_t.ravel(), dh=dh_um)
    drawn = CurveArrays(flat(h_true / (2.0 * r_true)), None, np.repeat(us, M, axis=0), gamma_t.ravel(),
                   np.repeat(vs, M))
    with np.errstate(invalid="ignore", divide="ignore"):
        lnk_t = np.log(K_t.astype(complex))
    x, _ = gauss_newton(table, emulator, bending, np.repeat(th, M, axis=0), drawn, lnk_t, steps=DRAW_STEPS)
    out[ok] = x.reshape(c, M, 4)
    return out


def complex_poisson(theta: npt.NDArray[np.float64]) -> Any:
    """ν* = (K_B* - K_S*)/(K_B* + K_S*) per row of θ = (ln K_B, ln K̃_S, δ_B, δ_S)."""
    kb = np.exp(1j * theta[:, 2])
    ks = np.exp(theta[:, 1] + 1j * theta[:, 3])
    return (kb - ks) / (kb + ks)
