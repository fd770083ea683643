"""Axisymmetric Stokes flow in the cell's interior: Taylor-Hood (P2/P1) elements.

The cytoplasm is an incompressible Newtonian fluid of viscosity η (Pa·s).
Reynolds numbers are ~1e-7 here (U ~ 1 µm/s, L ~ 10 µm, water), so inertia is
dropped: at every instant

    -∇·σ = 0,   ∇·u = 0,   σ = -p I + 2η e(u),   e = (∇u + ∇uᵀ)/2.

Axisymmetric, no swirl: u = (u_r, u_z)(r, z) on the meridian half-plane, with

    e:e = (∂_r u_r)² + (∂_z u_z)² + 2 e_rz² + (u_r/r)²,   e_rz = (∂_z u_r + ∂_r u_z)/2,
    ∇·u = ∂_r u_r + u_r/r + ∂_z u_z,

and the weak form over the upper half (dV = 2π r dr dz): find u, p with

    a(u, v) - b(v, p) = 0,   b(u, q) = 0,
    a(u, v) = ∫ 2η e(u):e(v) dV,   b(u, q) = ∫ q ∇·u dV,

for all v vanishing where u is prescribed. Boundary conditions: u given on
the shell (no slip), u_r = 0 on the axis, u_z = 0 and no shear stress on the
mid-plane (mirror symmetry). With u prescribed all round, p is fixed up to a
constant: one pressure unknown is held at 0, which is exact when the data's
flux vanishes (the divergence equations then sum to that identity). The
dissipation rate is D = a(u, u) = ∫ 2η e:e dV. Units: µm, s, Pa·s, so u is in
µm/s, p and σ in Pa, forces in Pa·µm² = 1e-3 nN, D in Pa·µm³/s = 1e-18 W.
"""

from collections.abc import Callable
from typing import Any

import numpy as np
import numpy.typing as npt
from scipy.sparse import bmat
from scipy.sparse.linalg import splu
from skfem import Basis, BilinearForm, DiscreteField, ElementTriP1, ElementTriP2, ElementVector, MeshTri

from solver.meridian_mesh import mesh_points

AXIS_TOL = 1e-9   # µm: a facet with both ends this close to r = 0 (or z = 0) is on the axis (mid-plane)


@BilinearForm
def viscous_form(u: DiscreteField, v: DiscreteField, w: Any) -> DiscreteField:
    """2η e(u):e(v) 2π r (η = 1; scaled by the caller)."""
    r = w.x[0]
    gu, gv = u.grad, v.grad
    erz_u, erz_v = 0.5 * (gu[0, 1] + gu[1, 0]), 0.5 * (gv[0, 1] + gv[1, 0])
    ee = gu[0, 0] * gv[0, 0] + gu[1, 1] * gv[1, 1] + 2 * erz_u * erz_v + u[0] * v[0] / r**2
    return 2.0 * ee * 2.0 * np.pi * r


@BilinearForm
def divergence_form(u: DiscreteField, q: DiscreteField, w: Any) -> DiscreteField:
    """q ∇·u 2π r."""
    r = w.x[0]
    return q * (u.grad[0, 0] + u[0] / r + u.grad[1, 1]) * 2.0 * np.pi * r


class Interior:
    """The Stokes problem on one mesh of the meridian half-domain.

    `vertices`, `triangles` as from `solver.meridian_mesh.mesh_points`; the
    first `n_outline` vertices are the shell's nodes (the rest of the
    boundary is the axis and the mid-plane)."""

    def __init__(self, vertices: npt.NDArray[np.float64], triangles: npt.NDArray[np.int64], n_outline: int) -> None:
        self.mesh = MeshTri(np.ascontiguousarray(vertices.T), np.ascontiguousarray(triangles.T))
        self.n_outline = n_outline
        self.ub = Basis(self.mesh, ElementVector(ElementTriP2()), intorder=5)
        self.pb = Basis(self.mesh, ElementTriP1(), intorder=5)
        self.A = viscous_form.assemble(self.ub)                  # η = 1
        self.B = divergence_form.assemble(self.ub, self.pb)
        self._classify()

    @classmethod
    def from_outline(cls, r: npt.NDArray[np.float64], z: npt.NDArray[np.float64], h_max: float = 0.5) -> "Interior":
        """Mesh the interior of the outline (pole (0, z_p) ... equator (R, 0))."""
        vertices, triangles = mesh_points(r, z, h_max)
        return cls(vertices, triangles, len(r))

    def _classify(self):
        """Velocity unknowns: the shell's (both components), the axis's u_r,
        the mid-plane's u_z (all prescribed), and the free rest."""
        m = self.mesh
        facets = m.boundary_facets()
        ends = m.p[:, m.facets[:, facets]]                    # (2, 2, nf)
        on_axis = np.all(np.abs(ends[0]) < AXIS_TOL, axis=0)
        on_mid = np.all(np.abs(ends[1]) < AXIS_TOL, axis=0)
        shell = facets[~on_axis & ~on_mid]
        dofs = self.ub.get_dofs(shell)
        self.shell_r, self.shell_z = dofs.all("u^1"), dofs.all("u^2")
        self.is_r = np.zeros(self.ub.N, bool)
        self.is_r[self.ub.nodal_dofs[0]] = True
        self.is_r[self.ub.facet_dofs[0]] = True
        axis, mid = self.ub.get_dofs(facets[on_axis]), self.ub.get_dofs(facets[on_mid])
        fixed = np.concatenate([self.shell_r, self.shell_z, axis.all("u^1"), mid.all("u^2")])
        self.fixed = np.unique(fixed)
        self.free = np.setdiff1d(np.arange(self.ub.N), self.fixed)
        self._lu = None

    def _factor(self):
        """LU of the saddle-point matrix on the free velocities and the pressures
        (pressure unknown 0 held at 0; the MMD ordering of AᵀA fills least here)."""
        if self._lu is None:
            A, B = self.A[self.free][:, self.free], self.B[1:][:, self.free]
            self._lu = splu(bmat([[A, -B.T], [-B, None]], format="csc"), permc_spec="MMD_ATA")
        return self._lu

    def solve(self, boundary_velocity: Callable[[npt.NDArray[np.float64]], npt.ArrayLike],
              viscosity_Pa_s: float = 1.0) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """Velocity (all dofs) and pressure for u = boundary_velocity(x) on the
        prescribed unknowns: a function of points (2, n) giving velocities
        (2, n), µm/s (on the axis and the mid-plane only its u_r = 0, u_z = 0
        components are used, so it must satisfy the symmetry)."""
        values = np.asarray(boundary_velocity(self.ub.doflocs[:, self.fixed]))
        u = np.zeros(self.ub.N)
        u[self.fixed] = np.where(self.is_r[self.fixed], values[0], values[1])
        return self._solve_fixed(u, viscosity_Pa_s)

    def _solve_fixed(self, u, viscosity):
        """Given u on the fixed dofs, the free velocities and the pressure."""
        free, p = self.extend(u[self.fixed])
        u = u.copy()
        u[self.free] = free
        return u, np.concatenate([[0.0], p]) * viscosity

    def extend(self, fixed_values: npt.ArrayLike) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """Free velocities and pressures (but the first, held at 0; per unit η) for
        the given values on the fixed dofs; columns of a 2D array are solved together."""
        w = np.asarray(fixed_values)
        rhs = np.concatenate([-(self.A[self.free][:, self.fixed] @ w), self.B[1:][:, self.fixed] @ w])
        x = self._factor().solve(rhs)
        return x[: len(self.free)], x[len(self.free):]

    def drag(self, fixed_values: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """The reaction R = A_bf u_f + A_bb u_b - B_bᵀ p on the fixed dofs (per unit
        η: Pa·µm² per Pa·s·µm/s) for the given values there: the Dirichlet-to-
        Neumann map, symmetric, with u_bᵀ R = ∫ 2 e:e dV (the dissipation per η)."""
        w = np.asarray(fixed_values)
        free, p = self.extend(w)
        Af, Ab, Bb = self.A[self.fixed][:, self.free], self.A[self.fixed][:, self.fixed], self.B[1:][:, self.fixed]
        return Af @ free + Ab @ w - Bb.T @ p

    def dissipation(self, u: npt.NDArray[np.float64], viscosity_Pa_s: float) -> float:
        """D = ∫ 2η e:e dV over the half domain (Pa·µm³/s)."""
        return float(viscosity_Pa_s * u @ (self.A @ u))
