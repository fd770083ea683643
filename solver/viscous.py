"""The shell around a viscous interior, oscillated: the complex modulus K*(ω).

SPEC section 7. At small amplitude the coupled problem is linear, so it is
solved in the frequency domain, around the equilibrium at the mean height
h_m = h0 - Δh/2 (the shell compressed from its stress-free droplet at h0;
`solver.fast`). The plate oscillates, h(t) = h_m + Re(δh e^{iωt}), and every
unknown responds at ω; inertia is dropped (Reynolds number ~1e-7).

Shell (generalised coordinates q = (u, z_p), u = node positions, contact
label l, pressure p; `solver.fast.lagrangian`): the linearised balance of the
elastic forces and the fluid's

    H_uu δu + H_u,zp δz_p + G_uᵀ R(iω G δq) = 0,

with H the exact Hessian of the discrete Lagrangian (the column in z_p by a
central difference of its exact gradient), G the map from δq to the
displacement of the shell's *material* at the fluid's boundary unknowns, and
R the fluid's reaction. No slip: the fluid moves with the cortex's material,
whose displacement at node k is δX_k - X'(ψ0_k) (∂ψ0_k/∂l) δl (the nodes'
labels ψ0 move with l); between nodes the material moves linearly, and each
edge's midpoint gets the normal correction that makes that slip field carry
no volume flux, so the fluid's flux is exactly the shell polygon's volume
change (zero, by the shell's constraint). The fluid (`solver.stokes`, half
cell, ×2 by symmetry) solved with the shell in one sparse system:

    A_ff w_f + A_fb G δq - B_fᵀ π = 0,   B_f w_f + B_b G δq = 0,
    R = 2·1e-3 iωη (A_bf w_f + A_bb G δq - B_bᵀ π)      (nN; Pa·µm² = 1e-3 nN),

w the fluid displacement (velocity / iω), π the pressure / (iωη).

Plate force F = -(1/2)(∂L/∂z_p + R_zp): δF = -(1/2)(H_zp,q δq + R_zp). As in
the experiment (SPEC 6) with the droplet's g(h) = 2 H A_c and A(h) at h_m:

    δγ_eff = (δF - γ_0 g'(h_m) δh) / g(h_m),   γ_0 = F_0 / g(h_m),   ε̂_A = A'(h_m) δh / A(h_m),
    K*(ω) = δγ_eff / ε̂_A = K' + i K'',   loss angle = arg K*.

Energy balance (checked): the mean power of the plate -(1/2) Re(δF̄ iω δh)
equals the mean dissipation (1/2) ∫ 2η ê:ê* dV.
"""

import time
from dataclasses import dataclass, replace
from functools import lru_cache
from typing import Any

import numpy as np
import numpy.typing as npt
from scipy.sparse import coo_matrix, csc_matrix
from scipy.sparse.linalg import spsolve

from common.errors import SolverError
from solver.fast import contact_at_least, equilibrium
from solver.fast.lagrangian import Lagrangian
from solver.geometry import droplet
from solver.model import Shell, check_viscous_inputs
from solver.stokes import Interior

NN_PER_PA_UM2 = 1e-3    # 1 Pa·µm² = 1e-3 nN
STEP_ZP = 1e-7          # µm, central difference of the gradient in z_p
STEP_H = 1e-4           # µm, central difference of the droplet's g(h) and A(h)
H_MAX = 0.5             # µm, largest element of the fluid mesh


@dataclass
class Linearised:
    """The shell's equilibrium at h_m and its linearisation."""

    lag: Lagrangian
    u: np.ndarray
    zp: float
    H: np.ndarray        # (n+1, n+1) Hessian in q = (u, z_p)
    force_nN: float      # F_0 at h_m
    h_mean_um: float
    G: Any = None        # q -> fluid boundary displacements (`prepare`)
    D: Any = None        # Gᵀ R_1 G: the fluid condensed onto q, per unit η (Pa·µm²/µm), an array once set
    shell: Any = None    # the `Shell`, once `prepare` or `solver.viscoelastic` set it
    held: bool = False   # whether the contact label l is held (a gauge, or at its bound)


def _zp_derivative(lag, u, zp, part):
    """∂/∂z_p of evaluate()'s output `part` (1: ∇L, 2: ∂L/∂z_p) at fixed u, by the
    fourth-order central difference (-f(2s) + 8 f(s) - 8 f(-s) + f(-2s)) / 12s:
    the first free node sits ~1e-4 µm above the plate, so the step must be far smaller."""
    f = [lag.evaluate(u, zp + k * STEP_ZP, hessian=False)[part] for k in (2, 1, -1, -2)]
    return (-f[0] + 8 * f[1] - 8 * f[2] + f[3]) / (12 * STEP_ZP)


def linearise(shell: Shell) -> Linearised:
    """The equilibrium at h_m = h0 - Δh/2 (from the stress-free droplet at h0) and
    the Hessian of L in q = (u, z_p). The contact label l moves with the
    response where it is stationary (dE*/dl = 0); it is held where it is a
    gauge (tension-only shell) or at its least value. Raises SolverError
    where it is held by the free surface touching the plate (not smooth)."""
    mean = replace(shell, dh_um=0.5 * shell.dh_um, viscosity_Pa_s=None, frequency_hz=None)
    lag, u, _ = equilibrium(mean)
    zp = 0.5 * mean.h1_um
    _, g, dzp, H = lag.evaluate(u, zp)
    held = not lag.elastic or contact_at_least(u)     # a gauge, or at its bound
    if not held and abs(g[-2]) > 1e-4 * lag.force_scale:
        raise SolverError("the contact line is held at the touching label (dE*/dl = "
                          f"{g[-2]:.3g}): no smooth linear response")
    lin = Linearised(lag=lag, u=u, zp=zp, H=full_hessian(lag, u, zp, H), force_nN=-0.5 * dzp, h_mean_um=2 * zp)
    lin.held = held
    if held:                     # l is a gauge (tension only) or at its least value: hold it
        hold_label(lin.H, 1.0)
    return lin


def full_hessian(lag: Lagrangian, u: npt.NDArray[np.float64], zp: float, H: npt.NDArray[np.float64] | None = None) -> npt.NDArray[np.float64]:
    """The Hessian of L in q = (u, z_p) at (u, z_p): `H` (the Hessian in u, evaluated
    here if not given) bordered by the column in z_p (`_zp_derivative`)."""
    n = lag.size
    full = np.zeros((n + 1, n + 1))
    full[:n, :n] = lag.evaluate(u, zp)[3] if H is None else H
    full[:n, n] = full[n, :n] = _zp_derivative(lag, u, zp, 1)
    full[n, n] = _zp_derivative(lag, u, zp, 2)
    return full


def hold_label(H: npt.NDArray[np.float64], diagonal: float) -> None:
    """Hold the contact label l (unknown n - 2 of q) in the Hessian H of q: its row
    and column zero, `diagonal` on the diagonal (1 for the Hessian, 0 for a part of it)."""
    k = H.shape[0] - 3
    H[k, :], H[:, k], H[k, k] = 0.0, 0.0, diagonal


def _node_jacobian(lin):
    """J (2(N+1), n+1): material displacement (δr_k, δz_k) of node k per δq."""
    lag, u, zp = lin.lag, lin.u, lin.zp
    n, N, nd = lag.size, lag.N, len(lag.ref.eta)
    r, z, psic, _ = lag.nodes(u, zp)
    rows, cols, vals = [], [], []
    for comp, idx in ((0, lag.ridx), (1, lag.zidx)):
        k = np.nonzero(idx <= n)[0]
        rows += list(2 * k + comp)
        cols += list(idx[k])
        vals += [1.0] * len(k)
    # label of every node from the disc's edge on: ψ0 and ∂ψ0/∂l
    xi, zeta = lag.ref.xi, lag.ref.zeta
    psi = np.concatenate([[0.0], psic * zeta, psic + (np.pi / 2 - psic) * xi])
    dpsi = np.concatenate([[0.0], psic * zeta, psic * (1.0 - xi)])
    k = np.arange(nd, N + 1)
    for comp, x in ((0, r), (1, z)):
        slope = np.gradient(x[k], psi, edge_order=2)          # X'(ψ0) along the shell
        rows += list(2 * k + comp)
        cols += [n - 2] * len(k)
        vals += list(-slope * dpsi)
    return coo_matrix((vals, (rows, cols)), shape=(2 * (N + 1), n + 1)).tocsr()


def _boundary_map(lin, fluid):
    """G (fluid shell dofs × (n+1)): nodes' material displacements to the P2
    dofs, midpoints the mean of their ends plus the flux-free correction."""
    lag = lin.lag
    N, n = lag.N, lag.size
    r, z = lag.nodes(lin.u, lin.zp)[:2]
    J = _node_jacobian(lin).toarray()
    ub, mesh = fluid.ub, fluid.mesh
    G = np.zeros((ub.N, n + 1))
    for comp in (0, 1):
        G[ub.nodal_dofs[comp, : N + 1]] = J[comp::2]
    facet_of = {tuple(f): i for i, f in enumerate(np.sort(mesh.facets.T, axis=1))}
    e = np.array([facet_of[(k, k + 1)] for k in range(N)])
    dr, dz = np.diff(r), np.diff(z)
    L = np.hypot(dr, dz)
    nr, nz = -dz / L, dr / L                                 # outward normal (pole -> equator)
    # ∫ over the edge of P2 basis × r (3-point Gauss, exact): ends and midpoint weights
    t, w = np.array([0.5 - np.sqrt(0.15), 0.5, 0.5 + np.sqrt(0.15)]), np.array([5, 8, 5]) / 18
    phi = np.stack([(1 - t) * (1 - 2 * t), 4 * t * (1 - t), t * (2 * t - 1)])
    rq = r[:-1, None] + np.outer(dr, t)
    W = np.einsum("q,jq,eq->ej", w, phi, rq) * L[:, None]       # (edge, [start, mid, end])
    slip = np.zeros((2 * (N + 1), n + 1))
    slip[:, n - 2] = J[:, n - 2]
    mid = 0.5 * (J[0::2][:-1] + J[0::2][1:]), 0.5 * (J[1::2][:-1] + J[1::2][1:])
    sr, sz = slip[0::2], slip[1::2]
    flux = (W[:, 0, None] * (sr[:-1] * nr[:, None] + sz[:-1] * nz[:, None])
            + W[:, 1, None] * (0.5 * (sr[:-1] + sr[1:]) * nr[:, None] + 0.5 * (sz[:-1] + sz[1:]) * nz[:, None])
            + W[:, 2, None] * (sr[1:] * nr[:, None] + sz[1:] * nz[:, None]))
    corr = -flux / W[:, 1, None]
    G[ub.facet_dofs[0, e]] = mid[0] + corr * nr[:, None]
    G[ub.facet_dofs[1, e]] = mid[1] + corr * nz[:, None]
    return csc_matrix(G[fluid.fixed])


@dataclass
class Response:
    """K*(ω) at one viscosity and frequency, and its energy balance."""

    complex_modulus: complex      # mN/m
    force_amplitude_nN: complex   # δF per δh = -1 µm (compression)
    displacement: np.ndarray      # δq = (δu, δz_p) per δh = -1 µm
    dissipation: float            # mean viscous dissipation, nN·µm/s (= 1e-15 W), whole cell, per µm² of δh²
    plate_power: float            # mean power the plate puts in, nN·µm/s, per µm² of δh²
    h_mean_um: float
    wall_s: float

    def to_dict(self, elastic_modulus: float) -> dict[str, float]:
        K = self.complex_modulus
        return {"modulus_mN_per_m": abs(K), "storage_modulus_mN_per_m": K.real,
                "loss_modulus_mN_per_m": K.imag, "loss_angle_rad": float(np.angle(K)),
                "elastic_modulus_mN_per_m": float(elastic_modulus),
                "dissipation_fW_per_um2": self.dissipation, "plate_power_fW_per_um2": self.plate_power,
                "h_mean_um": self.h_mean_um, "viscous_wall_s": self.wall_s}


def _droplet_slopes(shell, h):
    """g(h), g'(h), A(h), A'(h) of the droplet (g = 2 H A_c, µm; A, µm²)."""
    d = droplet(shell.volume_um3, np.array([h - STEP_H, h, h + STEP_H]))
    g, A = d.force_per_tension_um, d.surface_area_um2
    return g[1], (g[2] - g[0]) / (2 * STEP_H), A[1], (A[2] - A[0]) / (2 * STEP_H)


def shell_response(lin: Linearised, viscosity_Pa_s: float, frequency_hz: float,
                   extra: npt.NDArray[np.complex128] | None = None,
                   sparse: bool = False) -> tuple[npt.NDArray[np.complex128], complex]:
    """δq and δF (nN) for δh = -1 µm at (η, f): the dense solve of `respond`
    (`extra`: a matrix added to the shell's Hessian, e.g. `solver.viscoelastic`'s
    complex moduli; the fluid term is skipped where η = 0). `sparse`: the same system by a
    sparse LU (the shell's Hessian is banded and bordered: no threaded dense solve)."""
    n = lin.lag.size
    c = 2.0 * NN_PER_PA_UM2 * 2j * np.pi * frequency_hz * viscosity_Pa_s
    S = lin.H + c * lin.D if viscosity_Pa_s else lin.H.astype(complex)
    if extra is not None:
        S = S + extra
    dq = np.empty(n + 1, complex)
    dq[n] = -0.5                                          # δz_p for δh = -1
    rhs = -S[:n, n] * dq[n]
    dq[:n] = spsolve(csc_matrix(S[:n, :n]), rhs) if sparse else np.linalg.solve(S[:n, :n], rhs)
    return dq, -0.5 * (S[n] @ dq)


def respond(lin: Linearised, viscosity_Pa_s: float, frequency_hz: float,
            extra: npt.NDArray[np.complex128] | None = None, sparse: bool = False) -> Response:
    """Solve the coupled linear system at (η, f) for δh = -1 µm: a Response.
    With the fluid condensed onto the shell (`prepare`: D = Gᵀ R_1 G, R_1 the
    fluid's reaction per unit η and displacement), the shell's equations

        (H_uu + c D_uu) δu = -(H_u,zp + c D_u,zp) δz_p,   c = 2·1e-3 iωη,

    and δF = -(1/2) (H_zp,q + c D_zp,q) δq (`extra` added to H: `shell_response`;
    `dissipation` is the fluid's alone, 0 where η = 0; `sparse`: `shell_response`'s)."""
    check_viscous_inputs(viscosity_Pa_s, frequency_hz)
    start = time.perf_counter()
    omega = 2 * np.pi * frequency_hz
    dq, dF = shell_response(lin, viscosity_Pa_s, frequency_hz, extra, sparse)
    dissipation = (omega**2 * viscosity_Pa_s * np.real(np.conj(dq) @ (lin.D @ dq)) * NN_PER_PA_UM2
                   if viscosity_Pa_s else 0.0)
    power = -0.5 * np.real(dF * np.conj(1j * omega * -1.0))
    g, dg, area, darea = _droplet_slopes(lin.shell, lin.h_mean_um)
    dgamma = (dF - lin.force_nN / g * dg * -1.0) / g
    strain = darea * -1.0 / area
    return Response(complex_modulus=complex(dgamma / strain), force_amplitude_nN=complex(dF),
                    displacement=dq, dissipation=float(dissipation), plate_power=float(power),
                    h_mean_um=lin.h_mean_um, wall_s=time.perf_counter() - start)


def flow(lin: Linearised, fluid: Interior, response: Response, frequency_hz: float) -> npt.NDArray[np.complex128]:
    """The fluid's velocity amplitude (all P2 unknowns, µm/s per µm of δh) of a Response."""
    w = np.zeros(fluid.ub.N, complex)
    w[fluid.fixed] = lin.G @ response.displacement
    wb = w[fluid.fixed]
    w[fluid.free] = fluid.extend(wb.real)[0] + 1j * fluid.extend(wb.imag)[0]
    return 2j * np.pi * frequency_hz * w


def prepare(shell: Shell, h_max: float = H_MAX) -> tuple[Linearised, Interior]:
    """The linearised shell at h_m with its fluid mesh and boundary map."""
    lin = linearise(shell)
    r, z = lin.lag.nodes(lin.u, lin.zp)[:2]
    fluid = Interior.from_outline(r, z, h_max=h_max)
    lin.G = _boundary_map(lin, fluid)
    G = lin.G.toarray()
    lin.D = G.T @ fluid.drag(G)
    lin.D = 0.5 * (lin.D + lin.D.T)          # symmetric up to round-off
    lin.shell = shell
    return lin, fluid


def complex_modulus(shell: Shell, viscosity_Pa_s: float, frequency_hz: float, h_max: float = H_MAX) -> Response:
    """K*(ω) of `shell` (a `solver.model.Shell`) oscillated around h0 - Δh/2."""
    check_viscous_inputs(viscosity_Pa_s, frequency_hz)
    return respond(prepare(shell, h_max)[0], viscosity_Pa_s, frequency_hz)


@lru_cache(maxsize=4)
def _prepared(shell, h_max):
    """The condensed linearisation of an elastic shell (cached: a campaign asks
    for many viscosities and frequencies of the same cell in a row)."""
    return prepare(shell, h_max)[0]


def viscous_keys(shell: Shell, h_max: float = H_MAX) -> dict[str, float]:
    """K*(ω) of a shell with `viscosity_Pa_s` and `frequency_hz` set, around h_m:
    `modulus_mN_per_m` = |K*|, `storage_modulus_mN_per_m`, `loss_modulus_mN_per_m`,
    `loss_angle_rad`, `elastic_modulus_mN_per_m` (K*(ω) without viscosity, the
    same linearisation), the energy balance and the wall time."""
    start = time.perf_counter()
    eta, f = shell.viscosity_Pa_s, shell.frequency_hz
    assert eta is not None and f is not None, "viscous_keys needs a shell with a viscosity and a frequency"
    check_viscous_inputs(eta, f)
    lin = _prepared(replace(shell, viscosity_Pa_s=None, frequency_hz=None), h_max)
    out = {"viscosity_Pa_s": float(eta), "frequency_hz": float(f)}
    out.update(respond(lin, eta, f).to_dict(respond(lin, 0.0, f).complex_modulus.real))
    out["viscous_wall_s"] = time.perf_counter() - start
    return out
