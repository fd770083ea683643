"""The linear response of a prestressed viscoelastic shell: complex moduli on the material stiffness only.

SPEC sections 10 and 12. A cortex stepped from its stress-free droplet at h0 to h_m and
oscillated at once holds the step's stress σ = K a (a = e1 + e2, and likewise the shear
channel) while it oscillates. Its energy's Hessian at that state splits per modulus into

    ∂H/∂K_B = M_B + G_B,   M_B = Σ_e ∇a_e ∇a_e^T A0_e,   G_B = Σ_e a_e ∇²a_e A0_e

(A0_e = 4π r̄0_e dS_e): the material stiffness M and the geometric stiffness G of the
prestress. Under a small oscillation the stress increment is K*(ω) δa, while the prestress
itself is what it is (real), so

    H*(ω) = H + (K_B* - K_B) M_B + (K_S* - K_S) M_S,

unlike `solver.viscoelastic` (which weights the whole ∂H/∂K, right about the relaxed state,
where a = 0). G_B is the Hessian of the linear term Σ_e a_e(u_m) a_e(u) A0_e with the
state's strains frozen (`solver.fast.kernel`'s per-element prestress), so M_B = H(K_B + 1) -
H(prestress a(u_m)) at the state, both on the same mesh. The response to the plate is
`solver.viscous.respond` with H*; bending and γ_a stay real.
"""

from dataclasses import replace

import numpy as np

from solver.fast.lagrangian import Lagrangian
from solver.model import PN_UM_PER_MN_PER_M_UM2, Shell
from solver.time_domain import element_strains
from solver.viscous import Linearised, full_hessian, hold_label, linearise, respond


def _like(lag: Lagrangian, shell: Shell, bulk: float, shear: float) -> Lagrangian:
    """A Lagrangian on `lag`'s mesh with `shell`'s B held and moduli (K_B, K_S)."""
    other = Lagrangian(replace(shell, bending_pN_um=shell.bending_stiffness * PN_UM_PER_MN_PER_M_UM2,
                               bulk_mN_per_m=bulk, shear_mN_per_m=shear), lag.ref)
    other.V0, other.area0 = lag.V0, lag.area0
    return other


def material_parts(lin: Linearised, shell: Shell) -> tuple[np.ndarray, np.ndarray]:
    """(M_B, M_S): the material stiffness per unit K_B and K_S at the linearised state."""
    lag, u, zp = lin.lag, lin.u, lin.zp
    a, s = element_strains(lag, u, zp)
    bulk, shear = shell.bulk_mN_per_m, shell.shear_mN_per_m
    parts = []
    for unit, pre in (((bulk + 1.0, shear), dict(pa=a)), ((bulk, shear + 1.0), dict(ps=s))):
        geometric = _like(lag, shell, bulk, shear)
        geometric.terms = geometric.terms._replace(**pre)
        M = full_hessian(_like(lag, shell, *unit), u, zp) - full_hessian(geometric, u, zp)
        if lin.held:
            hold_label(M, 0.0)
        parts.append(M)
    return parts[0], parts[1]


def complex_response(lin: Linearised, shell: Shell, bulk_complex_mN_per_m: complex,
                     shear_complex_mN_per_m: complex, frequency_hz: float) -> complex:
    """K*(ω) (mN/m) about the state `lin` of `shell` (its real moduli the prestress's) with
    H*(ω) = H + (K_B* - K_B) M_B + (K_S* - K_S) M_S (module docstring)."""
    MB, MS = material_parts(lin, shell)
    extra = ((bulk_complex_mN_per_m - shell.bulk_mN_per_m) * MB
             + (shear_complex_mN_per_m - shell.shear_mN_per_m) * MS)
    return respond(lin, 0.0, frequency_hz, extra).complex_modulus


def prestressed_modulus(shell: Shell, bulk_complex_mN_per_m: complex, shear_complex_mN_per_m: complex,
                        frequency_hz: float) -> complex:
    """K*(ω) (mN/m) of `shell` compressed from h0 to h_m = h0 - Δh/2 with its (real) moduli and
    oscillated there with K_B*, K_S* on the material stiffness (module docstring)."""
    lin = linearise(shell)
    lin.shell = shell
    return complex_response(lin, shell, bulk_complex_mN_per_m, shear_complex_mN_per_m, frequency_hz)
