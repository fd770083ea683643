"""The fast solver: the compressed equilibrium of the shell, computed directly.

Formulation (upper half by mirror symmetry; SPEC section 2 symbols):

Material points are labelled by where they sit on the reference droplet at h0:
the contact disc (reference arc length S = r0 ∈ [0, a0], a0 = R_c(h0)) and the
free surface, labelled by its reference tangent angle ψ0 ∈ [0, π/2] with the
closed forms of `solver.geometry` (H_d the droplet's mean curvature):

    r0(ψ0) = (sin ψ0 + q) / (2 H_d),   S(ψ0) = a0 + s(ψ0).

After compression the material with ψ0 < ψ_c has come onto the plate too: the
contact label ψ_c is a continuous unknown, so the energy is smooth in it and
the contact line never jumps between nodes. Nodes: the pole, n_d nodes on the
old disc, n_n on the newly touching strip [0, ψ_c], n_f on the free part
ψ0 = ψ_c + (π/2 - ψ_c) ξ_j, graded towards the contact line where bending acts
in a layer of width sqrt(B/γ_a). Nodes on the plate keep z = h/2 and slide
(unknown r); free nodes have unknown (r, z); the equator node keeps z = 0.

Discrete Lagrangian of the whole cell (twice the half), elements e = (k, k+1):

    L = 2 Σ_e [γ_a π (r_k + r_k+1) ds_e + w(e1, e2) 2π r0_e dS_e]
      + 2 Σ_k 2B (H_k - H0_k)² dA_k + 2 Σ_plate 2B H0_e² dA_e
      - p (2 Σ_e π (z_k - z_k+1)(r_k² + r_k r_k+1 + r_k+1²)/3 - V0),

with λ1 = ds/dS, λ2 = r_mid/r0_mid, e_i = λ_i - 1,
w = (K_B/2)(e1+e2)² + (K_S/2)(e1-e2)²; at free nodes H = (κ_s + κ_φ)/2 with
κ_s = Δθ / ℓ (turning angle over the dual length) and κ_φ = sin θ / r, θ the
tangent angle to the plate; the equator closes by mirror symmetry. V0 is the
volume of the reference mesh, so the reference droplet is the discrete state
at h = h0.

Stationarity of L in (r, z, ψ_c, p) is solved by Newton's method: the
gradient by complex-step differentiation of the local energy terms (exact to
round-off; three colours per coordinate, since a term spans at most three
nodes), the Hessian by coloured finite differences of that gradient, with
continuation h0 -> h1 in a few steps. The plate force is the envelope
derivative F_tot = -∂L/∂h at the solution (virtual work); in nN, since
energies are in mN/m·µm² and lengths in µm.

A tiny in-plane stiffness (1e-3 γ_a) is added to K_B and K_S so that a
tension-only shell still has a unique node distribution; it changes F_tot by
~1e-6 relative.
"""

from dataclasses import dataclass, replace
from functools import lru_cache

import numpy as np

from solver.compression import Solution
from solver.errors import SolverError
from solver.geometry import droplet, meridian

_STEP = 1e-30          # complex-step size
_LOG_PSI_MIN = np.log(2e-3)   # least contact label (≈ 8 nm of material rolled on)
_REG = 1e-3            # in-plane regularisation, relative to γ_a


def _catan2(y, x):
    """atan2 that accepts complex arguments (for complex-step derivatives).
    A degenerate element (x < 0, y = 0) gives NaN, which Newton's step control
    rejects; no warning is printed for it."""
    with np.errstate(invalid="ignore", divide="ignore"):
        return 2.0 * np.arctan(y / (np.sqrt(x * x + y * y) + x))


@dataclass(frozen=True)
class Reference:
    """The reference droplet at h0 and the mesh parameters (cached per shell shape)."""

    a0: float           # R_c(h0)
    H: float            # droplet mean curvature H_d
    beta: float         # 2 H R_c
    eta: np.ndarray     # disc nodes S = a0 η, η in (0, 1]
    zeta: np.ndarray    # new-contact nodes ψ0 = ψ_c ζ, ζ in (0, 1]
    xi: np.ndarray      # free nodes ψ0 = ψ_c + (π/2 - ψ_c) ξ, ξ in (0, 1]
    h0: float
    zcoef: np.ndarray   # Chebyshev series of z0(ψ) on [0, π/2] (from the mid-plane)
    scale: float = 1.0  # radii scaled so that the reference mesh encloses exactly V

    def r0(self, psi):
        s = np.sin(psi)
        return self.scale * (s + np.sqrt(s * s + self.beta**2)) / (2.0 * self.H)

    def z0(self, psi):
        return np.polynomial.chebyshev.chebval(4.0 * psi / np.pi - 1.0, self.zcoef)

    def positions(self, psic):
        """Reference positions (r0, z0) of every node for the contact label ψ_c."""
        psi = np.concatenate([psic * self.zeta, psic + (np.pi / 2 - psic) * self.xi])
        disc = self.scale * self.a0 * np.concatenate([[0.0], self.eta])
        r0 = np.concatenate([disc, self.r0(psi)])
        z0 = np.concatenate([np.full(disc.shape, 0.5 * self.h0), self.z0(psi)])
        return r0, z0


def _graded(n, first, total=1.0):
    """n increasing points in (0, total], the first step ≈ `first`, growing geometrically."""
    if first * n >= total:
        return np.linspace(total / n, total, n)
    lo, hi = 1.0, 2.0
    f = lambda g: first * (g**n - 1.0) / (g - 1.0) - total  # noqa: E731
    while f(hi) < 0:
        hi *= 2.0
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if f(mid) < 0 else (lo, mid)
    g = 0.5 * (lo + hi)
    pts = first * (g ** np.arange(1, n + 1) - 1.0) / (g - 1.0)
    return pts * (total / pts[-1])


@lru_cache(maxsize=64)
def reference(volume, h0, resolution, layer):
    """Reference droplet and graded mesh; `layer` is the bending layer width (µm)."""
    d = droplet(volume, h0)
    a0, H = float(d.contact_radius_um), float(d.mean_curvature_per_um)
    res = float(resolution)
    first = min(layer / 8.0, 0.05) / res
    nf = int(np.ceil(60 * res))
    xi = _graded(nf, first * 2.0 * H / (np.pi / 2))   # ds/dψ = 1/(2H) at the contact line
    nd = int(np.ceil(20 * res))
    eta = 1.0 - _graded(nd, first / a0, 1.0)[::-1]
    eta = np.append(eta[1:], 1.0)
    nn = int(np.ceil(4 * res))
    zeta = np.linspace(1.0 / nn, 1.0, nn)
    zcoef = np.polynomial.chebyshev.chebinterpolate(
        lambda x: meridian(volume, h0, np.clip((x + 1.0) * np.pi / 4.0, 0.0, np.pi / 2))[1], 60)
    ref = Reference(a0=a0, H=H, beta=2.0 * H * a0, eta=eta, zeta=zeta, xi=xi, h0=h0, zcoef=zcoef)
    r, z = ref.positions(0.0)
    enclosed = 2.0 * np.sum(np.pi * (-np.diff(z)) * (r[1:] ** 2 + r[1:] * r[:-1] + r[:-1] ** 2) / 3.0)
    return replace(ref, scale=float(np.sqrt(volume / enclosed)))


class _Problem:
    """The discrete Lagrangian of one shell as a function of the unknowns."""

    def __init__(self, shell, ref, V0=None):
        self.ref = ref
        reg = _REG * shell.tension_mN_per_m
        self.KB = shell.bulk_mN_per_m + reg
        self.KS = shell.shear_mN_per_m + reg
        self.gamma = shell.tension_mN_per_m
        self.B = shell.bending_stiffness
        self.nd, self.nn, self.nf = len(ref.eta), len(ref.zeta), len(ref.xi)
        self.kc = self.nd + self.nn                 # contact node
        self.N = self.kc + self.nf                  # equator node
        self.nr = self.N                            # r_1..r_N
        self.nz = self.nf - 1                       # z_kc+1..z_N-1
        self.size = self.nr + self.nz + 2           # + ψ_c, p
        self.V0 = V0
        # natural size of a nodal force: tension times a typical element length
        self.force_scale = (self.gamma + self.KB + self.KS) * ref.a0 * 0.1
        self.elastic = shell.bulk_mN_per_m + shell.shear_mN_per_m > 0.0

    # -- unknowns <-> nodes ------------------------------------------------
    def nodes(self, u, zp):
        N, kc = self.N, self.kc
        r = np.concatenate([np.zeros(1, u.dtype), u[:N]])
        z = np.empty(N + 1, dtype=np.result_type(u, zp))
        z[: kc + 1] = zp
        z[kc + 1: N] = u[N: N + self.nz]
        z[N] = 0.0
        return r, z, np.exp(u[-2]), u[-1]

    def material(self, psic):
        """Reference positions (r0, z0) of the nodes' material points."""
        return self.ref.positions(psic)

    # -- local terms -------------------------------------------------------
    def terms(self, u, zp):
        """Element terms (N,) and nodal terms (N+1,) whose sum is L + p V0."""
        r, z, psic, p = self.nodes(u, zp)
        r0, z0 = self.material(psic)
        dr, dz = np.diff(r), np.diff(z)
        ds = np.sqrt(dr * dr + dz * dz)
        dS = np.sqrt(np.diff(r0) ** 2 + np.diff(z0) ** 2)
        rm, r0m = 0.5 * (r[1:] + r[:-1]), 0.5 * (r0[1:] + r0[:-1])
        e1, e2 = ds / dS - 1.0, rm / r0m - 1.0
        w = 0.5 * self.KB * (e1 + e2) ** 2 + 0.5 * self.KS * (e1 - e2) ** 2
        area = 2.0 * np.pi * rm * ds
        vol = np.pi * (-dz) * (r[1:] ** 2 + r[1:] * r[:-1] + r[:-1] ** 2) / 3.0
        elem = 2.0 * (self.gamma * area + w * 2.0 * np.pi * r0m * dS) - 2.0 * p * vol
        nodal = np.zeros(self.N + 1, dtype=elem.dtype)
        if self.B > 0:
            Hd = self.ref.H
            plate = slice(self.nd, self.kc)
            elem[plate] += 2.0 * 2.0 * self.B * Hd**2 * area[plate]
            theta = _catan2(-dz, dr)
            theta[: self.kc] = 0.0          # plate elements lie flat
            k = np.arange(self.kc, self.N)
            ta, tb = theta[k - 1], theta[k]
            ell = 0.5 * (ds[k - 1] + ds[k])
            H = 0.5 * ((tb - ta) / ell + np.sin(0.5 * (ta + tb)) / r[k])
            nodal[k] = 2.0 * 2.0 * self.B * (H - Hd) ** 2 * 2.0 * np.pi * r[k] * ell
            ta, ell = theta[-1], ds[-1]
            H = 0.5 * ((np.pi - 2.0 * ta) / ell + 1.0 / r[-1])
            nodal[-1] = 2.0 * 2.0 * self.B * (H - Hd) ** 2 * 2.0 * np.pi * r[-1] * 0.5 * ell
        return elem, nodal

    def lagrangian(self, u, zp):
        elem, nodal = self.terms(u, zp)
        return elem.sum() + nodal.sum() + u[-1] * self.V0

    def volume(self, u, zp):
        r, z, _, _ = self.nodes(u, zp)
        dz = np.diff(z)
        return 2.0 * np.sum(np.pi * (-dz) * (r[1:] ** 2 + r[1:] * r[:-1] + r[:-1] ** 2) / 3.0)

    def area(self, u, zp):
        r, z, _, _ = self.nodes(u, zp)
        ds = np.hypot(np.diff(r), np.diff(z))
        return 2.0 * np.sum(np.pi * (r[1:] + r[:-1]) * ds)

    # -- derivatives -------------------------------------------------------
    def dof_node(self):
        """Node index of every local unknown (r then z)."""
        return np.concatenate([np.arange(1, self.N + 1), np.arange(self.kc + 1, self.N)])

    def gradient(self, u, zp):
        g = np.zeros(self.size)
        node = self.dof_node()
        nloc = self.nr + self.nz
        for block in (slice(0, self.nr), slice(self.nr, nloc)):
            for c in range(3):
                sel = np.arange(nloc)[block][node[block] % 3 == c]
                uc = u.astype(complex)
                uc[sel] += 1j * _STEP
                elem, nodal = self.terms(uc, zp)
                ge, gn = elem.imag / _STEP, nodal.imag / _STEP
                # element e spans nodes e, e+1; nodal term k spans k-1..k+1
                acc = np.zeros(self.N + 2)
                e = np.arange(self.N)
                owner = np.where(e % 3 == c, e, e + 1)
                np.add.at(acc, owner, ge)
                k = np.arange(self.N + 1)
                owner = k + ((c - k) % 3 + 1) % 3 - 1
                np.add.at(acc, owner, gn)
                g[sel] = acc[node[sel]]
        uc = u.astype(complex)
        uc[-2] += 1j * _STEP
        g[-2] = self.lagrangian(uc, zp).imag / _STEP
        g[-1] = self.V0 - self.volume(u, zp)
        return g

    def hessian(self, u, zp, g0):
        """Central differences of the gradient, coloured: the gradient at a node
        depends on nodes within two of it, so every fifth node is perturbed at once;
        the dense rows of ψ_c and p follow from symmetry."""
        n, nloc = self.size, self.nr + self.nz
        Hm = np.zeros((n, n))
        node = self.dof_node()
        rows = np.arange(nloc)
        for block in (slice(0, self.nr), slice(self.nr, nloc)):
            for c in range(5):
                cols = rows[block][node[block] % 5 == c]
                h = 1e-6
                up, um = u.copy(), u.copy()
                up[cols] += h
                um[cols] -= h
                dg = (self.gradient(up, zp) - self.gradient(um, zp)) / (2.0 * h)
                owner = np.full(nloc, -1)
                for j in cols:
                    owner[np.abs(node - node[j]) <= 2] = j
                hit = owner >= 0
                Hm[rows[hit], owner[hit]] = dg[:nloc][hit]
        for j, h in ((n - 2, 1e-6), (n - 1, 1e-3)):
            up, um = u.copy(), u.copy()
            up[j] += h
            um[j] -= h
            col = (self.gradient(up, zp) - self.gradient(um, zp)) / (2.0 * h)
            Hm[:, j] = col
            Hm[j, :nloc] = col[:nloc]
        return 0.5 * (Hm + Hm.T)

    def force(self, u, zp):
        """F_tot = -∂L/∂h1 = -(1/2) ∂L/∂z_plate (complex step), nN."""
        uc = u.astype(complex)
        return -0.5 * self.lagrangian(uc, zp + 1j * _STEP).imag / _STEP


def _newton(prob, u, zp, tol=1e-4, maxit=30):
    """Newton's method on ∇L = 0, damping only steps that make the residual
    explode. The contact label ψ_c is held fixed (its equation dropped) for a
    shell without in-plane elasticity, where it is a gauge (any material may
    sit at the contact line), and while it rests on its lower bound (the
    contact line may not recede on the material), an active set that is
    released when ∂L/∂ψ_c < 0 says the contact wants to grow."""
    clamped = False
    g = prob.gradient(u, zp)
    for it in range(1, maxit + 1):
        if clamped and g[-2] < 0.0:
            clamped = False
        fixed = clamped or not prob.elastic
        Hm = prob.hessian(u, zp, g)
        rhs = -g.copy()
        if fixed:
            Hm[-2, :], Hm[:, -2], Hm[-2, -2], rhs[-2] = 0.0, 0.0, 1.0, 0.0
        try:
            step = np.linalg.solve(Hm, rhs)
        except np.linalg.LinAlgError as err:
            raise SolverError(f"singular Newton system at iteration {it}: {err}") from None
        t = 1.0
        while u[-2] + t * step[-2] > np.log(np.pi / 2):
            t *= 0.5
        if not fixed and u[-2] + t * step[-2] < _LOG_PSI_MIN:
            clamped, step[-2] = True, _LOG_PSI_MIN - u[-2]
        norm0 = np.linalg.norm(g[:-2])
        while True:
            gt = prob.gradient(u + t * step, zp)
            if (np.all(np.isfinite(gt)) and np.linalg.norm(gt[:-2]) < 100.0 * norm0) or t < 1e-3:
                break
            t *= 0.5
        u, g = u + t * step, gt
        if not np.all(np.isfinite(g)):
            raise SolverError(f"non-finite residual at Newton iteration {it}")
        free = g[:-2] if (clamped and g[-2] >= 0) or not prob.elastic else g[:-1]
        if np.abs(free).max() < tol * prob.force_scale and abs(g[-1]) < 1e-7 * prob.V0:
            return u, it
    raise SolverError(f"Newton did not converge in {maxit} iterations (largest residual "
                      f"force {np.abs(g[:-2]).max():.3g} nN, volume residual {g[-1]:.3g} um3)")


def _reference_unknowns(prob, psic, h_ratio=1.0):
    """The unknowns of the reference mesh for label ψ_c, heights scaled by h_ratio."""
    r0, z0 = prob.material(psic)
    zfree = z0[prob.kc + 1: prob.N] * h_ratio
    return np.concatenate([r0[1:], zfree, [np.log(psic), 2.0 * prob.gamma * prob.ref.H]])


def _reference_state(prob, h0):
    """Volume (= V by construction of the scale) and area of the reference mesh."""
    u = _reference_unknowns(prob, 1e-12)
    return prob.volume(u, 0.5 * h0), prob.area(u, 0.5 * h0)


def _droplet_guess(prob, volume, h):
    """Start: the nodes spread over the droplet shape at gap h (the exact answer
    for a tension-only shell), the plate nodes in proportion to their labels."""
    ref, d = prob.ref, droplet(volume, h)
    Rc = float(d.contact_radius_um)
    psic = min(max((Rc - ref.a0) * 2.0 * ref.H, 1e-3), 0.5)
    r0, _ = prob.material(psic)
    r_plate = Rc * r0[1: prob.kc + 1] / r0[prob.kc]
    rf, zf, _ = meridian(volume, h, 0.5 * np.pi * ref.xi)
    p = 2.0 * prob.gamma * float(d.mean_curvature_per_um)
    return np.concatenate([r_plate, rf, zf[:-1], [np.log(psic), p]])


def _squeezed_reference(prob, shell, h, widen=1.0):
    """Start for an elastic shell: the reference nodes, heights scaled to the gap h."""
    dR = float(droplet(shell.volume_um3, h).contact_radius_um) - prob.ref.a0
    psic = min(max(widen * dR * 2.0 * prob.ref.H, 2e-3), 0.5)
    return _reference_unknowns(prob, psic, h / shell.h0_um)


def _compress(prob, shell, steps, widen=1.0, start="droplet"):
    """Newton from the droplet guess at the first gap, then from each solution."""
    iterations = 0
    for i in range(1, steps + 1):
        h = shell.h0_um - shell.dh_um * i / steps
        if i == 1:
            u = (_droplet_guess(prob, shell.volume_um3, h) if start == "droplet"
                 else _squeezed_reference(prob, shell, h, widen))
        u, it = _newton(prob, u, 0.5 * h)
        iterations += it
    return u, iterations


def _equilibrium(shell):
    """The solved problem, its unknowns, Newton iterations and the reference area."""
    B = shell.bending_stiffness
    layer = np.sqrt(B / shell.tension_mN_per_m) if B > 0 else 0.2
    ref = reference(float(shell.volume_um3), float(shell.h0_um), float(shell.resolution),
                    round(float(layer), 4))
    prob = _Problem(shell, ref)
    # the reference mesh at h0 defines V0 and the reference area
    prob.V0, area0 = _reference_state(prob, shell.h0_um)
    # Newton from a start with too little contact can end on a stationary state
    # whose free surface pokes through the plate: start with more contact then.
    zp, failure = 0.5 * shell.h1_um, None
    starts = [(1, 1.0, "droplet"), (3, 1.0, "droplet")]
    if prob.elastic:
        starts += [(1, 1.0, "reference"), (1, 2.0, "reference"), (3, 3.0, "reference")]
    for steps, widen, start in starts:
        try:
            u, iterations = _compress(prob, shell, steps, widen, start)
        except SolverError as err:
            failure = err
            continue
        if np.max(prob.nodes(u, zp)[1]) <= zp * (1.0 + 1e-9):
            break
        failure = SolverError("the free surface crossed the plate")
    else:
        raise SolverError(f"no admissible equilibrium found (continuation up to 8 steps): {failure}")
    return prob, u, iterations, area0


def energy(shell):
    """E* = min E at fixed volume and gap h1 (mN/m·µm², = 1e-15 J): the energy
    whose derivative -dE*/dh1 is the plate force (virtual work)."""
    prob, u, _, _ = _equilibrium(shell)
    return _energy(prob, u, 0.5 * shell.h1_um)


def _energy(prob, u, zp):
    """E = L + p (V - V0), the Lagrangian with the constraint term removed."""
    return prob.lagrangian(u.astype(complex), zp).real + u[-1] * (prob.volume(u, zp) - prob.V0)


def solve(shell):
    """Compressed equilibrium of `shell` (a `solver.model.Shell`): a `Solution`."""
    prob, u, iterations, area0 = _equilibrium(shell)
    zp = 0.5 * shell.h1_um
    force = prob.force(u, zp)
    r, z, psic, p = prob.nodes(u, zp)
    r0, z0 = prob.material(psic)
    ds = np.hypot(np.diff(r), np.diff(z))
    lam_e = ds / np.hypot(np.diff(r0), np.diff(z0))
    lam1 = np.concatenate([[lam_e[0]], 0.5 * (lam_e[1:] + lam_e[:-1]), [lam_e[-1]]])
    with np.errstate(divide="ignore", invalid="ignore"):
        lam2 = np.where(r0 > 0, r / np.where(r0 > 0, r0, 1.0), lam1)
    lam2[0] = lam1[0]
    if not np.isfinite(force):
        raise SolverError("non-finite plate force")
    return Solution(force_nN=float(force), volume_um3=prob.volume(u, zp),
                    area_um2=prob.area(u, zp), area0_um2=area0, r_um=r, z_um=z,
                    lambda1=lam1, lambda2=lam2, converged=True, iterations=iterations,
                    message=f"contact label psi_c = {psic:.5g}, pressure {p:.6g} mN/m/um")
