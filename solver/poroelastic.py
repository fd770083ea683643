"""A thin poroelastic layer compressed between porous plates (SPEC section 8).

A layer of thickness t_c (the cortex: a scaffold of drained compression
modulus K, Pa, soaked in a fluid of viscosity η, Pa·s) is compressed across
its thickness between two porous plates that let the fluid out freely (p = 0
there). The solid displacement u(z) (z from the mid-plane, |z| ≤ t_c/2) and
the pore pressure p obey (biphasic mixture, Darcy flow):

    total stress   σ = K ∂u/∂z - p          uniform in z (no inertia),
    Darcy          w = -(k_perm/η) ∂p/∂z    (fluid flux relative to the solid),
    no net volume change  ∂u/∂t + w = 0,

hence the diffusion equation ∂u/∂t = D ∂²u/∂z² with D = K k_perm/η. The
plates oscillate, u(±t_c/2) = ±(t_c/2) ε̂ e^{iωt}; the solution
u = ε̂ t_c sinh(q z) / (2 sinh(q t_c/2)), q² = iω/D, gives the stress on a
plate σ̂ = K ε̂ x coth x, so the exact effective modulus is

    K_eff = K x coth x,        x = (t_c/2) sqrt(iωη / (K k_perm)).

λ = 1/|x| = (2/t_c) sqrt(K k_perm/(ωη)) is the poroelastic diffusion length
sqrt(D/ω) over the half thickness. For large λ (slow oscillation, permeable
layer) the strain is uniform across the layer, x coth x = 1 + x²/3 + O(x⁴),
and

    K_eff = K + iωη t_c² / (12 k_perm)        (large-λ limit),

whose imaginary (dissipative) part does not depend on K: it is the mean pore
pressure of the Poiseuille-like outflow, p = (η ε̇/2k)(z² - t_c²/4). The
permeability of straight pores of diameter d_pore (Hagen-Poiseuille):
k_perm = d_pore²/32.

Units: lengths in µm at the interface (converted to m inside), η in Pa·s,
f in Hz, moduli in Pa (a 3D modulus: the layer's, not the shell's 2D one).
"""

import numpy as np

from common.errors import InputError

UM = 1e-6   # m per µm


def _positive(name, value, allow_zero=False):
    value = float(value)
    if not np.isfinite(value) or value < 0 or (value == 0 and not allow_zero):
        bound = ">= 0" if allow_zero else "> 0"
        raise InputError(f"{name} must be a finite number {bound} (got {value:g})")
    return value


def permeability_m2(pore_diameter_um: float) -> float:
    """k_perm = d_pore²/32 (m²), Hagen-Poiseuille flow through pores of diameter d_pore (µm)."""
    d = _positive("pore diameter", pore_diameter_um) * UM
    return d * d / 32.0


def dissipative_modulus_Pa(pore_diameter_um: float, viscosity_Pa_s: float, thickness_um: float,
                           frequency_hz: float) -> float:
    """The large-λ term ω η t_c² / (12 k_perm) (Pa), ω = 2π f."""
    eta = _positive("viscosity", viscosity_Pa_s, allow_zero=True)
    t = _positive("thickness", thickness_um) * UM
    omega = 2.0 * np.pi * _positive("frequency", frequency_hz)
    return omega * eta * t * t / (12.0 * permeability_m2(pore_diameter_um))


def diffusion_ratio(modulus_Pa: float, pore_diameter_um: float, viscosity_Pa_s: float, thickness_um: float,
                    frequency_hz: float) -> float:
    """λ = (2/t_c) sqrt(K k_perm / (ω η)): the diffusion length sqrt(D/ω) over t_c/2
    (inf for η = 0)."""
    term = dissipative_modulus_Pa(pore_diameter_um, viscosity_Pa_s, thickness_um, frequency_hz)
    K = _positive("scaffold modulus", modulus_Pa)
    return float(np.sqrt(K / (3.0 * term))) if term > 0 else float("inf")   # |x|² = 3 term/K


def effective_modulus_exact(modulus_Pa: float, pore_diameter_um: float, viscosity_Pa_s: float,
                            thickness_um: float, frequency_hz: float) -> complex:
    """K_eff = K x coth x (complex, Pa), x² = iωη t_c²/(4 K k_perm) = 3i (ωηt_c²/12k_perm)/K."""
    K = _positive("scaffold modulus", modulus_Pa)
    term = dissipative_modulus_Pa(pore_diameter_um, viscosity_Pa_s, thickness_um, frequency_hz)
    x = np.sqrt(3j * term / K)
    if abs(x) < 1e-4:                                     # x coth x = 1 + x²/3 - x⁴/45
        return complex(K * (1.0 + x * x / 3.0 - x**4 / 45.0))
    return complex(K * x / np.tanh(x))


def effective_modulus_limit(modulus_Pa: float, pore_diameter_um: float, viscosity_Pa_s: float,
                            thickness_um: float, frequency_hz: float) -> complex:
    """K_eff = K + iωη t_c²/(12 k_perm) (complex, Pa), the large-λ limit."""
    K = _positive("scaffold modulus", modulus_Pa, allow_zero=True)
    return complex(K, dissipative_modulus_Pa(pore_diameter_um, viscosity_Pa_s, thickness_um,
                                             frequency_hz))
