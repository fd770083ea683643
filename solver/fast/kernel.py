"""The compiled evaluation of the fast solver's discrete Lagrangian.

The formulas are those of `solver.fast.lagrangian` (its docstring gives L; symbols
as in SPEC section 2), evaluated by numba-compiled loops over elements and
nodes instead of numpy arrays of (elements × 6 × 6) temporaries. Per element
e = (k, k+1), in the local unknowns (r_k, z_k, r_k+1, z_k+1, l, p):

    f_e = 4π [c_e r̄ ds + w(e1, e2) r̄0 dS] - 2 p V_e,
    V_e = π (z_k - z_k+1)(r_k² + r_k r_k+1 + r_k+1²)/3     (`solver.frustum`),

w(e1, e2) with the element's linear prestress term P_a (e1+e2) + P_s (e1-e2)
(`Terms.pa`, `Terms.ps`; zeros for the elastic shell, where adding them changes no bit),

through the intermediate quantities a = (ds, r̄, dS, r̄0) with Jacobian J:
∇f = (∂f/∂a) J and ∇²f = J^T (∂²f/∂a²) J + Σ ∂f/∂a ∇²a. Per free node k
(and, with half weight and the mirror symmetry θ_b = π - θ_a, the equator)
the bending term κ (H_k - H_d)² r_k ℓ_k, κ = 8π B, through
b = (θ_a, θ_b, ds_a, ds_b, r_k) the same way. Local gradients and Hessians
are added into the global gradient at the index arrays of `Lagrangian`
(index n: the plate height z_p, n + 1: a fixed coordinate) and into the
Newton matrix in the parts its solve uses: the band of the position block
(a node couples to its neighbours within two) and the l and p columns.

The floating-point operations are grouped differently from a numpy
evaluation of the same formulas: results agree with one to round-off.
"""

from collections import namedtuple

import numpy as np
import numpy.typing as npt

from solver.jit import njit

# what `evaluate` needs besides the state: per-element tension c_e, moduli,
# H_d, contact node k_c, the global indices of each element's (r, z, r, z, l, p)
# and each bending node's (r, z) × 3, and where each global index goes in the
# Newton matrix (`slot`: its column in the band, or L_SLOT, P_SLOT, NO_SLOT); per
# element a prestress linear in the strain, w += pa (e1+e2) + ps (e1-e2) (zero for the
# elastic shell; `solver.time_domain` carries a viscoelastic cortex's history in it)
Terms = namedtuple("Terms", "cten KB KS B Hd kc elem_idx bend_idx slot band pa ps")
L_SLOT, P_SLOT, NO_SLOT = -1, -2, -3
# per-element lengths and angles with their derivatives, and scratch buffers
# (allocated once per evaluation: small allocations would dominate)
_Work = namedtuple("_Work", "ds gds hds th gth hth g h J F T b gb hb Hi Hij Ai sl")


@njit(inline="always", error_model="numpy")
def _work(N):
    return _Work(np.empty(N), np.empty((N, 4)), np.empty((N, 4, 4)), np.zeros(N),
                 np.zeros((N, 4)), np.zeros((N, 4, 4)), np.empty(6), np.empty((6, 6)),
                 np.empty((5, 6)), np.empty((5, 5)), np.empty((5, 6)), np.empty(5), np.empty(5),
                 np.empty((5, 5)), np.empty(5), np.empty((5, 5)), np.empty(5), np.empty(6, np.int64))


@njit(inline="always", error_model="numpy")
def _block(h, e, p00, p01, p11):
    """h[e] = [[P, -P], [-P, P]] with the symmetric 2×2 P = [[p00, p01], [p01, p11]]."""
    for i in range(4):
        for j in range(4):
            p = p00 if (i % 2 == 0 and j % 2 == 0) else (p11 if (i % 2 == 1 and j % 2 == 1) else p01)
            h[e, i, j] = p if (i < 2) == (j < 2) else -p


@njit(inline="always", error_model="numpy")
def _length(dx, dy, g, h, e):
    """ds = |(dx, dy)|; fills g[e] (4,) and h[e] (4, 4), its gradient and
    Hessian in (x1, y1, x2, y2)."""
    d = np.hypot(dx, dy)
    tx, ty = dx / d, dy / d
    g[e, 0], g[e, 1], g[e, 2], g[e, 3] = -tx, -ty, tx, ty
    _block(h, e, (1.0 - tx * tx) / d, -tx * ty / d, (1.0 - ty * ty) / d)
    return d


@njit(inline="always", error_model="numpy")
def _angle(dr, dz, g, h, e):
    """θ = atan2(-dz, dr), the tangent angle to the plate; fills g[e] and h[e]."""
    q = dr * dr + dz * dz
    g[e, 0], g[e, 1], g[e, 2], g[e, 3] = -dz / q, dr / q, dz / q, -dr / q
    _block(h, e, -2.0 * dr * dz / q**2, (dr * dr - dz * dz) / q**2, 2.0 * dr * dz / q**2)
    return np.arctan2(-dz, dr)


@njit(inline="always", error_model="numpy")
def _couple(h, oi, oj, th, ds, ea, eb, c00, c01, c10, c11, mirror):
    """h[oi:oi+4, oj:oj+4] += P_a^T C P_b, and its transpose into h[oj:oj+4,
    oi:oi+4] if mirror, with P_e = [∇θ_e; ∇ds_e] (2 × 4) of elements a = ea,
    b = eb from th, ds and C = [[c00, c01], [c10, c11]]: a bending term's
    J^T (∂²f/∂b²) J over the angles and lengths of two elements."""
    for j in range(4):
        t0 = c00 * th[eb, j] + c01 * ds[eb, j]
        t1 = c10 * th[eb, j] + c11 * ds[eb, j]
        for i in range(4):
            v = th[ea, i] * t0 + ds[ea, i] * t1
            h[oi + i, oj + j] += v
            if mirror:
                h[oj + j, oi + i] += v


@njit(inline="always", error_model="numpy")
def _couple_r(h, o, th, ds, e, c0, c1):
    """h[o:o+4, 2] and h[2, o:o+4] += P_e^T (c0, c1): a bending term's coupling
    of the node's r (local index 2) with element e's angle and length."""
    for i in range(4):
        v = th[e, i] * c0 + ds[e, i] * c1
        h[o + i, 2] += v
        h[2, o + i] += v


@njit(inline="always", error_model="numpy")
def _bending(Hd, kappa, w, want_h):
    """κ (H - H_d)² r ℓ with H = (1/2)[(θ_b - θ_a)/ℓ + sin((θ_a+θ_b)/2)/r],
    ℓ = (ds_a + ds_b)/2, in b = (θ_a, θ_b, ds_a, ds_b, r) = w.b: the value;
    fills w.gb (5,) and, if want_h, w.hb (5, 5)."""
    ta, tb, da, db, r = w.b[0], w.b[1], w.b[2], w.b[3], w.b[4]
    g, h, Hi, Hij, Ai = w.gb, w.hb, w.Hi, w.Hij, w.Ai
    ell, D, m = 0.5 * (da + db), tb - ta, 0.5 * (ta + tb)
    s, c = np.sin(m), np.cos(m)
    u = 0.5 * (D / ell + s / r) - Hd
    A = r * ell
    Hi[0], Hi[1] = -0.5 / ell + 0.25 * c / r, 0.5 / ell + 0.25 * c / r
    Hi[2] = Hi[3] = -0.25 * D / ell**2
    Hi[4] = -0.5 * s / r**2
    Ai[0], Ai[1], Ai[2], Ai[3], Ai[4] = 0.0, 0.0, 0.5 * r, 0.5 * r, ell
    for i in range(5):
        g[i] = kappa * (2 * u * Hi[i] * A + (u * u) * Ai[i])
    if not want_h:
        return kappa * u * u * A
    _zero(Hij, 5, 5)
    for i in range(2):
        for j in range(2):
            Hij[i, j] = -0.125 * s / r
            Hij[2 + i, 2 + j] = 0.25 * D / ell**3
            Hij[i, 2 + j] = Hij[2 + j, i] = (1.0 - 2.0 * i) * 0.25 / ell**2
        Hij[i, 4] = Hij[4, i] = -0.25 * c / r**2
    Hij[4, 4] = s / r**3
    for i in range(5):
        for j in range(i, 5):           # symmetric: the upper triangle, mirrored
            aij = 0.5 if i >= 2 and j == 4 and i < 4 else 0.0
            h[i, j] = h[j, i] = kappa * (2 * Hi[i] * Hi[j] * A + 2 * (u * A) * Hij[i, j]
                                         + 2 * u * (Hi[i] * Ai[j] + Ai[i] * Hi[j]) + (u * u) * aij)
    return kappa * u * u * A


@njit(inline="always", error_model="numpy")
def _surface(e, x, ref, t, w, want_h):
    """Tension and stretching of element e: 4π [c_e r̄ ds + w r̄0 dS]; fills
    w.g (6,) and w.h (6, 6) with its derivatives (the p entries zero)."""
    r, z, p = x
    R, Z, Rl, Zl, Rll, Zll = ref
    gds, ge, he = w.gds, w.g, w.h
    ds = w.ds[e]
    dR, dZ = R[e + 1] - R[e], Z[e + 1] - Z[e]
    dS = np.hypot(dR, dZ)
    dRl, dZl = Rl[e + 1] - Rl[e], Zl[e + 1] - Zl[e]
    dS_l = (dR * dRl + dZ * dZl) / dS
    dS_ll = (dRl**2 + dZl**2 - dS_l**2) / dS + (dR * (Rll[e + 1] - Rll[e]) + dZ * (Zll[e + 1] - Zll[e])) / dS
    rm, r0m = 0.5 * (r[e + 1] + r[e]), 0.5 * (R[e + 1] + R[e])
    r0m_l, r0m_ll = 0.5 * (Rl[e + 1] + Rl[e]), 0.5 * (Rll[e + 1] + Rll[e])
    l1, l2 = ds / dS, rm / r0m
    e1, e2 = l1 - 1.0, l2 - 1.0
    KB, KS, c, pa, ps = t.KB, t.KS, t.cten[e], t.pa[e], t.ps[e]
    wv = 0.5 * KB * (e1 + e2) ** 2 + 0.5 * KS * (e1 - e2) ** 2 + (pa * (e1 + e2) + ps * (e1 - e2))
    w1 = KB * (e1 + e2) + KS * (e1 - e2) + (pa + ps)
    w2 = KB * (e1 + e2) - KS * (e1 - e2) + (pa - ps)
    wa, wb, k4 = KB + KS, KB - KS, 4.0 * np.pi
    fa0, fa1 = k4 * (c * rm + w1 * r0m), k4 * (c * ds + w2 * dS)
    fa2, fa3 = k4 * (r0m * (wv - w1 * l1)), k4 * (dS * (wv - w2 * l2))
    ge[0] = fa0 * gds[e, 0] + 0.5 * fa1
    ge[1] = fa0 * gds[e, 1]
    ge[2] = fa0 * gds[e, 2] + 0.5 * fa1
    ge[3] = fa0 * gds[e, 3]
    ge[4], ge[5] = fa2 * dS_l + fa3 * r0m_l, 0.0
    value = k4 * (c * rm * ds + wv * r0m * dS)
    if not want_h:
        return value
    # ∂²f/∂a² (symmetric, a = (ds, r̄, dS, r̄0)), then J^T (∂²f/∂a²) J written out:
    # J's rows are ∇ds (on the positions), m = ∇r̄ = (1/2, 0, 1/2, 0) and
    # dS_l, r̄0_l (on l), so the position block is F00 ∇ds∇ds^T + F01 (∇ds m^T
    # + m ∇ds^T) + F11 m m^T, plus the length's curvature times ∂f/∂ds
    F00, F01, F11 = k4 * (wa * r0m / dS), k4 * (c + wb), k4 * (wa * dS / r0m)
    F02, F03 = k4 * (-wa * l1 * r0m / dS), k4 * (w1 - wb * l2)
    F12, F13 = k4 * (w2 - wb * l1), k4 * (-wa * l2 * dS / r0m)
    F22, F23 = k4 * (wa * r0m * l1**2 / dS), k4 * (wv - w1 * l1 - w2 * l2 + wb * l1 * l2)
    F33 = k4 * (wa * dS * l2**2 / r0m)
    ul, vl = F02 * dS_l + F03 * r0m_l, F12 * dS_l + F13 * r0m_l
    for i in range(4):
        gi, mi = gds[e, i], 0.5 * (1 - i % 2)
        for j in range(4):
            gj, mj = gds[e, j], 0.5 * (1 - j % 2)
            he[i, j] = F00 * gi * gj + F01 * (gi * mj + mi * gj) + F11 * mi * mj + fa0 * w.hds[e, i, j]
        he[i, 4] = he[4, i] = gi * ul + mi * vl
        he[i, 5] = he[5, i] = 0.0
    he[4, 4] = (F22 * dS_l * dS_l + 2.0 * F23 * dS_l * r0m_l + F33 * r0m_l * r0m_l
                + fa2 * dS_ll + fa3 * r0m_ll)
    he[4, 5] = he[5, 4] = he[5, 5] = 0.0
    return value


@njit(inline="always", error_model="numpy")
def _volume(e, r, z, p, ge, he, want_h):
    """2 p V_e of element e (the term subtracted from L): returns it and
    subtracts its derivatives from ge and he (p entries: -2 ∂V_e)."""
    ra, rb, dz = r[e], r[e + 1], z[e] - z[e + 1]
    sq = rb**2 + rb * ra + ra**2
    vol = np.pi * dz * sq / 3.0
    s1, s2 = np.pi / 3.0 * (2 * ra + rb), np.pi / 3.0 * (ra + 2 * rb)
    gv0, gv1, gv2, gv3 = dz * s1, np.pi / 3.0 * sq, dz * s2, -(np.pi / 3.0 * sq)
    ge[0] -= 2.0 * p * gv0
    ge[1] -= 2.0 * p * gv1
    ge[2] -= 2.0 * p * gv2
    ge[3] -= 2.0 * p * gv3
    ge[5] = -2.0 * vol
    if want_h:
        zz = -2.0 * p * (dz * np.pi / 3.0)
        he[0, 0] += 2 * zz
        he[2, 2] += 2 * zz
        he[0, 2] += zz
        he[2, 0] += zz
        for a, b, v in ((0, 1, s1), (0, 3, -s1), (2, 1, s2), (2, 3, -s2)):
            he[a, b] -= 2.0 * p * v
            he[b, a] -= 2.0 * p * v
        he[0, 5] = he[5, 0] = -2.0 * gv0
        he[1, 5] = he[5, 1] = -2.0 * gv1
        he[2, 5] = he[5, 2] = -2.0 * gv2
        he[3, 5] = he[5, 3] = -2.0 * gv3
    return 2.0 * p * vol


@njit(inline="always", error_model="numpy")
def _add_block(h, factor, blocks, e, offset=0):
    """h[o:o+4, o:o+4] += factor × blocks[e] (4, 4)."""
    for i in range(4):
        for j in range(4):
            h[offset + i, offset + j] += factor * blocks[e, i, j]


@njit(inline="always", error_model="numpy")
def _zero(a, n, m):
    """a[:n, :m] = 0 (a loop: no array view is made)."""
    for i in range(n):
        for j in range(m):
            a[i, j] = 0.0


@njit(inline="always", error_model="numpy")
def _bend_node(k, r, t, w, want_h):
    """Bending at free node k between elements a = k-1 and b = k: its value;
    fills w.g (6,), w.h (6, 6) in (r_k-1, z_k-1, r_k, z_k, r_k+1, z_k+1)."""
    a = k - 1
    w.b[0], w.b[1], w.b[2], w.b[3], w.b[4] = w.th[a], w.th[k], w.ds[a], w.ds[k], r[k]
    value = _bending(t.Hd, 8.0 * np.pi * t.B, w, want_h)
    gb, gth, gds = w.gb, w.gth, w.gds
    for j in range(6):                  # Σ_i (∂f/∂b_i) ∇b_i: a's θ, ds on 0..3, b's on 2..5, r_k on 2
        v = 0.0
        if j < 4:
            v += gb[0] * gth[a, j]
        if j >= 2:
            v += gb[1] * gth[k, j - 2]
        if j < 4:
            v += gb[2] * gds[a, j]
        if j >= 2:
            v += gb[3] * gds[k, j - 2]
        if j == 2:
            v += gb[4]
        w.g[j] = v
    if want_h:                          # J^T (∂²f/∂b²) J block by block, J's structure used
        hb = w.hb
        _zero(w.h, 6, 6)
        _couple(w.h, 0, 0, gth, gds, a, a, hb[0, 0], hb[0, 2], hb[2, 0], hb[2, 2], False)
        _couple(w.h, 0, 2, gth, gds, a, k, hb[0, 1], hb[0, 3], hb[2, 1], hb[2, 3], True)
        _couple(w.h, 2, 2, gth, gds, k, k, hb[1, 1], hb[1, 3], hb[3, 1], hb[3, 3], False)
        _couple_r(w.h, 0, gth, gds, a, hb[0, 4], hb[2, 4])
        _couple_r(w.h, 2, gth, gds, k, hb[1, 4], hb[3, 4])
        w.h[2, 2] += hb[4, 4]
        _add_block(w.h, gb[0], w.hth, a)
        _add_block(w.h, gb[2], w.hds, a)
        _add_block(w.h, gb[1], w.hth, k, 2)
        _add_block(w.h, gb[3], w.hds, k, 2)
    return value


@njit(inline="always", error_model="numpy")
def _bend_equator(r, t, w, want_h):
    """Half the bending term at the equator node N, closed by mirror symmetry:
    b = M (θ, ds, r_N) = (θ, π - θ, ds, ds, r_N) of the last element e. Its
    value; fills w.g[:4], w.h[:4, :4] in element e's (r, z, r, z)."""
    e = r.size - 2
    w.b[0], w.b[1], w.b[2], w.b[3], w.b[4] = w.th[e], np.pi - w.th[e], w.ds[e], w.ds[e], r[e + 1]
    value = _bending(t.Hd, 8.0 * np.pi * t.B, w, want_h)
    qg, qh = w.gb, w.hb
    g0, g1, g2 = 0.5 * (qg[0] - qg[1]), 0.5 * (qg[2] + qg[3]), 0.5 * qg[4]
    Jq = w.J                                # its leading (3, 4)
    _zero(Jq, 3, 4)
    for j in range(4):
        Jq[0, j], Jq[1, j] = w.gth[e, j], w.gds[e, j]
    Jq[2, 2] = 1.0
    for j in range(4):
        w.g[j] = g0 * Jq[0, j] + g1 * Jq[1, j] + g2 * Jq[2, j]
    if want_h:
        M, h3 = w.T, w.F                    # M: (5, 3) in T's corner, h3: F's (3, 3)
        _zero(M, 5, 3)
        M[0, 0], M[1, 0], M[2, 1], M[3, 1], M[4, 2] = 1.0, -1.0, 1.0, 1.0, 1.0
        for i in range(3):
            for j in range(3):
                h3[i, j] = 0.0
                for a in range(5):
                    for b in range(5):
                        h3[i, j] += 0.5 * M[a, i] * qh[a, b] * M[b, j]
        _zero(w.h, 6, 6)
        _couple(w.h, 0, 0, w.gth, w.gds, e, e, h3[0, 0], h3[0, 1], h3[1, 0], h3[1, 1], False)
        _couple_r(w.h, 0, w.gth, w.gds, e, h3[0, 2], h3[1, 2])
        w.h[2, 2] += h3[2, 2]
        _add_block(w.h, g0, w.hth, e)
        _add_block(w.h, g1, w.hds, e)
    return 0.5 * value


@njit(inline="always", error_model="numpy")
def _scatter(grad, band, lp, idx, row, m, slot, bw, g, h, want_h, sl):
    """Add the local gradient g[:m] at the global indices idx[row, :m], and the local
    Hessian h into the Newton matrix (band, lp) (arrays, not the tuples
    of `evaluate`: each array handed to an inlined function costs a reference
    count): entries between positions into the band (LAPACK storage
    ab[bw + i - j, j] = A[i, j]), the columns of l and p into lp[0], lp[1];
    z_p and fixed rows (NO_SLOT) are dropped. sl: scratch for the m slots."""
    for a in range(m):
        I = idx[row, a]
        grad[I] += g[a]
        sl[a] = slot[I]
    if not want_h:
        return
    for a in range(m):
        I, si = idx[row, a], sl[a]
        if si == NO_SLOT:
            continue
        for b in range(m):
            sj = sl[b]
            if sj >= 0:
                if si >= 0:
                    band[bw + si - sj, sj] += h[a, b]
            elif sj == L_SLOT:
                lp[0, I] += h[a, b]
            elif sj == P_SLOT:
                lp[1, I] += h[a, b]


@njit(cache=True, error_model="numpy")
def evaluate(x: tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], float], ref: tuple[npt.NDArray[np.float64], ...], t: Terms, n: int,
             want_h: bool) -> tuple[float, npt.NDArray[np.float64], tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]]:
    """L - p V0 at x = (r, z, p) of all nodes, with ref = (r0, z0, dr0/dl,
    dz0/dl, d²r0/dl², d²z0/dl²) and the terms t, for n unknowns (the last two
    l and p); its gradient over the n + 2 global indices (+ z_p, + a fixed
    coordinate) and, if want_h, the Newton matrix (band, lp) of `_scatter`
    (band: (2 t.band + 1, n - 2), lp: (2, n); else empty)."""
    r, z, p = x
    N = r.size - 1
    k = n if want_h else 0
    grad, band, lp = np.zeros(n + 2), np.zeros((2 * t.band + 1, max(k - 2, 0))), np.zeros((2, k))
    w = _work(N)
    slot, g, h = t.slot, w.g, w.h
    for e in range(N):
        w.ds[e] = _length(r[e + 1] - r[e], z[e + 1] - z[e], w.gds, w.hds, e)
        if t.B > 0 and e >= t.kc:     # angles for bending only; on the plate θ = 0
            w.th[e] = _angle(r[e + 1] - r[e], z[e + 1] - z[e], w.gth, w.hth, e)
    value = 0.0
    for e in range(N):
        # tension, stretching and volume of element e: the value; fills
        # w.g (6,), w.h (6, 6) in (r_k, z_k, r_k+1, z_k+1, l, p)
        value += _surface(e, x, ref, t, w, want_h) - _volume(e, r, z, p, g, h, want_h)
        _scatter(grad, band, lp, t.elem_idx, e, 6, slot, t.band, g, h, want_h, w.sl)
    if t.B > 0:
        for k in range(t.kc, N):
            value += _bend_node(k, r, t, w, want_h)
            _scatter(grad, band, lp, t.bend_idx, k - t.kc, 6, slot, t.band, g, h, want_h, w.sl)
        value += _bend_equator(r, t, w, want_h)
        _scatter(grad, band, lp, t.elem_idx, N - 1, 4, slot, t.band, g, h, want_h, w.sl)
    return value, grad, (band, lp)
