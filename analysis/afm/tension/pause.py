"""Cortical tension and pressure of a cell held at one height (SPEC 11, SPEC 1).

A tension-only cell of volume V held between the plates at gap h pushes on each
with F = 2 γ_a H A_c, so

    γ_a = F / (2 H A_c),      ΔP = 2 γ_a H,

H and A_c of the droplet shape at (V, h) (`solver.droplet_table`). Units: γ in
mN/m, H in 1/µm, so 2 γ H is in mN/m/µm = 10³ Pa: ΔP (Pa) = 2000 γ H.

95 % intervals: the percentile interval of DRAWS draws of the truth the cell
could have had, as for the oscillation analysis (`analysis.invert.intervals`): a
volume V_m = V (1 + σ_V ε_m) (σ_V = 7.5 %) and a height h_m = h + σ_h η_m
(σ_h = 0.5 µm, an uneven wedge or dish reference) and a force F_m = F + σ_F ζ_m
(σ_F the SD of the relaxed force, `relaxation`; 0 for a force taken as
known), ε, η, ζ ~ N(0, 1), giving γ_m = F_m / (2 H A_c)(V_m, h_m) and
ΔP_m = 2 γ_m H(V_m, h_m). Where the height
comes from the approach's contact point instead of a dish reference
(h = 2R - δ with δ the compression since contact), the height error is the
radius's: h_m = 2 R_m - δ. A draw whose gap reaches the free sphere (no
contact) has γ_m = ∞; an interval may then be open (∞) above. Draws flatter
than h̃ = 0.05 (no cell is) are left out.

For a ramp the tension's interval from the volume error is [T(V_-), T(V_+)]
(sorted), the ramp refitted at V_± = V (1 ± 1.96 σ_V) on the same window
(`ramp_interval`): the ends of a 95 % interval where T is monotonic in V.
"""

from dataclasses import dataclass
from statistics import NormalDist

import numpy as np
import numpy.typing as npt

from analysis.afm.tension.ramp import RampFit, refit
from analysis.invert.measurement_errors import LEVEL, MeasurementErrors
from solver.droplet_table import force_per_tension_um, mean_curvature_per_um
from common.errors import InputError
from solver.geometry import cell_radius

DRAWS = 2000
FLATTEST = 0.05           # draws flatter than this h̃ (beyond any cell) are left out
Z95 = NormalDist().inv_cdf((1.0 + LEVEL) / 2.0)   # the normal quantile of the intervals' level
PA_PER_MN_PER_M_PER_UM = 1e3


def pressure_Pa(tension_mN_per_m: npt.ArrayLike, mean_curvature_per_um: npt.ArrayLike) -> np.ndarray:
    """ΔP = 2 γ H in Pa (γ in mN/m, H in 1/µm)."""
    return 2.0 * PA_PER_MN_PER_M_PER_UM * np.asarray(tension_mN_per_m) * np.asarray(mean_curvature_per_um)


TENSION_ERRORS = MeasurementErrors(draws=DRAWS)     # the published errors, DRAWS draws


@dataclass(frozen=True)
class PauseTension:
    """γ_a (mN/m), ΔP (Pa) with their 95 % intervals, at force F (nN) and height h (µm)."""

    tension_mN_per_m: float
    tension_lo95_mN_per_m: float
    tension_hi95_mN_per_m: float
    pressure_Pa: float
    pressure_lo95_Pa: float
    pressure_hi95_Pa: float
    force_nN: float
    height_um: float
    h_tilde: float


def _tension_pressure(force: npt.ArrayLike, volume: npt.ArrayLike,
                      height: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    g = force_per_tension_um(volume, height)
    with np.errstate(divide="ignore"):
        gamma = np.where(g > 0, force / np.where(g > 0, g, 1.0), np.inf)
    return gamma, pressure_Pa(gamma, mean_curvature_per_um(volume, height))


def pause_tension(force_nN: float, height_um: float, volume_um3: float, *, depth_um: float | None = None,
                  errors: MeasurementErrors = TENSION_ERRORS, force_sd_nN: float = 0.0) -> PauseTension:
    """γ_a and ΔP of a cell of volume V held at gap h by force F (above the
    baseline), F known to SD `force_sd_nN`; `depth_um` δ where h = 2R - δ comes
    from the contact point. InputError for F ≤ 0 or a gap at or above the free
    cell's diameter."""
    radius = float(cell_radius(volume_um3))
    if not force_nN > 0:
        raise InputError(f"pause without force: {force_nN:.3g} nN above the baseline")
    if not height_um < 2.0 * radius:
        raise InputError(f"pause at height {height_um:.4g} um, not below the free cell's diameter "
                         f"{2 * radius:.4g} um (volume {volume_um3:.4g} um^3): no contact")
    gamma, dp = _tension_pressure(force_nN, volume_um3, height_um)
    rng = np.random.default_rng(errors.seed)
    v = volume_um3 * np.clip(1.0 + errors.volume_rel_sd * rng.standard_normal(errors.draws), 1e-3, None)
    eta = rng.standard_normal(errors.draws)
    h = (2.0 * cell_radius(v) - depth_um) if depth_um is not None else height_um + errors.height_sd_um * eta
    flat = h < FLATTEST * 2.0 * cell_radius(v)
    f = force_nN + force_sd_nN * rng.standard_normal(errors.draws)
    g_m, p_m = _tension_pressure(f, v, np.where(flat, 2.0 * cell_radius(v), h))
    g_m[flat], p_m[flat] = np.nan, np.nan
    q = [100 * (1 - LEVEL) / 2, 100 * (1 + LEVEL) / 2]
    (t_lo, t_hi), (p_lo, p_hi) = (np.nanpercentile(a, q, method="nearest") for a in (g_m, p_m))
    return PauseTension(float(gamma), float(t_lo), float(t_hi), float(dp), float(p_lo), float(p_hi),
                        float(force_nN), float(height_um), height_um / (2.0 * radius))


def ramp_interval(fit: RampFit, x_um: npt.ArrayLike, force_nN: npt.ArrayLike, volume_um3: float,
                  errors: MeasurementErrors = TENSION_ERRORS) -> tuple[float, float, float, float]:
    """(T_lo, T_hi, ΔP_lo, ΔP_hi) of a ramp fit from the volume error: refits at
    V (1 ± 1.96 σ_V) on the fit's window; ΔP = 2 T / R of the free cell."""
    ts, ps = [], []
    for sign in (-1.0, 1.0):
        r = float(cell_radius(volume_um3 * (1.0 + sign * Z95 * errors.volume_rel_sd)))
        t = refit(fit, x_um, force_nN, r).tension_mN_per_m
        ts.append(t)
        ps.append(float(pressure_Pa(t, 1.0 / r)))
    return min(ts), max(ts), min(ps), max(ps)
