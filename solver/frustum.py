"""Volume, area and stretches of an axisymmetric polygon meridian (SPEC section 2).

The shell's upper half meridian is a polyline of nodes (r_j, z_j), j = 0..N,
from the pole on the plate to the equator on the mid-plane; element j joins
nodes j and j+1 and sweeps a frustum of a cone about the axis:

    l_j = |x_{j+1} - x_j|,                 a_j = π (r_j + r_{j+1}) l_j,
    V_j = (π/3)(z_j - z_{j+1})(r_j² + r_j r_{j+1} + r_{j+1}²).

The closed cell is the half mirrored at z = 0: V = 2 Σ_j V_j, A = 2 Σ_j a_j.

Principal stretches at the nodes, against reference nodes (r0, z0) of the
same material: meridional λ1 = l_j / l0_j on each element, averaged over the
two elements at a node (the end nodes take their element's value);
circumferential λ2 = r / r0, and at the pole, where r = r0 = 0, the limit
λ2 = λ1 (axisymmetry).

The sums are compiled loops, so the explicit solver's time loop calls them
too; lengths in µm, areas in µm², volumes in µm³.
"""

import numpy as np
import numpy.typing as npt

from solver.jit import njit


@njit(cache=True)
def half_volume(r: npt.NDArray[np.float64], z: npt.NDArray[np.float64]) -> float:
    """Σ_j V_j: the volume between the meridian and the mid-plane (µm³)."""
    v = 0.0
    for j in range(r.size - 1):
        v += np.pi / 3.0 * (z[j] - z[j + 1]) * (r[j] ** 2 + r[j] * r[j + 1] + r[j + 1] ** 2)
    return v


@njit(cache=True)
def half_area(r: npt.NDArray[np.float64], z: npt.NDArray[np.float64]) -> float:
    """Σ_j a_j: the area swept by the upper half meridian (µm²)."""
    a = 0.0
    for j in range(r.size - 1):
        a += np.pi * (r[j] + r[j + 1]) * np.hypot(r[j + 1] - r[j], z[j + 1] - z[j])
    return a


def enclosed_volume(r: npt.ArrayLike, z: npt.ArrayLike) -> float:
    """V = 2 Σ_j V_j of the closed, mirrored surface (µm³)."""
    return 2.0 * half_volume(np.asarray(r, float), np.asarray(z, float))


def surface_area(r: npt.ArrayLike, z: npt.ArrayLike) -> float:
    """A = 2 Σ_j a_j of the closed, mirrored surface (µm²)."""
    return 2.0 * half_area(np.asarray(r, float), np.asarray(z, float))


def nodal_stretches(r: npt.NDArray[np.float64], z: npt.NDArray[np.float64], r0: npt.NDArray[np.float64], z0: npt.NDArray[np.float64]) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """(λ1, λ2) at the nodes of the current meridian (r, z) against the
    reference (r0, z0) (module docstring)."""
    lam_e = np.hypot(np.diff(r), np.diff(z)) / np.hypot(np.diff(r0), np.diff(z0))
    lam1 = np.concatenate([[lam_e[0]], 0.5 * (lam_e[1:] + lam_e[:-1]), [lam_e[-1]]])
    lam2 = np.concatenate([[lam1[0]], r[1:] / r0[1:]])
    return lam1, lam2
