"""The fast solver's contact search, compiled: the admissible local minimum of E*(l).

E*(l) is the equilibrium energy at fixed contact label l = log ψ_c (the
Newton iteration of `solver.fast.newton`), G(l) = dE*/dl = g_l (g_x = 0 at
equilibrium) and, by the Schur complement,

    dx/dl = -H_xx⁻¹ h_xl,   k = dG/dl = H_ll + h_xl · dx/dl.

Safeguarded Newton on G = 0 with steps at most TRUST_L inside a bracket
[lo, hi]: a root lies above any l with G < 0 or whose equilibrium crosses
the plate (gap = max z_free - z_p > 0), below any l with G > 0. E* is very
flat in l (the contact is set by bending and stretching near the contact
line only), hence the bracket. At l = log ψ_min with G > 0 the contact
cannot shrink further: that bound is the answer. Where the bracket closes
(to TOL_L) between a label whose free surface crosses the plate and one with
G > 0, the admissible minimum is the label at which the free surface
touches the plate (the secant of the gap through the last two labels above
it), and that is the answer. Each new label starts from the last
equilibrium moved along its tangent dx/dl (kept only if that leaves the
admissible shapes). With `retreat`, a label at which Newton's method fails
is not the end: the next label is halfway back to the last one it solved
(until they are TOL_L apart), so a trust step too long for the iteration
is shortened instead of failing the search (the continuation of
`solver.fast.advance` asks for that; a single compression does not). With
`predict`, the first label held by the plate (below it, G > 0) does not step
further down than the label its tangent predicts to touch (the gap moved
along dx/dl, `_touch_predicted`), nor less than TOL_L/2: where the start is
already near the touching label (a time step's, continued from the last)
that ends the search in 2-3 labels instead of a bisection of the bracket's
TRUST_L (~log2(TRUST_L/TOL_L) labels); the answer is the same touching
label to TOL_L. The time-domain shell asks for it; the elastic tables were
built without it and keep that search.

A stored history (`solver.time_domain`: the prestress P_a, P_s of each element, linear in its
strain, sampled at the material labels ψ0 of the elements from the disc's edge on) moves with
the material: at every label l the elements' P are read off it at their mid-labels ψ̄0_e(l)
(`carry_history`: the cubic Hermite interpolant in ψ0 with the slopes of the parabolas through
three samples, continued along the end's tangent, so that P and dP/dψ0 are continuous in l; the
samples sit at the mid-labels of the label the history was carried to, next to the answer, where
a linear P would have its kinks; written here, not scipy's CubicHermiteSpline, because it is
evaluated inside the compiled search, where no scipy object can be called), and the history's
share of dE*/dl,

    G_hist = Σ_e 4π r̄0_e dS_e [(e1+e2)_e dP_a/dψ0 + (e1-e2)_e dP_s/dψ0] dψ̄0_e/dl,

joins G (`history_share`); k is then the secant of G through the last two labels solved where
that is positive (the history's share of k is left out of the tangent), else the tangent's. The
history's share nearly cancels the elastic one: G is small down to the touching label, and can
have a root (a minimum of E*) next to the start besides the touching label below it. So the
first label solved below the plate steps FIRST_STEP_L towards -G (the secant then sees the
nearby root, and the answer is the minimum the start lies next to, continuous in the cell's
parameters), and after it a step towards a side not yet bracketed is at least OPEN_STEP_L. A
search still going after CRAWL_AFTER labels with a bracket closed on both sides (a secant crawling
along one end of it where G is nearly flat) shrinks it by at least SHRINK of its width a label,
and closed to TOL_L below the plate its label is the answer (G's root there, or where G changes
sign). With no history (empty arrays: the elastic solver) nothing changes.

The loop is compiled whole; h_xl · dx/dl is summed in index order. `contact`
returns a status, which `solver.fast` turns into its errors.
"""

import numpy as np
import numpy.typing as npt

from solver.fast.kernel import Terms
from solver.fast.mesh import label_positions
from solver.fast.newton import CONVERGED, block_solve, newton, nodes, shape_ok
from solver.jit import njit

LOG_PSI_MIN = np.log(2e-3)   # least contact label (≈ 8 nm of material rolled on)
LOG_PSI_MAX = np.log(1.4)    # at most 1.4 rad of the free surface on the plate (< π/2: the equator stays free)
TRUST_L = 0.3                # largest change of l = log ψ_c in one Newton step
TOL_L = 1e-3                 # bracket width at which the touching label is accepted
OPEN_STEP_L = 0.1            # with a history: the least step of l towards a side not yet bracketed
FIRST_STEP_L = 0.01          # with a history: the step of l from the first label solved below the plate
SHRINK = 0.25               # with a history, after CRAWL_AFTER labels: a closed bracket shrinks by this share a label
CRAWL_AFTER = 12             # with a history: labels solved before a closed bracket is made to shrink
PROBE_L = 0.02               # the tangent's probe of the gap's slope dgap/dl (`_touch_predicted`)

# `contact`'s status beside `newton.newton`'s SINGULAR, REJECTED and NOT_CONVERGED (1-3)
FOUND, TANGENT_SINGULAR, NO_CONTACT = 0, 4, 5
HELD = 1                     # `contact`'s `last` with FOUND: the answer is the touching label


@njit(cache=True)
def gap(u: npt.NDArray[np.float64], zp: float, N: int, kc: int) -> float:
    """How far the free surface rises above the plate (µm; > 0: it crosses)."""
    z = nodes(u, zp, N, kc)[1]
    return np.max(z[kc + 1:]) - zp * (1.0 + 1e-9)


@njit(cache=True)
def node_labels(l, zeta, xi):
    """ψ0 and dψ0/dl of the nodes from the disc's edge on at contact label l (`solver.fast.mesh`)."""
    psic, nn = np.exp(l), zeta.size
    psi, dpsi = np.zeros(1 + nn + xi.size), np.zeros(1 + nn + xi.size)
    for j in range(nn):
        psi[1 + j] = dpsi[1 + j] = psic * zeta[j]
    for j in range(xi.size):
        psi[1 + nn + j] = psic + (0.5 * np.pi - psic) * xi[j]
        dpsi[1 + nn + j] = psic * (1.0 - xi[j])
    return psi, dpsi


@njit(cache=True)
def hermite_slopes(at, v):
    """dv/dψ0 at the samples: the slope of the parabola through each sample and its two
    neighbours (the one-sided secant at the ends), linear in v (`carry_history`)."""
    n = at.size
    d = np.zeros(n)
    if n < 2:
        return d
    d[0] = (v[1] - v[0]) / (at[1] - at[0])
    d[n - 1] = (v[n - 1] - v[n - 2]) / (at[n - 1] - at[n - 2])
    for i in range(1, n - 1):
        h0, h1 = at[i] - at[i - 1], at[i + 1] - at[i]
        s0, s1 = (v[i] - v[i - 1]) / h0, (v[i + 1] - v[i]) / h1
        d[i] = (h1 * s0 + h0 * s1) / (h0 + h1)
    return d


@njit(cache=True)
def _hermite(at, v, d, x):
    """(v, dv/dψ0) at x: the cubic Hermite interpolant of v with slopes d at the samples `at`
    (C¹ in x), continued along the end's tangent beyond the samples."""
    n = at.size
    if n == 1:
        return v[0], 0.0
    if x <= at[0]:
        return v[0] + d[0] * (x - at[0]), d[0]
    if x >= at[n - 1]:
        return v[n - 1] + d[n - 1] * (x - at[n - 1]), d[n - 1]
    i = np.searchsorted(at, x)
    w = at[i] - at[i - 1]
    t = (x - at[i - 1]) / w
    t2, t3 = t * t, t * t * t
    value = ((2 * t3 - 3 * t2 + 1) * v[i - 1] + (t3 - 2 * t2 + t) * w * d[i - 1]
             + (-2 * t3 + 3 * t2) * v[i] + (t3 - t2) * w * d[i])
    slope = ((6 * t2 - 6 * t) * (v[i - 1] - v[i]) / w + (3 * t2 - 4 * t + 1) * d[i - 1]
             + (3 * t2 - 2 * t) * d[i])
    return value, slope


@njit(cache=True)
def carry_history(l: float, zeta: npt.NDArray[np.float64], xi: npt.NDArray[np.float64],
                  history: tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64]],
                  terms: Terms) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """Set terms.pa, terms.ps of the elements from the disc's edge on to the history
    (ψ̄0 samples, P_a, P_s) at their mid-labels at contact label l, C¹ in ψ0 (the cubic Hermite
    interpolant with `hermite_slopes`, continued along the end's tangent beyond the samples); return
    dP_a/dl, dP_s/dl of those elements."""
    at, pa0, ps0 = history
    psi, dpsi = node_labels(l, zeta, xi)
    m, nd = psi.size - 1, terms.kc - zeta.size
    dpa, dps = np.zeros(m), np.zeros(m)
    da, ds = hermite_slopes(at, pa0), hermite_slopes(at, ps0)
    for e in range(m):
        x = 0.5 * (psi[e] + psi[e + 1])
        dx = 0.5 * (dpsi[e] + dpsi[e + 1])
        terms.pa[nd + e], sa = _hermite(at, pa0, da, x)
        terms.ps[nd + e], ss = _hermite(at, ps0, ds, x)
        dpa[e], dps[e] = sa * dx, ss * dx
    return dpa, dps


@njit(cache=True)
def history_share(u: npt.NDArray[np.float64], zp: float, r0: npt.NDArray[np.float64],
                  z0: npt.NDArray[np.float64], N: int, kc: int, nd: int,
                  dpa: npt.NDArray[np.float64], dps: npt.NDArray[np.float64]) -> float:
    """G_hist (module docstring) at the unknowns u, reference nodes (r0, z0) of u's label, with
    the elements' dP/dl from the disc's edge (element nd) on (mN/m·µm²)."""
    r, z = nodes(u, zp, N, kc)
    G = 0.0
    for e in range(dpa.size):
        k = nd + e
        ds, dS = np.hypot(r[k + 1] - r[k], z[k + 1] - z[k]), np.hypot(r0[k + 1] - r0[k], z0[k + 1] - z0[k])
        rm, r0m = 0.5 * (r[k + 1] + r[k]), 0.5 * (r0[k + 1] + r0[k])
        e1, e2 = ds / dS - 1.0, rm / r0m - 1.0
        G += 4.0 * np.pi * r0m * dS * ((e1 + e2) * dpa[e] + (e1 - e2) * dps[e])
    return G


@njit(cache=True)
def _tangent(g, band, lp, order, keep, bw):
    """(G, k, dx/dl, info) at an equilibrium of fixed l (module docstring)."""
    n = g.size
    rhs = np.empty((n - 1, 1))
    for i in range(n - 1):
        rhs[i, 0] = lp[0][keep[i]]
    sol, info = block_solve(band, lp[1], order, bw, rhs)
    tangent = np.empty(n - 1)
    k = 0.0
    for i in range(n - 1):
        tangent[i] = -sol[i, 0]
        k += rhs[i, 0] * tangent[i]
    return g[n - 2], lp[0][n - 2] + k, tangent, info


@njit(cache=True)
def _moved(u, zp, N, kc, keep, tangent, target):
    """A copy of u at the label `target`, its other unknowns moved along
    `tangent` (None-like: empty, not moved) unless that leaves the admissible shapes."""
    u, l = u.copy(), u[-2]
    if tangent.size:
        for i in range(keep.size):
            u[keep[i]] += tangent[i] * (target - l)
        r, z = nodes(u, zp, N, kc)
        if not (np.all(np.isfinite(u)) and shape_ok(r, z, kc)):
            for i in range(keep.size):
                u[keep[i]] -= tangent[i] * (target - l)
    u[-2] = target
    return u


@njit(cache=True)
def _touch_predicted(u, zp, N, kc, keep, tangent, above):
    """The label at which the free surface would touch the plate, l - gap/(dgap/dl), the gap's
    slope that of u moved along its tangent by -PROBE_L (the linear prediction); -inf where the
    tangent does not raise the gap (no prediction)."""
    l = u[-2]
    slope = (gap(_moved(u, zp, N, kc, keep, tangent, l - PROBE_L), zp, N, kc) - above) / -PROBE_L
    return l - above / slope if slope < 0 else -np.inf


@njit(cache=True)
def _step(G, k):
    """The Newton step on G = 0, at most TRUST_L either way."""
    step = -G / k if k > 0 else -np.sign(G) * TRUST_L
    if step < -TRUST_L:
        return -TRUST_L
    if step > TRUST_L:
        return TRUST_L
    return step


@njit(cache=True)
def contact(u: npt.NDArray[np.float64], zp: float, labels: tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64]], shape: npt.NDArray[np.float64], terms: Terms,
            order: npt.NDArray[np.int64], keep: npt.NDArray[np.int64], N: int, V0: float, force_scale: float, tol: float, maxit: int,
            newton_maxit: int, retreat: bool, predict: bool,
            history: tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64]]) -> tuple[int, npt.NDArray[np.float64], npt.NDArray[np.float64], int, int, float, float]:
    """The contact search from u at z_p (module docstring): at most `maxit`
    labels, Newton's method at each for at most `newton_maxit` steps; labels
    and shape those of `solver.fast.mesh.label_positions` (`Reference.arrays`);
    `history` the stored history (ψ̄0, P_a, P_s), empty for none (module docstring).
    Returns (status, u, g, iterations, last, lo, hi): FOUND with the
    solution, `last` HELD where the free surface touching the plate holds its
    label (G > 0 there), else 0; Newton's status with its last state and `last` its iteration;
    TANGENT_SINGULAR with `last` the zero pivot; NO_CONTACT with the bracket
    [lo, hi]."""
    lo, hi, iterations, kc = LOG_PSI_MIN, LOG_PSI_MAX, 0, terms.kc
    touching, t0_l, t0_gap, t0_u, t1_l, t1_gap = 0, 0.0, 0.0, u, 0.0, 0.0
    tangent, G = np.empty(0), 0.0
    solved, solved_tangent = np.empty(0), np.empty(0)     # the last label solved (`retreat`)
    carried, nd = history[0].size > 0, kc - labels[1].size
    dpa, dps = np.empty(0), np.empty(0)
    last_l, last_G = np.nan, np.nan          # the last label solved below the plate and its G
    first = True                             # no label solved below the plate yet
    for n in range(maxit):
        ref = label_positions(u[-2], labels, shape)
        if carried:
            dpa, dps = carry_history(u[-2], labels[1], labels[2], history, terms)
        tried = u[-2]
        status, u, g, band, lp, it = newton(u, zp, ref, terms, order, N, V0, force_scale, 1e-6, newton_maxit)
        if status != CONVERGED:
            if retreat and solved.size and abs(tried - solved[-2]) > TOL_L:
                u = _moved(solved, zp, N, kc, keep, solved_tangent, 0.5 * (tried + solved[-2]))
                continue
            return status, u, g, iterations, it, lo, hi
        iterations += it
        l, above = u[-2], gap(u, zp, N, kc)
        if above > 0:
            lo, step = l, TRUST_L
        else:
            G, k, tangent, info = _tangent(g, band, lp, order, keep, terms.band)
            if info != 0:
                return TANGENT_SINGULAR, u, g, iterations, info, lo, hi
            if carried:
                G += history_share(u, zp, ref[0], ref[1], N, kc, nd, dpa, dps)
                if l != last_l and (G - last_G) / (l - last_l) > 0:
                    k = (G - last_G) / (l - last_l)
                last_l, last_G = l, G
            if abs(G) < tol * force_scale or (G > 0 and u[-2] <= LOG_PSI_MIN + 1e-12):
                return FOUND, u, g, iterations, 0, lo, hi
            if G > 0:
                hi = l
                t1_l, t1_gap = t0_l, t0_gap
                t0_l, t0_gap, t0_u = l, above, u
                touching = min(touching + 1, 2)
            else:
                lo = l
            step = _step(G, k)
            if carried and first:
                step = FIRST_STEP_L if G < 0 else -FIRST_STEP_L
            elif carried and (lo if step < 0 else hi) in (LOG_PSI_MIN, LOG_PSI_MAX) and abs(step) < OPEN_STEP_L:
                step = OPEN_STEP_L if step > 0 else -OPEN_STEP_L
            first = False
        target = l + step
        if predict and touching == 1 and above <= 0 and G > 0:
            # no further down than the tangent's touching label, at least TOL_L/2 (docstring)
            touch = _touch_predicted(u, zp, N, kc, keep, tangent, above)
            target = min(max(target, touch + 0.3 * TOL_L), l - 0.5 * TOL_L)
        if touching == 2 and above <= 0 and G > 0:
            # less contact would lift the free surface through the plate: the
            # minimum over the admissible labels is where it touches
            touch = t0_l - t0_gap * (t0_l - t1_l) / (t0_gap - t1_gap) if t0_gap != t1_gap else lo
            if abs(touch - t0_l) < TOL_L:
                return FOUND, t0_u, g, iterations, HELD, lo, hi
            target = max(target, touch + 0.3 * TOL_L)
        if hi - lo < TOL_L and touching:
            return FOUND, t0_u, g, iterations, HELD, lo, hi
        if carried and n >= CRAWL_AFTER and above <= 0 and LOG_PSI_MIN < lo and hi < LOG_PSI_MAX:
            if hi - lo < TOL_L:          # G changes sign within TOL_L: a root, or its jump
                return FOUND, u, g, iterations, 0, lo, hi
            # a secant crawling along one end of a closed bracket: make it shrink
            target = min(max(target, lo + SHRINK * (hi - lo)), hi - SHRINK * (hi - lo))
        if not lo < target < hi:
            target = 0.5 * (lo + hi) if hi < LOG_PSI_MAX else min(l + TRUST_L, hi)
        solved, solved_tangent = u, tangent if above <= 0 else np.empty(0)
        u = _moved(u, zp, N, kc, keep, solved_tangent, max(target, LOG_PSI_MIN))
    return NO_CONTACT, u, np.empty(0), iterations, maxit, lo, hi
