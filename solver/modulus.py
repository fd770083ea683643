"""From a plate force to an effective area modulus (SPEC section 3).

All geometric quantities come from the droplet shape (section 1) at the given
volume, not from a simulated shape. With h1 = h0 - Δh:

    γ_eff  = F_tot / (2 H(h1) A_c(h1)),        Δγ_eff = γ_eff - γ_a,
    ε_A    = (A(h1) - A(h0)) / A(h0),          K = Δγ_eff / ε_A,

reported at the mean height h = (h0 + h1)/2, h̃ = h / (2 R_cell).
Vectorised: every argument may be an array (broadcast).
"""

import numpy as np
import numpy.typing as npt

from solver.geometry import droplet


def effective_modulus(volume: npt.ArrayLike, h0: npt.ArrayLike, h1: npt.ArrayLike, tension: npt.ArrayLike,
                      force: npt.ArrayLike) -> dict[str, npt.NDArray[np.float64]]:
    """K and its ingredients for forces F_tot (nN) measured at gap h1 after a
    compression from h0 (µm), cell volume V (µm³), active tension γ_a (mN/m).

    Returns a dict of arrays keyed with units: `gamma_eff_mN_per_m`,
    `delta_gamma_mN_per_m`, `area_strain`, `modulus_mN_per_m`, `h_mean_um`,
    `h_tilde`, `active_force_nN` (F_a(h1) = 2 γ_a H(h1) A_c(h1)),
    `area_increase_um2` (droplet estimate A(h1) - A(h0))."""
    d0, d1 = droplet(volume, h0), droplet(volume, h1)
    force = np.asarray(force, float)
    gamma_eff = force / d1.force_per_tension_um
    delta_gamma = gamma_eff - np.asarray(tension, float)
    increase = d1.surface_area_um2 - d0.surface_area_um2
    strain = increase / d0.surface_area_um2
    h_mean = 0.5 * (np.asarray(h0, float) + np.asarray(h1, float))
    with np.errstate(divide="ignore", invalid="ignore"):
        modulus = delta_gamma / strain
    return {
        "gamma_eff_mN_per_m": gamma_eff,
        "delta_gamma_mN_per_m": delta_gamma,
        "area_strain": strain,
        "modulus_mN_per_m": modulus,
        "h_mean_um": h_mean,
        "h_tilde": h_mean / (2.0 * d0.cell_radius_um),
        "active_force_nN": np.asarray(tension, float) * d1.force_per_tension_um,
        "area_increase_um2": increase,
    }
