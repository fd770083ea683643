"""Surface forces of the axisymmetric shell on its meridian mesh (SPEC section 2),
numba-compiled, and the explicit time loop that uses them.

Mesh: nodes i = 0..N along the upper half meridian, pole (r = 0, on the plate)
to equator (z = 0, mirror plane). Element j joins nodes j, j+1 and is a frustum:

    l_j = |x_{j+1} - x_j|,   r̄_j = (r_j + r_{j+1})/2,   a_j = 2π r̄_j l_j,
    ψ_j = atan2(-(z_{j+1} - z_j), r_{j+1} - r_j)      (tangent angle to the plate).

Discrete energy of the upper half (mirror symmetry gives the rest):

    E = γ_a Σ a_j + Σ w(λ1_j, λ2_j) a0_j + 2B Σ_i (H_i - H0_i)² A_i,
    λ1_j = l_j / l0_j,  λ2_j = r̄_j / r̄0_j,
    w = (K_B/2)(e1+e2)² + (K_S/2)(e1-e2)²,   e = λ - 1,
    H_i = (κ1 + κ2)/2,  κ1 = (ψ_i - ψ_{i-1}) / L_i,  κ2 = sin ψ̄_i / r_i,
    ψ̄_i = (ψ_{i-1} + ψ_i)/2,  L_i = (l_{i-1} + l_i)/2,  A_i = 2π r_i L_i.

At the equator the mirror element has angle π - ψ_{N-1}, so ψ̄_N = π/2,
κ1 = (π - 2ψ_{N-1}) / l_{N-1}, κ2 = 1/r_N and the half node has A_N = π r_N l_{N-1}.
The pole lies on the plate, where the surface is flat (no bending term).
Half volume V/2 = Σ_j V_j of the frustums (`solver.frustum.half_volume`).

The nodal forces are f = -∂E/∂x + p ∂V/∂x, the exact gradient of the
discrete energy; divided by the nodal area they are the discretisation of
SPEC's force densities: tension -2γ_a H n; stretching
-(2H n - ∇_Γ)τ1 + (τ1 - τ2)/r e_r with Cauchy tensions (checked against these
densities in tests/test_explicit_solver.py);
bending B (2Δ_Γ(H-H0) + 4(2H² - K_G)(H-H0) - 4H(H-H0)²) n; pressure p n.
Because they are exact gradients, the plate's reaction on the contact nodes
sums to ∂E/∂h at fixed volume: the force on the plate is consistent with the
energy to round-off.

Units: µm, mN/m, nN (mN/m·µm), mN/m/µm for pressures and force densities, s.
"""

from collections import namedtuple

import numpy as np
import numpy.typing as npt

from solver.frustum import half_volume
from solver.jit import njit

FREE, PLATE, EQUATOR, POLE = 0, 1, 2, 3

# The reference meridian: l0_j, r̄0_j per element and H0_i per node (`reference`).
Reference = namedtuple("Reference", "l0 rb0 H0")
# The material: γ_a, K_B, K_S (mN/m) and B (mN/m·µm²).
Material = namedtuple("Material", "gamma KB KS B")
# The time loop (`flow`): mobility μ, step dt, target half volume V0/2, the
# plate motion (h0, Δh, t_comp) and the stopping rule (check_every,
# tau_relax, tol, max_steps) and the plate's release threshold.
Run = namedtuple("Run", "mu dt V0half h0 dh t_comp check_every tau_relax tol max_steps release_tol")


@njit(cache=True)
def elements(r: npt.NDArray[np.float64], z: npt.NDArray[np.float64]) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """(l_j, ψ_j) of every element: its length and tangent angle to the plate."""
    n = r.size - 1
    l = np.empty(n)
    psi = np.empty(n)
    for j in range(n):
        dr = r[j + 1] - r[j]
        dz = z[j + 1] - z[j]
        l[j] = np.sqrt(dr * dr + dz * dz)
        psi[j] = np.arctan2(-dz, dr)
    return l, psi


@njit(cache=True)
def mean_curvature(r: npt.NDArray[np.float64], z: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """Discrete H_i at the nodes (0 at the pole, which lies on the plate)."""
    l, psi = elements(r, z)
    n = r.size - 1
    H = np.zeros(n + 1)
    for i in range(1, n):
        L = 0.5 * (l[i - 1] + l[i])
        k1 = (psi[i] - psi[i - 1]) / L
        k2 = np.sin(0.5 * (psi[i] + psi[i - 1])) / r[i]
        H[i] = 0.5 * (k1 + k2)
    H[n] = 0.5 * ((np.pi - 2.0 * psi[n - 1]) / l[n - 1] + 1.0 / r[n])
    return H


@njit(cache=True)
def reference(r0: npt.NDArray[np.float64], z0: npt.NDArray[np.float64]) -> Reference:
    """The `Reference` of the nodes (r0, z0): l0, r̄0 = (r0_j + r0_j+1)/2 and H0."""
    return Reference(elements(r0, z0)[0], 0.5 * (r0[1:] + r0[:-1]), mean_curvature(r0, z0))


@njit(cache=True)
def energy(r: npt.NDArray[np.float64], z: npt.NDArray[np.float64], ref: Reference, mat: Material) -> float:
    """Discrete energy E of the upper half (see module docstring), in mN/m·µm²,
    for the reference `ref` and the material `mat`."""
    l0, rb0, H0 = ref
    gamma, KB, KS, B = mat
    l, psi = elements(r, z)
    n = r.size - 1
    H = mean_curvature(r, z)
    E = 0.0
    for j in range(n):
        rb = 0.5 * (r[j] + r[j + 1])
        e1 = l[j] / l0[j] - 1.0
        e2 = rb / rb0[j] - 1.0
        w = 0.5 * KB * (e1 + e2) ** 2 + 0.5 * KS * (e1 - e2) ** 2
        E += gamma * 2.0 * np.pi * rb * l[j] + w * 2.0 * np.pi * rb0[j] * l0[j]
    if B > 0.0:
        for i in range(1, n):
            E += 2.0 * B * (H[i] - H0[i]) ** 2 * 2.0 * np.pi * r[i] * 0.5 * (l[i - 1] + l[i])
        E += 2.0 * B * (H[n] - H0[n]) ** 2 * np.pi * r[n] * l[n - 1]
    return E


@njit(cache=True)
def _stretch_and_volume(r, z, l, ref, mat, acc):
    """Per element: tension and stretching as ∂E/∂l_j (into gl) and ∂E/∂r̄_j
    (half onto each node's r), and ∂(V_j)/∂(r, z) of its frustum (into gV)."""
    l0, rb0, _ = ref
    gamma, KB, KS, _ = mat
    gE, gV, gl, _, _ = acc
    for j in range(r.size - 1):
        rb = 0.5 * (r[j] + r[j + 1])
        e1 = l[j] / l0[j] - 1.0
        e2 = rb / rb0[j] - 1.0
        t1 = (KB + KS) * e1 + (KB - KS) * e2
        t2 = (KB - KS) * e1 + (KB + KS) * e2
        a0 = 2.0 * np.pi * rb0[j] * l0[j]
        gl[j] += gamma * 2.0 * np.pi * rb + a0 * t1 / l0[j]
        dEdrb = gamma * 2.0 * np.pi * l[j] + a0 * t2 / rb0[j]
        gE[j, 0] += 0.5 * dEdrb
        gE[j + 1, 0] += 0.5 * dEdrb
        S = r[j] ** 2 + r[j] * r[j + 1] + r[j + 1] ** 2
        dz = z[j] - z[j + 1]
        c = np.pi / 3.0
        gV[j, 1] += c * S
        gV[j + 1, 1] -= c * S
        gV[j, 0] += c * dz * (2.0 * r[j] + r[j + 1])
        gV[j + 1, 0] += c * dz * (r[j] + 2.0 * r[j + 1])


@njit(cache=True)
def _bending_and_areas(r, l, psi, ref, B, acc):
    """The nodal areas A_i, and per node the bending term's ∂E/∂ψ (into gp),
    ∂E/∂l (into gl) and ∂E/∂r_i; the equator closed by mirror symmetry."""
    H0 = ref[2]
    gE, _, gl, gp, A = acc
    n = r.size - 1
    for i in range(1, n):
        L = 0.5 * (l[i - 1] + l[i])
        A[i] = 2.0 * np.pi * r[i] * L
        if B > 0.0:
            pb = 0.5 * (psi[i] + psi[i - 1])
            k1 = (psi[i] - psi[i - 1]) / L
            k2 = np.sin(pb) / r[i]
            d = 0.5 * (k1 + k2) - H0[i]
            q = 2.0 * B * 2.0 * d * A[i] * 0.5          # ∂e_i/∂(κ1 + κ2)
            cb = np.cos(pb) * 0.5 / r[i]
            gp[i] += q * (1.0 / L + cb)
            gp[i - 1] += q * (-1.0 / L + cb)
            dl = q * (-k1 * 0.5 / L) + 2.0 * B * d * d * np.pi * r[i]
            gl[i] += dl
            gl[i - 1] += dl
            gE[i, 0] += q * (-k2 / r[i]) + 2.0 * B * d * d * 2.0 * np.pi * L
    A[n] = np.pi * r[n] * l[n - 1]
    if B > 0.0:
        L = l[n - 1]
        k1 = (np.pi - 2.0 * psi[n - 1]) / L
        k2 = 1.0 / r[n]
        d = 0.5 * (k1 + k2) - H0[n]
        q = 2.0 * B * 2.0 * d * A[n] * 0.5
        gp[n - 1] += q * (-2.0 / L)
        gl[n - 1] += q * (-k1 / L) + 2.0 * B * d * d * np.pi * r[n]
        gE[n, 0] += q * (-k2 / r[n]) + 2.0 * B * d * d * np.pi * L


@njit(cache=True)
def _chain(r, z, l, acc):
    """∂E/∂l_j and ∂E/∂ψ_j through the element's end nodes onto gE."""
    gE, _, gl, gp, _ = acc
    for j in range(r.size - 1):
        dr = r[j + 1] - r[j]
        dzz = z[j + 1] - z[j]
        ll = l[j] * l[j]
        fr = gl[j] * dr / l[j] + gp[j] * dzz / ll
        fz = gl[j] * dzz / l[j] - gp[j] * dr / ll
        gE[j + 1, 0] += fr
        gE[j + 1, 1] += fz
        gE[j, 0] -= fr
        gE[j, 1] -= fz


@njit(cache=True)
def gradients(r: npt.NDArray[np.float64], z: npt.NDArray[np.float64], ref: Reference, mat: Material, gE: npt.NDArray[np.float64], gV: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """Fill gE (N+1, 2) with ∂E/∂(r, z) and gV with ∂(V/2)/∂(r, z); returns the
    nodal areas A_i (half node at the equator, π (l_0/2)² at the pole)."""
    n = r.size - 1
    l, psi = elements(r, z)
    gE[:, :] = 0.0
    gV[:, :] = 0.0
    acc = (gE, gV, np.zeros(n), np.zeros(n), np.empty(n + 1))   # + ∂E/∂l_j, ∂E/∂ψ_j, A_i
    acc[4][0] = np.pi * (0.5 * l[0]) ** 2
    _stretch_and_volume(r, z, l, ref, mat, acc)
    _bending_and_areas(r, l, psi, ref, mat[3], acc)
    _chain(r, z, l, acc)
    return acc[4]


@njit(cache=True)
def plate_force(kind: npt.NDArray[np.int64], gE: npt.NDArray[np.float64], gV: npt.NDArray[np.float64], p: float) -> float:
    """F_tot: the z-forces -∂E/∂z + p ∂V/∂z on the nodes held by the plate, which
    the plate balances (nN, pushing the plate outward when positive)."""
    F = 0.0
    for i in range(kind.size):
        if kind[i] == PLATE or kind[i] == POLE:
            F += -gE[i, 1] + p * gV[i, 1]
    return F


@njit(cache=True)
def plate_height(t: float, run: Run) -> float:
    """h(t) = h0 - (Δh/2)(1 - cos(π t / t_comp)) until t_comp, then h1 = h0 - Δh."""
    return run.h0 - 0.5 * run.dh * (1.0 - np.cos(np.pi * min(t, run.t_comp) / run.t_comp))


@njit(cache=True)
def _pressure(kind, gE, gV, A, dV, run):
    """The p that makes the step change the half volume by dV (µm³): from
    Σ ∂V/∂x · dt μ (p ∂V/∂x - ∂E/∂x)/A = dV over the nodes free to move
    (r of all but the pole, z of the free nodes)."""
    num = 0.0
    den = 0.0
    for i in range(kind.size):
        if kind[i] != POLE:
            num += gV[i, 0] * gE[i, 0] / A[i]
            den += gV[i, 0] * gV[i, 0] / A[i]
        if kind[i] == FREE:
            num += gV[i, 1] * gE[i, 1] / A[i]
            den += gV[i, 1] * gV[i, 1] / A[i]
    return (dV / (run.mu * run.dt) + num) / den


@njit(cache=True)
def _move(nodes, forces, p, h, run):
    """One explicit step v = μ f / A of nodes = (r, z, kind), in place, at the
    plate height h, forces = (∂E/∂x, ∂(V/2)/∂x, A): nodes crossing the plate
    are put on it, plate nodes the plate would have to pull lift off."""
    r, z, kind = nodes
    gE, gV, A = forces
    for i in range(kind.size):
        if kind[i] == POLE:
            z[i] = 0.5 * h
            continue
        r[i] += run.dt * run.mu * (-gE[i, 0] + p * gV[i, 0]) / A[i]
        if kind[i] == FREE:
            z[i] += run.dt * run.mu * (-gE[i, 1] + p * gV[i, 1]) / A[i]
            if z[i] >= 0.5 * h:
                z[i] = 0.5 * h
                kind[i] = PLATE
        elif kind[i] == PLATE:
            z[i] = 0.5 * h
            if -gE[i, 1] + p * gV[i, 1] < -run.release_tol * p * A[i]:
                kind[i] = FREE      # the plate would have to pull: the node lifts off


@njit(cache=True)
def _residual(kind, gE, gV, A, p):
    """max |f|/A over the free nodes (mN/m/µm)."""
    res = 0.0
    for i in range(kind.size):
        if kind[i] == FREE:
            fr = (-gE[i, 0] + p * gV[i, 0]) / A[i]
            fz = (-gE[i, 1] + p * gV[i, 1]) / A[i]
            res = max(res, np.sqrt(fr * fr + fz * fz))
    return res


@njit(cache=True)
def flow(r: npt.NDArray[np.float64], z: npt.NDArray[np.float64], kind: npt.NDArray[np.int64], ref: Reference, mat: Material,
         run: Run) -> tuple[float, float, int, bool, float]:
    """Explicit gradient flow v_i = μ f_i / A_i with f = -∂E/∂x + p ∂V/∂x.

    p is the Lagrange multiplier that keeps dV/dt = (V0 - V)/(10 dt) (volume
    drift corrected every step). The plate (upper half: z = h(t)/2) moves as
    `plate_height`. Nodes crossing it are put on it and then move only in r
    (frictionless); the pole moves with the plate; the equator only in r.
    After t_comp, every `check_every` steps the plate force F is compared with
    its previous value: settled when |ΔF|/|F| per relaxation time `tau_relax`
    is below `tol`. Modifies r, z, kind in place.
    Returns (F, p, steps, settled, residual = max |f|/A over the free nodes)."""
    n = r.size
    gE = np.zeros((n, 2))
    gV = np.zeros((n, 2))
    F_prev, p, t, step, settled = np.nan, 0.0, 0.0, 0, False
    while step < run.max_steps:
        A = gradients(r, z, ref, mat, gE, gV)
        h_old = plate_height(t, run)
        t += run.dt
        h_new = plate_height(t, run)
        # the plate's motion changes V by the plate nodes' z motion
        dVplate = 0.0
        for i in range(n):
            if kind[i] == PLATE or kind[i] == POLE:
                dVplate += gV[i, 1] * 0.5 * (h_new - h_old)
        p = _pressure(kind, gE, gV, A, (run.V0half - half_volume(r, z)) / 10.0 - dVplate, run)
        _move((r, z, kind), (gE, gV, A), p, h_new, run)
        step += 1
        if t > run.t_comp and step % run.check_every == 0:
            F = plate_force(kind, gE, gV, p)
            if F_prev == F_prev:
                rate = abs(F - F_prev) / abs(F) * run.tau_relax / (run.check_every * run.dt)
                if rate < run.tol:
                    settled = True
                    break
            F_prev = F
    A = gradients(r, z, ref, mat, gE, gV)
    return plate_force(kind, gE, gV, p), p, step, settled, _residual(kind, gE, gV, A, p)
