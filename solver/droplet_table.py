"""The droplet's force per tension g = F_a/γ_a = 2 H A_c, mean curvature H and
surface area A at many heights at once: interpolated from one table of `solver.geometry.droplet`
(SPEC section 1), for fits that ask for them at every sample of a force curve.

The shape scales with the cell: at volume V (R_cell = (3V/4π)^(1/3)) and gap h,

    g(V, h) = R_cell ĝ(δ̂),   H(V, h) = Ĥ(δ̂) / R_cell,   A(V, h) = R_cell² Â(δ̂),   δ̂ = δ / R_cell = 2 (1 - h̃),

with δ = 2 R_cell - h the deformation of the free sphere. ĝ is not smooth in h̃ at
the sphere: it goes to 0 like δ̂ / ln(1/δ̂) (the free surface leaves the plate
like a catenoid), so a cubic spline in h̃ fails there. In ln δ̂ ln ĝ, ln Ĥ and ln Â
are smooth: they are tabulated on 500 shapes (200 knots uniform in ln δ̂ from
1e-9 to 0.1, 300 uniform in δ̂ from 0.1 to 1.6) and interpolated by cubic splines,
relative error below 1e-7 against `droplet` for δ̂ from 1e-8 to 1.6 (h̃ from 0.2
to 1; checked by a test). Outside the table: δ ≤ 0 (no contact) gives g = 0 and
H = 1/R_cell, A = 4π R_cell²; δ̂ below 1e-9 continues the last slope (g ∝ δ̂ to within the log; H and A keep their value at 1e-9);
h̃ below 0.2 is solved exactly by `droplet` (which refuses impossible heights).
Units: µm, µm³, 1/µm.
"""

from functools import lru_cache

import numpy as np
import numpy.typing as npt
from scipy.interpolate import CubicSpline

from solver.geometry import cell_radius, droplet

DEPTH_MIN = 1e-9          # smallest tabulated δ̂
DEPTH_MAX = 1.6           # largest tabulated δ̂ (h̃ = 0.2)


@lru_cache(maxsize=1)
def _tables():
    """(ln ĝ, ln Ĥ, ln Â) as cubic splines of ln δ̂ (about 2 ms once numba is loaded)."""
    ln_d = np.concatenate([np.linspace(np.log(DEPTH_MIN), np.log(0.1), 200),
                           np.log(np.linspace(0.1, DEPTH_MAX, 301)[1:])])
    d = droplet(4.0 * np.pi / 3.0, 2.0 - np.exp(ln_d))
    return tuple(CubicSpline(ln_d, np.log(v)) for v in (d.force_per_tension_um, d.mean_curvature_per_um,
                                                         d.surface_area_um2))


def _unit(depth, which):
    """ĝ (which 0), Ĥ (which 1) or Â (which 2) of the unit cell at deformations δ̂ (module doc)."""
    depth = np.asarray(depth, float)
    d = np.atleast_1d(depth).ravel()
    out = np.full(d.shape, (0.0, 1.0, 4.0 * np.pi)[which])
    touching = ~(d <= 0)                              # the spline read only where it is needed (and NaN)
    dt = d[touching]
    ot = np.exp(_tables()[which](np.log(np.clip(dt, DEPTH_MIN, DEPTH_MAX))))
    tiny = dt < DEPTH_MIN
    if which == 0 and np.any(tiny):
        ot[tiny] *= dt[tiny] / DEPTH_MIN
    beyond = dt > DEPTH_MAX
    if np.any(beyond):
        exact = droplet(4.0 * np.pi / 3.0, 2.0 - dt[beyond])
        ot[beyond] = (exact.force_per_tension_um, exact.mean_curvature_per_um, exact.surface_area_um2)[which]
    out[touching] = ot
    return out.reshape(depth.shape)


def unit_force_per_tension(depth: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """ĝ of the unit cell (R_cell = 1) at deformations δ̂ (array); 0 where δ̂ ≤ 0."""
    return _unit(depth, 0)


def unit_shape(depth: npt.ArrayLike) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """(ĝ, Ĥ) of the unit cell (R_cell = 1) at deformations δ̂ (array): ĝ = 0 and
    Ĥ = 1 where δ̂ ≤ 0."""
    return _unit(depth, 0), _unit(depth, 1)


def unit_area(depth: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """Â of the unit cell (R_cell = 1) at deformations δ̂ (array); 4π where δ̂ ≤ 0."""
    return _unit(depth, 2)


def force_per_tension_um(volume: npt.ArrayLike, height: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """g = F_a/γ_a = 2 H A_c (µm; × mN/m gives nN) for volumes V (µm³) and gaps h (µm), broadcast."""
    radius = cell_radius(volume)
    return radius * unit_force_per_tension((2.0 * radius - np.asarray(height, float)) / radius)


def mean_curvature_per_um(volume: npt.ArrayLike, height: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """H (1/µm) for volumes V (µm³) and gaps h (µm), broadcast; 1/R_cell where h ≥ 2 R_cell."""
    radius = cell_radius(volume)
    return _unit((2.0 * radius - np.asarray(height, float)) / radius, 1) / radius
