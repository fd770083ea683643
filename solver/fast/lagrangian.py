"""The fast solver's discrete Lagrangian with its exact gradient and Hessian.

Nodes run along the upper half meridian (mirror symmetry): the pole k = 0,
the plate nodes k ≤ k_c (z = z_p = h/2, sliding in r), the free nodes
(r, z unknown) and the equator k = N (z = 0). The unknowns are
u = (r_1..r_N, z_{k_c+1}..z_{N-1}, l = log ψ_c, p); the reference positions
(r0, z0) of the nodes depend on l (`solver.fast.mesh`).

Discrete Lagrangian of the whole cell (twice the half), elements e = (k, k+1):

    L = Σ_e 4π [c_e r̄_e ds_e + w(e1, e2) r̄0_e dS_e]           (tension, stretching)
      + Σ_k 8π B (H_k - H_d)² r_k ℓ_k                          (bending, free nodes)
      - p (2 Σ_e π (z_k - z_k+1)(r_k² + r_k r_k+1 + r_k+1²)/3 - V0)

with ds, dS the current and reference element lengths, r̄ and r̄0 the mid
radii, λ1 = ds/dS, λ2 = r̄/r̄0, e_i = λ_i - 1,
w = (K_B/2)(e1+e2)² + (K_S/2)(e1-e2)² (plus a prestress linear in the
strain per element, P_a,e (e1+e2) + P_s,e (e1-e2), `Terms.pa`, `Terms.ps`: zero
unless set, as `solver.time_domain` does), and c_e = γ_a, plus 2 B H_d² on the
strip of material that has newly come onto the plate (reference curvature
H_d, now flat). At a free node H = (1/2)[(θ_b - θ_a)/ℓ + sin((θ_a+θ_b)/2)/r]
with θ the elements' tangent angles to the plate (zero on the plate),
ℓ = (ds_a + ds_b)/2; the equator closes by mirror symmetry (θ_b = π - θ_a,
half the dual area).

Every term is a function of a few intermediate quantities (lengths, mid
radii, angles), so its Hessian is the chain rule J^T (∂²f) J + Σ ∂f ∇²(a);
the formulas are written out, and compiled, in `solver.fast.kernel` and
checked against central differences in the tests. Energies in mN/m·µm² (= 1e-15 J), forces in nN.
"""

from collections import namedtuple
from functools import lru_cache

import numpy as np
import numpy.typing as npt
from solver.frustum import enclosed_volume, surface_area
from solver.fast.kernel import L_SLOT, NO_SLOT, P_SLOT, Terms, evaluate
from solver.fast.mesh import Reference
from solver.fast.newton import block_solve, nodes
from solver.model import Shell

BAND = 5    # half-bandwidth of the position block in node order
SCALE_LEAST = 0.1    # the force scale's length at least this times 1/H_d (a0 -> 0 at the free sphere)

# The Newton matrix (the Hessian of L in the unknowns) in the parts the solve
# uses: `band`, the position block in LAPACK band storage in node order
# (`Lagrangian.band_order`); `lcol`, `pcol`, its columns of l and p (size).
NewtonMatrix = namedtuple("NewtonMatrix", "band lcol pcol")


class Lagrangian:
    """L(u; z_p) of one shell on one reference mesh, with exact derivatives."""

    V0: float       # the reference mesh's volume (µm³) and area (µm²), set by who made the
    area0: float    # mesh (`solver.fast.problem`)
    # the mesh's index arrays, from `_layout` (shared by the Lagrangians of one mesh)
    ridx: npt.NDArray[np.int64]
    zidx: npt.NDArray[np.int64]
    elem_idx: npt.NDArray[np.int64]
    bend_idx: npt.NDArray[np.int64]
    band_order: npt.NDArray[np.int64]
    band_mask: npt.NDArray[np.bool_]
    band_rows: npt.NDArray[np.int64]
    band_cols: npt.NDArray[np.int64]
    slot: npt.NDArray[np.int64]
    keep: npt.NDArray[np.int64]

    def __init__(self, shell: Shell, ref: Reference, regularisation: float = 1e-3) -> None:
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
        self.size = self.nr + self.nz + 2           # + l, p
        self.cten = np.full(N, float(self.gamma))
        self.cten[self.nd: self.kc] += 2.0 * self.B * ref.H**2
        vars(self).update(_layout(self.nd, self.nn, self.nf))
        self.elastic = shell.bulk_mN_per_m + shell.shear_mN_per_m > 0.0
        self.terms = Terms(cten=self.cten, KB=float(self.KB), KS=float(self.KS), B=float(self.B),
                           Hd=float(ref.H), kc=int(self.kc), elem_idx=self.elem_idx,
                           bend_idx=self.bend_idx, slot=self.slot, band=BAND,
                           pa=np.zeros(N), ps=np.zeros(N))
        # natural size of a nodal force: tension times a typical element length (a tenth
        # of the contact radius a0, or of SCALE_LEAST / H_d where a0 is smaller: a reference
        # near the free sphere, whose a0 -> 0 would ask for residuals below round-off)
        self.force_scale = (self.gamma + self.KB + self.KS) * max(ref.a0, SCALE_LEAST / ref.H) * 0.1

    def solve(self, H: NewtonMatrix | npt.NDArray[np.float64], rhs: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """Solve the Newton system for the positions and p at fixed l:
        [A b; b^T 0] [x; y] = rhs, with A (positions) banded (a node couples
        to its neighbours within two) and b = ∂²L/∂x∂p, by block elimination
        (compiled: `solver.fast.newton.block_solve`). H: a `NewtonMatrix` or
        the dense Hessian."""
        H = self.banded(H) if isinstance(H, np.ndarray) else H
        rhs = np.ascontiguousarray(np.asarray(rhs, dtype=float).reshape(self.size - 1, -1))
        out, info = block_solve(H.band, H.pcol, self.band_order, BAND, rhs)
        if info != 0:
            raise np.linalg.LinAlgError(f"singular Newton matrix (zero pivot {info})")
        return out

    def banded(self, H: npt.NDArray[np.float64]) -> NewtonMatrix:
        """The dense Hessian H (size × size) as a `NewtonMatrix`."""
        n = self.size
        return NewtonMatrix(np.where(self.band_mask, H[self.band_rows, self.band_cols], 0.0),
                            H[:, n - 2].copy(), H[:, n - 1].copy())

    def dense(self, M: NewtonMatrix) -> npt.NDArray[np.float64]:
        """The `NewtonMatrix` M as the dense Hessian (size × size)."""
        n = self.size
        H = np.zeros((n, n))
        H[self.band_rows[self.band_mask], self.band_cols[self.band_mask]] = M.band[self.band_mask]
        H[:, n - 2] = H[n - 2, :] = M.lcol
        H[:, n - 1] = H[n - 1, :] = M.pcol
        return H

    def nodes(self, u: npt.NDArray[np.float64], zp: float) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], float, float]:
        """(r, z) of every node, ψ_c and p from the unknowns."""
        r, z = nodes(np.asarray(u, dtype=float), float(zp), self.N, self.kc)
        return r, z, np.exp(u[-2]), u[-1]

    def volume(self, u: npt.NDArray[np.float64], zp: float) -> float:
        """Enclosed volume V(u) (µm³, `solver.frustum`)."""
        return enclosed_volume(*self.nodes(u, zp)[:2])

    def area(self, u: npt.NDArray[np.float64], zp: float) -> float:
        """Total area A(u) (µm², contact discs included; `solver.frustum`)."""
        return surface_area(*self.nodes(u, zp)[:2])

    def newton_system(self, u: npt.NDArray[np.float64], zp: float,
                      hessian: bool = True) -> tuple[float, npt.NDArray[np.float64], float, NewtonMatrix | None]:
        """L, ∇L (size), ∂L/∂z_p, and the Hessian as a `NewtonMatrix` if asked
        (compiled: `solver.fast.kernel.evaluate`)."""
        n = self.size
        r, z, _, p = self.nodes(u, zp)
        value, grad, (band, lp) = evaluate((r, z, float(p)), self.ref.positions(u[-2]), self.terms,
                                           n, hessian)
        grad[n - 1] += self.V0
        M = NewtonMatrix(band, lp[0], lp[1]) if hessian else None
        return value + p * self.V0, grad[:n], grad[n], M

    def evaluate(self, u: npt.NDArray[np.float64], zp: float, hessian: bool = True) -> tuple[float, npt.NDArray[np.float64], float, npt.NDArray[np.float64] | None]:
        """L, ∇L (size), ∂L/∂z_p, and the dense Hessian (size × size) if asked."""
        value, grad, dzp, M = self.newton_system(u, zp, hessian)
        return value, grad, dzp, self.dense(M) if M is not None else None


@lru_cache(maxsize=64)
def _layout(nd, nn, nf):
    """Where everything goes for a mesh of nd disc, nn strip and nf free
    nodes (the same for every shell on that mesh: computed once, shared by
    its Lagrangians, not to be modified): the global index of each node
    coordinate, of each element's and bending node's unknowns, the node order
    of the positions (the Newton matrix is then banded), its band storage,
    each index's slot in the Newton matrix (`solver.fast.kernel`) and `keep`,
    the unknowns without l."""
    kc = nd + nn
    N = kc + nf
    n = N + nf - 1 + 2
    # where each node coordinate goes: an unknown, the plate height (n), or nowhere (n + 1)
    k = np.arange(N + 1)
    ridx = np.where(k >= 1, k - 1, n + 1)
    zidx = np.where(k <= kc, n, np.where(k < N, N + k - kc - 1, n + 1))
    e = np.arange(N)
    lp = np.full(N, n - 2), np.full(N, n - 1)
    elem_idx = np.stack([ridx[e], zidx[e], ridx[e + 1], zidx[e + 1], *lp], axis=1)
    kb = np.arange(kc, N)
    bend_idx = np.stack([ridx[kb - 1], zidx[kb - 1], ridx[kb], zidx[kb], ridx[kb + 1], zidx[kb + 1]],
                        axis=1)
    # node-by-node order of the position unknowns: the Newton matrix is then banded
    k = np.arange(1, N + 1)
    zk = np.where((k > kc) & (k < N), N + k - kc - 1, -1)
    order = np.stack([k - 1, zk], axis=1).ravel()
    o = order[order >= 0]
    # LAPACK band storage: ab[BAND + i - j, j] = A[i, j]
    d, j = np.meshgrid(np.arange(-BAND, BAND + 1), np.arange(len(o)), indexing="ij")
    i = j + d
    band_mask = (i >= 0) & (i < len(o))
    i = np.clip(i, 0, len(o) - 1)
    slot = np.full(n + 2, NO_SLOT)
    slot[o], slot[n - 2], slot[n - 1] = np.arange(len(o)), L_SLOT, P_SLOT
    return dict(ridx=ridx, zidx=zidx, elem_idx=elem_idx, bend_idx=bend_idx, band_order=o,
                band_mask=band_mask, band_rows=o[i], band_cols=o[j], slot=slot,
                keep=np.r_[0: n - 2, n - 1])
