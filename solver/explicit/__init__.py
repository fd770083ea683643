"""The published explicit scheme as reference solver: gradient flow of the shell's
surface forces on a 1D axisymmetric mesh of the upper half meridian (SPEC section 2).

Reference state: the droplet at h0 (`solver.geometry.meridian`), stress free;
H0 of each node is the discrete mean curvature of the reference mesh (so the
droplet's free surface carries H0 = H(h0), the contact disc H0 = 0, and the
reference mesh has no bending force); its radii are scaled by 1 + O(ds²) so
that it encloses exactly V, and it is stress free at that volume. The mesh is graded in reference arc
length S from the pole: element size `ds_min` over the band around the contact
line that the compression rolls onto the plate plus 3 bending lengths
ℓ_b = sqrt(B/γ_a) on each side, growing linearly with slope `GROWTH` to
`ds_max` away from it. At resolution 1, ds_min = min(DS_MIN, ℓ_b/LAYER_ELEMENTS)
and ds_max = DS_MAX; resolution r divides this whole size function by r, so
the meshes of one shell form a refinement family (Richardson extrapolation,
`bench/convergence.py`). With DS_MAX = 0.15 µm K converged at order p ≈ 2 and
was 0.12-0.22 % off its limit at resolution 1 on some points, limited by the
far field, not the contact band; with 0.075 µm it is within 0.07 % of the
limit (and of the fast solver's), and the observed order varies (0.6-3.4)
because the far-field and contact-band errors are now of similar size.

Time stepping (`solver.explicit.surface_forces.flow`): v = μ f / A (force density), μ = 1
µm²/(s·mN/m) (only μ t matters for the equilibrium), volume held by a Lagrange
multiplier (the pressure p), time step below both explicit limits,

    dt = C_DT / (2 (K_B + K_S + γ_a)/ds_min² + 8 B/ds_min⁴),

plate moved as h(t) = h0 - (Δh/2)(1 - cos(π t / t_c)) over t_c = τ, then held
until the plate force settles. A plate node lifts off again where the plate would have
to pull it by more than RELEASE × p (a departure from the published "stays on
the plate": nodes stuck during the transient made F_tot jump by ~2 % with the
contact position; with lift-off F_tot = -∂E/∂h to 3e-4). Tension-only shells
keep the published rule (lift-off chatters there, and F is exact without it).
Settled when |ΔF_tot|/F_tot per relaxation time
τ = R_cell² / (4 μ (γ_a + K_B + K_S)) below `TOL`. F_tot is the sum of the
plate's normal reactions on the nodes it holds (exact for the discrete energy).
"""

import numpy as np
import numpy.typing as npt

from solver.explicit import surface_forces as sf
from common.errors import SolverError
from solver.frustum import enclosed_volume, nodal_stretches, surface_area
from solver.geometry import droplet, meridian
from solver.model import Shell
from solver.solution import Solution

MU = 1.0              # µm² / (s · mN/m)
C_DT = 0.8            # fraction of the explicit stability limit
TOL = 1e-7            # relative change of F_tot per relaxation time
GROWTH = 0.12         # element size growth per unit arc length away from the contact band
DS_MIN = 0.05         # element size at the contact line at resolution 1, µm
LAYER_ELEMENTS = 4.0  # ... or at most sqrt(B/γ_a) / LAYER_ELEMENTS
DS_MAX = 0.075        # largest element at resolution 1, µm (0.15 left K 0.1-0.2 % unconverged)
RELEASE = 1e-2        # plate nodes lift off where the plate pulls by more than this × p
MAX_TIMES = 80.0      # step budget: this many relaxation times after the compression


def _psi_of_s(V, h, s):
    """Invert the free surface's closed-form arc length s(ψ) (Newton from a table)."""
    d = droplet(V, h)
    H, Rc = float(d.mean_curvature_per_um), float(d.contact_radius_um)
    beta = 2.0 * H * Rc
    m = np.sqrt(1.0 + beta * beta)
    table = np.linspace(0.0, np.pi / 2, 4001)
    s_of = lambda p: (p + np.arcsin(1.0 / m) - np.arcsin(np.cos(p) / m)) / (2.0 * H)
    psi = np.interp(s, s_of(table), table)
    for _ in range(4):
        q = np.sqrt(np.sin(psi) ** 2 + beta * beta)
        psi = np.clip(psi - (s_of(psi) - s) * 2.0 * H / (1.0 + np.sin(psi) / q), 0.0, np.pi / 2)
    return psi


def _graded(a, b, size):
    """Nodes from a to b with local element size size(S) (equidistributed 1/size)."""
    S = np.linspace(a, b, 20001)
    dens = np.concatenate([[0.0], np.cumsum(0.5 * (1 / size(S[1:]) + 1 / size(S[:-1])) * np.diff(S))])
    n = max(2, int(np.ceil(dens[-1])))
    return np.interp(np.linspace(0.0, dens[-1], n + 1), dens, S)


def mesh(shell: Shell) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.int64], float]:
    """Reference nodes (r0, z0), node kinds and the sizes used: returns
    r0, z0, kind, ds_min."""
    V, h0, h1 = shell.volume_um3, shell.h0_um, shell.h1_um
    d0, d1 = droplet(V, h0), droplet(V, h1)
    Rc = float(d0.contact_radius_um)
    s_free = float(meridian(V, h0, np.array([np.pi / 2]))[2][0])
    B, gamma = shell.bending_stiffness, shell.tension_mN_per_m
    lb = np.sqrt(B / gamma) if B > 0 else 0.0
    ds1 = min(DS_MIN, lb / LAYER_ELEMENTS) if B > 0 else DS_MIN     # ds_min at resolution 1
    roll = 1.5 * (float(d1.contact_radius_um) - Rc) + 3.0 * lb + 5 * ds1
    lo, hi = Rc - 3.0 * lb - 5 * ds1, Rc + roll
    # resolution divides the whole size function: every element is refined alike
    size = lambda S: np.minimum(DS_MAX, ds1 + GROWTH * np.maximum(0.0, np.maximum(lo - S, S - hi))
                                ) / shell.resolution
    ds_min = ds1 / shell.resolution
    S_disc = _graded(0.0, Rc, size)
    S_free = _graded(Rc, Rc + s_free, size)
    r_f, z_f, _ = meridian(V, h0, _psi_of_s(V, h0, S_free[1:] - Rc))
    r0 = np.concatenate([S_disc, r_f])
    z0 = np.concatenate([np.full(S_disc.size, h0 / 2.0), z_f])
    z0[-1] = 0.0
    r0 *= np.sqrt(V / enclosed_volume(r0, z0))     # chords enclose exactly V
    kind = np.full(r0.size, sf.FREE, dtype=np.int64)
    kind[: S_disc.size] = sf.PLATE
    kind[0] = sf.POLE
    kind[-1] = sf.EQUATOR
    return r0, z0, kind, ds_min


def _run(shell, mat, ds_min):
    """The time loop's `surface_forces.Run`: dt from the stability bound of the
    module docstring, the plate compressed over one relaxation time τ, the
    force checked every τ/10, at most 1 + MAX_TIMES relaxation times."""
    gamma, KB, KS, B = mat
    dt = C_DT / (2.0 * (KB + KS + gamma) / ds_min**2 + 8.0 * B / ds_min**4) / MU
    R_cell = float(droplet(shell.volume_um3, shell.h0_um).cell_radius_um)
    tau = R_cell**2 / (4.0 * MU * (gamma + KB + KS))
    return sf.Run(mu=MU, dt=dt, V0half=0.5 * shell.volume_um3, h0=float(shell.h0_um),
                  dh=float(shell.dh_um), t_comp=tau, check_every=max(1, int(0.1 * tau / dt)),
                  tau_relax=tau, tol=TOL, max_steps=int((1.0 + MAX_TIMES) * tau / dt),
                  release_tol=RELEASE if KB + KS + B > 0 else np.inf)


def solve(shell: Shell) -> Solution:
    """Compress `shell` from h0 to h1 by the explicit gradient flow; raise
    SolverError if the plate force does not settle within the step budget."""
    return relax(shell)[0]


def relax(shell: Shell) -> tuple[Solution, float, tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]]:
    """`solve`, also returning the final pressure p (mN/m/µm, the volume's
    Lagrange multiplier) and the reference nodes (r0, z0) in µm."""
    r0, z0, kind, ds_min = mesh(shell)
    mat = sf.Material(float(shell.tension_mN_per_m), float(shell.bulk_mN_per_m),
                      float(shell.shear_mN_per_m), float(shell.bending_stiffness))
    r, z = r0.copy(), z0.copy()
    run = _run(shell, mat, ds_min)
    F, p, steps, settled, res = sf.flow(r, z, kind, sf.reference(r0, z0), mat, run)
    dt, max_steps = run.dt, run.max_steps
    if not np.isfinite(F) or not np.all(np.isfinite(r)):
        raise SolverError(f"explicit scheme went unstable (dt = {dt:.3g} s, ds_min = {ds_min:.3g} um)")
    if not settled:
        raise SolverError(f"plate force did not settle to {TOL:g} per relaxation time within "
                          f"{max_steps} steps ({MAX_TIMES:g} relaxation times); F = {F:.6g} nN")
    lam1, lam2 = nodal_stretches(r, z, r0, z0)
    volume = enclosed_volume(r, z)
    msg = (f"settled after {steps} steps (dt = {dt:.3g} s, {r.size} nodes, ds_min = {ds_min:.3g} um); "
           f"pressure {p:.6g} mN/m/um, residual force density {res:.3g} mN/m/um")
    return Solution(force_nN=float(F), volume_um3=float(volume),
                    area_um2=float(surface_area(r, z)), area0_um2=float(surface_area(r0, z0)),
                    r_um=r, z_um=z, lambda1=lam1, lambda2=lam2,
                    converged=True, iterations=int(steps), message=msg), float(p), (r0, z0)
