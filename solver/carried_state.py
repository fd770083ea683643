"""The frequency-domain reading of a cortex that carries its history: the carried-state model (SPEC 10, 12).

A cell measured at several mean heights is stepped from its stress-free droplet at h_ref down
to h_1, waits, oscillates, steps to h_2, ... A power-law cortex never sheds the steps' stress:
at time t it still holds, of step k (height change Δh_k, made at t_k),

    σ_k(t) ≈ K(t - t_k) a_k,

so at h_m the cortex is the shell compressed from h_ref with the moduli of its history,

    K_eff = Σ_k K(t - t_k) Δh_k / Σ_k Δh_k        (each step's share of the strain ∝ Δh_k),

and oscillated there its stress increment is K*(ω) δa on the material stiffness while the
prestress stays what it is (`solver.prestressed_response`):

    K*_c(ω) = linear response of the shell (h_ref → h_m, moduli K_eff) with H + (K* - K_eff) M.

A power law fitted at f (|K*|, δ) gives its own relaxation (`power_law_relaxation`):

    K(t) = |K*| (ω t)^-β / Γ(1 - β),   β = 2δ/π,   ω = 2π f.

The relaxed-state model (`solver.viscoelastic`, what the published reading and its emulator
assume) is the same linear response about the relaxed droplet at h_m, K*_r(ω). Their ratio

    c = K*_c / K*_r,   Δγ = γ_a (F_c / F_r - 1)

(F the plate force of each state at h_m) turns a measured segment into the one the relaxed
model reads: K*/c, and <γ_eff> - Δγ its mean tension (`carried_correction`). For T_w → ∞
K_eff → 0 and the prestress vanishes, but c keeps the strain's reference h_ref (the time
domain's, `solver.time_domain`); `afm analyze --wait-s inf` skips the correction.

Limits: one compression with age-weighted moduli stands for the sum of steps (each step's
strain field is not the share Δh_k of the whole); the strains creep during the waits, which
K(t - t_k) a ignores; first order in the amplitude (the secant's amplitude factor is the
relaxed model's); the contact label is held where the touching free surface leaves no smooth
response (below about 3 µm depth). Validated against the time-domain shell in
docs/viscoelastic.md ("The history across heights").
"""

from dataclasses import dataclass, replace

import numpy as np
import numpy.typing as npt
from scipy.special import gamma as gamma_fn

from solver.model import PN_UM_PER_MN_PER_M_UM2, Shell
from solver.prestressed_response import complex_response
from solver.viscoelastic import complex_response as relaxed_response, hessian_parts
from solver.viscous import linearise

AMPLITUDE_UM = 0.25     # the oscillation's amplitude: the relaxed model's shell spans h_m ± this


def power_law_relaxation(modulus_mN_per_m: float, loss_angle_rad: float, frequency_hz: float,
                         t_s: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """K(t) (mN/m) of the power law with |K*| = `modulus_mN_per_m` and δ = `loss_angle_rad` at f."""
    beta = float(np.clip(2.0 * loss_angle_rad / np.pi, 0.0, 0.95))
    t = np.asarray(t_s, float)
    return np.asarray(modulus_mN_per_m * (2 * np.pi * frequency_hz * t) ** -beta / gamma_fn(1.0 - beta))


def effective_modulus(relaxation: npt.NDArray[np.float64], steps_um: npt.ArrayLike) -> float:
    """K_eff = Σ_k K(t - t_k) Δh_k / Σ_k Δh_k from K(t - t_k) of each step and its Δh_k (µm)."""
    dh = np.asarray(steps_um, float)
    return float((np.asarray(relaxation) * dh).sum() / dh.sum())


@dataclass(frozen=True)
class CarriedState:
    """One oscillation of a cell: its volume (µm³), active tension (mN/m), bending variant, the
    stress-free height h_ref (µm), the mean height h_m (µm) and the history's moduli K_eff (mN/m)."""

    volume_um3: float
    tension_mN_per_m: float
    bending: str
    reference_um: float
    mean_um: float
    bulk_eff_mN_per_m: float
    shear_eff_mN_per_m: float


def carried_correction(state: CarriedState, bulk_complex_mN_per_m: complex, shear_complex_mN_per_m: complex,
                       frequency_hz: float) -> tuple[complex, float]:
    """(c, Δγ): K*_c / K*_r and the mean tension the history adds (mN/m), module docstring."""
    kb, ks = bulk_complex_mN_per_m, shear_complex_mN_per_m
    relaxed = Shell(volume_um3=state.volume_um3, h0_um=state.mean_um + AMPLITUDE_UM, dh_um=2 * AMPLITUDE_UM,
                    bulk_mN_per_m=abs(kb), shear_mN_per_m=abs(ks), tension_mN_per_m=state.tension_mN_per_m,
                    bending=state.bending)
    parts = hessian_parts(relaxed)
    k_r = relaxed_response(parts, float(np.angle(kb)), float(np.angle(ks)), frequency_hz)
    carried = replace(relaxed, h0_um=state.reference_um, dh_um=2 * (state.reference_um - state.mean_um),
                      bulk_mN_per_m=state.bulk_eff_mN_per_m, shear_mN_per_m=state.shear_eff_mN_per_m,
                      bending_pN_um=relaxed.bending_stiffness * PN_UM_PER_MN_PER_M_UM2)
    lin = linearise(carried, hold_touching=True)
    lin.shell = carried
    k_c = complex_response(lin, carried, kb, ks, frequency_hz)
    return complex(k_c / k_r), state.tension_mN_per_m * (lin.force_nN / parts.lin.force_nN - 1.0)
