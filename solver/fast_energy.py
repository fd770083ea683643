"""The fast solver's discrete Lagrangian with its exact gradient and Hessian.

Nodes run along the upper half meridian (mirror symmetry): the pole k = 0,
the plate nodes k ≤ k_c (z = z_p = h/2, sliding in r), the free nodes
(r, z unknown) and the equator k = N (z = 0). The unknowns are
u = (r_1..r_N, z_{k_c+1}..z_{N-1}, l = log ψ_c, p); the reference positions
(r0, z0) of the nodes depend on l (`solver.fast_mesh`).

Discrete Lagrangian of the whole cell (twice the half), elements e = (k, k+1):

    L = Σ_e 4π [c_e r̄_e ds_e + w(e1, e2) r̄0_e dS_e]           (tension, stretching)
      + Σ_k 8π B (H_k - H_d)² r_k ℓ_k                          (bending, free nodes)
      - p (2 Σ_e π (z_k - z_k+1)(r_k² + r_k r_k+1 + r_k+1²)/3 - V0)

with ds, dS the current and reference element lengths, r̄ and r̄0 the mid
radii, λ1 = ds/dS, λ2 = r̄/r̄0, e_i = λ_i - 1,
w = (K_B/2)(e1+e2)² + (K_S/2)(e1-e2)², and c_e = γ_a, plus 2 B H_d² on the
strip of material that has newly come onto the plate (reference curvature
H_d, now flat). At a free node H = (1/2)[(θ_b - θ_a)/ℓ + sin((θ_a+θ_b)/2)/r]
with θ the elements' tangent angles to the plate (zero on the plate),
ℓ = (ds_a + ds_b)/2; the equator closes by mirror symmetry (θ_b = π - θ_a,
half the dual area).

Every term is a function of a few intermediate quantities (lengths, mid
radii, angles), so its Hessian is the chain rule J^T (∂²f) J + Σ ∂f ∇²(a);
the formulas are written out below and checked against complex-step
differences in the tests. Energies in mN/m·µm² (= 1e-15 J), forces in nN.
"""

import numpy as np
from scipy.linalg import solve_banded

BAND = 5    # half-bandwidth of the position block in node order


def _length(dx, dy):
    """Length of (dx, dy) with gradient (4,) and Hessian (4, 4) in (x1, y1, x2, y2)."""
    d = np.hypot(dx, dy)
    tx, ty = dx / d, dy / d
    g = np.stack([-tx, -ty, tx, ty], axis=-1)
    P = np.empty(dx.shape + (2, 2))
    P[..., 0, 0], P[..., 1, 1] = (1 - tx * tx) / d, (1 - ty * ty) / d
    P[..., 0, 1] = P[..., 1, 0] = -tx * ty / d
    return d, g, np.block([[P, -P], [-P, P]])


def _angle(dr, dz):
    """θ = atan2(-dz, dr), the tangent angle to the plate, with gradient and Hessian."""
    q = dr * dr + dz * dz
    theta = np.arctan2(-dz, dr)
    g = np.stack([-dz / q, dr / q, dz / q, -dr / q], axis=-1)
    Q = np.empty(dr.shape + (2, 2))
    Q[..., 0, 0], Q[..., 1, 1] = -2 * dr * dz / q**2, 2 * dr * dz / q**2
    Q[..., 0, 1] = Q[..., 1, 0] = (dr * dr - dz * dz) / q**2
    return theta, g, np.block([[Q, -Q], [-Q, Q]])


def _bending(ta, tb, da, db, r, Hd, kappa):
    """g = κ (H - H_d)² r ℓ in b = (θ_a, θ_b, ds_a, ds_b, r): value, gradient, Hessian."""
    ell, D, m = 0.5 * (da + db), tb - ta, 0.5 * (ta + tb)
    s, c = np.sin(m), np.cos(m)
    u = 0.5 * (D / ell + s / r) - Hd
    A = r * ell
    n = len(r)
    Hi = np.stack([-0.5 / ell + 0.25 * c / r, 0.5 / ell + 0.25 * c / r,
                   -0.25 * D / ell**2, -0.25 * D / ell**2, -0.5 * s / r**2], axis=-1)
    Hij = np.zeros((n, 5, 5))
    Hij[:, :2, :2] = (-0.125 * s / r)[:, None, None]
    for i, sign in ((0, 1.0), (1, -1.0)):
        Hij[:, i, 2:4] = Hij[:, 2:4, i] = (sign * 0.25 / ell**2)[:, None]
        Hij[:, i, 4] = Hij[:, 4, i] = -0.25 * c / r**2
    Hij[:, 2:4, 2:4] = (0.25 * D / ell**3)[:, None, None]
    Hij[:, 4, 4] = s / r**3
    Ai = np.zeros((n, 5))
    Ai[:, 2] = Ai[:, 3] = 0.5 * r
    Ai[:, 4] = ell
    Aij = np.zeros((n, 5, 5))
    Aij[:, 2:4, 4] = Aij[:, 4, 2:4] = 0.5
    value = kappa * u * u * A
    grad = kappa * (2 * u[:, None] * Hi * A[:, None] + (u * u)[:, None] * Ai)
    outer = Hi[:, :, None] * Ai[:, None, :]
    hess = kappa * (2 * Hi[:, :, None] * Hi[:, None, :] * A[:, None, None]
                    + 2 * (u * A)[:, None, None] * Hij
                    + 2 * u[:, None, None] * (outer + outer.transpose(0, 2, 1))
                    + (u * u)[:, None, None] * Aij)
    return value, grad, hess


class Lagrangian:
    """L(u; z_p) of one shell on one reference mesh, with exact derivatives."""

    def __init__(self, shell, ref, regularisation=1e-3):
        self.ref = ref
        reg = regularisation * shell.tension_mN_per_m
        self.KB = shell.bulk_mN_per_m + reg
        self.KS = shell.shear_mN_per_m + reg
        self.gamma = shell.tension_mN_per_m
        self.B = shell.bending_stiffness
        self.nd, self.nn, self.nf = len(ref.eta), len(ref.zeta), len(ref.xi)
        self.kc = self.nd + self.nn                 # contact node
        self.N = N = self.kc + self.nf              # equator node
        self.nr, self.nz = N, self.nf - 1
        self.size = n = self.nr + self.nz + 2       # + l, p
        self.V0 = None
        # where each node coordinate goes: an unknown, the plate height (n), or nowhere (n + 1)
        k = np.arange(N + 1)
        self.ridx = np.where(k >= 1, k - 1, n + 1)
        self.zidx = np.where(k <= self.kc, n, np.where(k < N, N + k - self.kc - 1, n + 1))
        e = np.arange(N)
        lp = np.full(N, n - 2), np.full(N, n - 1)
        self.elem_idx = np.stack([self.ridx[e], self.zidx[e], self.ridx[e + 1], self.zidx[e + 1],
                                  *lp], axis=1)
        self.cten = np.full(N, float(self.gamma))
        self.cten[self.nd: self.kc] += 2.0 * self.B * ref.H**2
        kb = np.arange(self.kc, N)
        self.bend_nodes = kb
        self.bend_idx = np.stack([self.ridx[kb - 1], self.zidx[kb - 1], self.ridx[kb],
                                  self.zidx[kb], self.ridx[kb + 1], self.zidx[kb + 1]], axis=1)
        self.eq_idx = np.array([self.ridx[N - 1], self.zidx[N - 1], self.ridx[N], self.zidx[N]])
        # node-by-node order of the position unknowns: the Newton matrix is then banded
        k = np.arange(1, N + 1)
        zk = np.where((k > self.kc) & (k < N), N + k - self.kc - 1, -1)
        order = np.stack([k - 1, zk], axis=1).ravel()
        self.band_order = o = order[order >= 0]
        # LAPACK band storage: ab[BAND + i - j, j] = A[i, j]
        d, j = np.meshgrid(np.arange(-BAND, BAND + 1), np.arange(len(o)), indexing="ij")
        i = j + d
        self.band_mask = (i >= 0) & (i < len(o))
        i = np.clip(i, 0, len(o) - 1)
        self.band_rows, self.band_cols = o[i], o[j]
        self.elastic = shell.bulk_mN_per_m + shell.shear_mN_per_m > 0.0
        # natural size of a nodal force: tension times a typical element length
        self.force_scale = (self.gamma + self.KB + self.KS) * ref.a0 * 0.1

    def solve(self, H, rhs):
        """Solve the Newton system for the positions and p at fixed l:
        [A b; b^T 0] [x; y] = rhs, with A (positions) banded (a node couples
        to its neighbours within two) and b = ∂²L/∂x∂p, by block elimination."""
        o, n = self.band_order, self.size
        ab = np.where(self.band_mask, H[self.band_rows, self.band_cols], 0.0)
        rhs = np.asarray(rhs, dtype=float).reshape(n - 1, -1)
        b = H[o, n - 1]
        X = solve_banded((BAND, BAND), ab, np.column_stack([rhs[o], b]),
                         overwrite_ab=True, check_finite=False)
        xf, xb = X[:, :-1], X[:, -1]
        y = (b @ xf - rhs[-1]) / (b @ xb)
        out = np.empty_like(rhs)
        out[o] = xf - np.outer(xb, y)
        out[-1] = y
        return out

    def nodes(self, u, zp):
        """(r, z) of every node, ψ_c and p from the unknowns."""
        N, kc = self.N, self.kc
        r = np.concatenate([[0.0], u[:N]])
        z = np.empty(N + 1)
        z[: kc + 1] = zp
        z[kc + 1: N] = u[N: N + self.nz]
        z[N] = 0.0
        return r, z, np.exp(u[-2]), u[-1]

    def volume(self, u, zp):
        r, z = self.nodes(u, zp)[:2]
        return 2.0 * np.sum(np.pi * (-np.diff(z)) * (r[1:] ** 2 + r[1:] * r[:-1] + r[:-1] ** 2) / 3.0)

    def area(self, u, zp):
        r, z = self.nodes(u, zp)[:2]
        return 2.0 * np.sum(np.pi * (r[1:] + r[:-1]) * np.hypot(np.diff(r), np.diff(z)))

    def evaluate(self, u, zp, hessian=True):
        """L, ∇L (size), ∂L/∂z_p, and the Hessian (size × size) if asked."""
        n = self.size
        r, z, _, p = self.nodes(u, zp)
        R, Z, Rl, Zl, Rll, Zll = self.ref.positions(u[-2])
        # -- tension and stretching, per element, in (r1, z1, r2, z2, l, p)
        ds, gds, hds = _length(np.diff(r), np.diff(z))
        dR, dZ = np.diff(R), np.diff(Z)
        dS = np.hypot(dR, dZ)
        dRl, dZl = np.diff(Rl), np.diff(Zl)
        dS_l = (dR * dRl + dZ * dZl) / dS
        dS_ll = (dRl**2 + dZl**2 - dS_l**2) / dS + (dR * np.diff(Rll) + dZ * np.diff(Zll)) / dS
        rm, r0m = 0.5 * (r[1:] + r[:-1]), 0.5 * (R[1:] + R[:-1])
        r0m_l, r0m_ll = 0.5 * (Rl[1:] + Rl[:-1]), 0.5 * (Rll[1:] + Rll[:-1])
        l1, l2 = ds / dS, rm / r0m
        e1, e2 = l1 - 1.0, l2 - 1.0
        KB, KS, c = self.KB, self.KS, self.cten
        w = 0.5 * KB * (e1 + e2) ** 2 + 0.5 * KS * (e1 - e2) ** 2
        w1 = KB * (e1 + e2) + KS * (e1 - e2)
        w2 = KB * (e1 + e2) - KS * (e1 - e2)
        wa, wb = KB + KS, KB - KS                      # w11 = w22, w12
        k4 = 4.0 * np.pi
        f = k4 * (c * rm * ds + w * r0m * dS)
        fa = k4 * np.stack([c * rm + w1 * r0m, c * ds + w2 * dS,
                            r0m * (w - w1 * l1), dS * (w - w2 * l2)], axis=-1)
        J = np.zeros((self.N, 4, 6))
        J[:, 0, :4] = gds
        J[:, 1, 0] = J[:, 1, 2] = 0.5
        J[:, 2, 4], J[:, 3, 4] = dS_l, r0m_l
        vol = np.pi * (z[:-1] - z[1:]) * (r[1:] ** 2 + r[1:] * r[:-1] + r[:-1] ** 2) / 3.0
        gvol = np.pi / 3.0 * np.stack([(z[:-1] - z[1:]) * (2 * r[:-1] + r[1:]),
                                       r[1:] ** 2 + r[1:] * r[:-1] + r[:-1] ** 2,
                                       (z[:-1] - z[1:]) * (r[:-1] + 2 * r[1:]),
                                       -(r[1:] ** 2 + r[1:] * r[:-1] + r[:-1] ** 2)], axis=-1)
        ge = (fa[:, None, :] @ J)[:, 0]
        ge[:, :4] -= 2.0 * p * gvol
        ge[:, 5] = -2.0 * vol
        value = f.sum() - 2.0 * p * vol.sum() + p * self.V0
        # -- bending at the free nodes and the equator
        if self.B > 0:
            kappa, Hd = 8.0 * np.pi * self.B, self.ref.H
            theta, gth, hth = _angle(np.diff(r), np.diff(z))
            plate = np.arange(self.N) < self.kc
            theta[plate], gth[plate], hth[plate] = 0.0, 0.0, 0.0
            kb = self.bend_nodes
            a, b = kb - 1, kb
            gb_val, gb, hb = _bending(theta[a], theta[b], ds[a], ds[b], r[kb], Hd, kappa)
            Jb = np.zeros((len(kb), 5, 6))
            Jb[:, 0, :4], Jb[:, 1, 2:] = gth[a], gth[b]
            Jb[:, 2, :4], Jb[:, 3, 2:] = gds[a], gds[b]
            Jb[:, 4, 2] = 1.0
            gbend = (gb[:, None, :] @ Jb)[:, 0]
            # equator: b = (θ, π - θ, ds, ds, r_N), half the dual area
            e = self.N - 1
            q_val, q_g, q_h = _bending(theta[e:], np.pi - theta[e:], ds[e:], ds[e:], r[-1:], Hd, kappa)
            M = np.array([[1.0, 0, 0], [-1.0, 0, 0], [0, 1.0, 0], [0, 1.0, 0], [0, 0, 1.0]])
            g3, h3 = 0.5 * q_g[0] @ M, 0.5 * M.T @ q_h[0] @ M
            Jq = np.zeros((3, 4))
            Jq[0], Jq[1], Jq[2, 2] = gth[e], gds[e], 1.0
            value += gb_val.sum() + 0.5 * q_val[0]
        # -- gradient
        grad = np.bincount(self.elem_idx.ravel(), ge.ravel(), minlength=n + 2)
        if self.B > 0:
            grad += np.bincount(self.bend_idx.ravel(), gbend.ravel(), minlength=n + 2)
            grad += np.bincount(self.eq_idx, g3 @ Jq, minlength=n + 2)
        grad[n - 1] += self.V0
        dzp = grad[n]
        grad = grad[:n]
        if not hessian:
            return value, grad, dzp, None
        # -- Hessian: J^T f'' J + Σ f' ∇²a (+ volume and p terms)
        F = np.empty((self.N, 4, 4))
        F[:, 0, 0] = wa * r0m / dS
        F[:, 0, 1] = F[:, 1, 0] = c + wb
        F[:, 0, 2] = F[:, 2, 0] = -wa * l1 * r0m / dS
        F[:, 0, 3] = F[:, 3, 0] = w1 - wb * l2
        F[:, 1, 1] = wa * dS / r0m
        F[:, 1, 2] = F[:, 2, 1] = w2 - wb * l1
        F[:, 1, 3] = F[:, 3, 1] = -wa * l2 * dS / r0m
        F[:, 2, 2] = wa * r0m * l1**2 / dS
        F[:, 2, 3] = F[:, 3, 2] = w - w1 * l1 - w2 * l2 + wb * l1 * l2
        F[:, 3, 3] = wa * dS * l2**2 / r0m
        He = J.transpose(0, 2, 1) @ (k4 * F) @ J
        He[:, :4, :4] += fa[:, 0, None, None] * hds
        He[:, 4, 4] += fa[:, 2] * dS_ll + fa[:, 3] * r0m_ll
        zz = (z[:-1] - z[1:]) * np.pi / 3.0
        hv = np.zeros((self.N, 4, 4))
        hv[:, 0, 0], hv[:, 2, 2] = 2 * zz, 2 * zz
        hv[:, 0, 2] = hv[:, 2, 0] = zz
        hv[:, 0, 1] = hv[:, 1, 0] = np.pi / 3.0 * (2 * r[:-1] + r[1:])
        hv[:, 0, 3] = hv[:, 3, 0] = -np.pi / 3.0 * (2 * r[:-1] + r[1:])
        hv[:, 2, 1] = hv[:, 1, 2] = np.pi / 3.0 * (r[:-1] + 2 * r[1:])
        hv[:, 2, 3] = hv[:, 3, 2] = -np.pi / 3.0 * (r[:-1] + 2 * r[1:])
        He[:, :4, :4] -= 2.0 * p * hv
        He[:, :4, 5] = He[:, 5, :4] = -2.0 * gvol
        m = n + 2
        flat = (self.elem_idx[:, :, None] * m + self.elem_idx[:, None, :]).ravel()
        Hm = np.bincount(flat, He.ravel(), minlength=m * m)
        if self.B > 0:
            Hb = Jb.transpose(0, 2, 1) @ hb @ Jb
            Hb[:, :4, :4] += gb[:, 0, None, None] * hth[a] + gb[:, 2, None, None] * hds[a]
            Hb[:, 2:, 2:] += gb[:, 1, None, None] * hth[b] + gb[:, 3, None, None] * hds[b]
            flat = (self.bend_idx[:, :, None] * m + self.bend_idx[:, None, :]).ravel()
            Hm += np.bincount(flat, Hb.ravel(), minlength=m * m)
            Hq = Jq.T @ h3 @ Jq + g3[0] * hth[e] + g3[1] * hds[e]
            flat = (self.eq_idx[:, None] * m + self.eq_idx[None, :]).ravel()
            Hm += np.bincount(flat, Hq.ravel(), minlength=m * m)
        return value, grad, dzp, Hm.reshape(m, m)[:n, :n]
