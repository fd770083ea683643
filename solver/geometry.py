"""The droplet shape: a cell of volume V between parallel plates a gap h apart,
with no elastic stress (SPEC section 1).

The free surface has constant mean curvature H and meets both plates
tangentially on contact discs of radius R_c; its widest radius R_eq is at
mid-height. Force balance at the equator gives

    H = R_eq / (R_eq² - R_c²),

and along the free surface (ψ the tangent angle to the plate, 0 at the contact
line, π/2 at the equator) the first integral is r sin ψ = H (r² - R_c²), so

    r(ψ)    = (sin ψ + q) / (2H),              q = sqrt(sin² ψ + β²),  β = 2 H R_c,
    dr/dψ   = cos ψ (1 + sin ψ / q) / (2H),
    dz/dψ   = sin ψ (1 + sin ψ / q) / (2H),
    ds/dψ   = (1 + sin ψ / q) / (2H).

Parametrising by ψ instead of r removes the square-root singularity at the
equator: every integrand is smooth. Half the height, half the volume and half
the free area are

    h/2 = ∫ dz,   V/2 = ∫ π r² dz,   A_free/2 = ∫ 2π r ds    (ψ from 0 to π/2),

evaluated by composite Gauss-Legendre quadrature (12 points) on [0, lo],
lo = β/8, and on intervals from lo growing geometrically by at most a factor
2 (as few as that allows, at most 24) up to the end: the integrands' only
singularities near the path are at ψ = ±i asinh β, where sin ψ / q turns over
on the scale β (tiny near the free sphere), and on [a, 2a] they lie far
enough outside Gauss-Legendre's ellipse that the error is below round-off. The arc length has a closed form,
s(ψ) = [ψ + asin(1/√(1+β²)) - asin(cos ψ/√(1+β²))] / (2H).

With R_eq = 1 the shape depends on k = R_c / R_eq alone, so the normalised
height h̃ = h / (2 R_cell), R_cell = (3V/4π)^(1/3), is a function of k. Given
(V, h), k solves h̃(k) = h / (2 R_cell): a tabulated inverse gives the start,
one or two Newton steps finish it (`_solve`); then R_eq = h / η(k) with η = h/R_eq.

Total area A = A_free + 2π R_c² (the cortex covers both contact discs);
contact area A_c = π R_c²; the force of a tension-only cell on each plate
F_a = 2 γ_a H A_c, so `force_per_tension_um` = 2 H A_c (µm; × mN/m gives nN).

Everything is vectorised over arrays of volumes and heights (broadcast); the
quadrature and the solve for k are compiled (`solver.droplet_quadrature`).
Units: µm, µm², µm³, 1/µm.
"""

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import numpy.typing as npt

from common.errors import InputError

_GL_X, _GL_W = np.polynomial.legendre.leggauss(12)
_INTERVALS = 24          # most geometric intervals from β/8 to the upper limit
_GROWTH = 2.0            # largest size ratio of neighbouring intervals
_K_MAX = 0.995           # h̃ ≈ 0.026: far flatter than any cell is squeezed


def _quadrature():
    """The compiled numerics (`solver.droplet_quadrature`), imported with
    numba when a shape is first integrated: a command that never integrates
    one (reading a campaign file, a campaign of no-op tasks) does not pay
    numba's import (0.3-0.6 s)."""
    from solver import droplet_quadrature
    return droplet_quadrature


def cell_radius(volume: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """R_cell = (3V / 4π)^(1/3), µm."""
    return np.cbrt(3.0 * np.asarray(volume, float) / (4.0 * np.pi))


def sphere_height(volume: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """The free sphere's diameter 2 R_cell, the largest possible gap, µm."""
    return 2.0 * cell_radius(volume)


def _half_integrals(k, psi_end=None):
    """For R_eq = 1 and R_c = k: height, volume and free area from the contact
    line (ψ = 0) up to ψ_end (default the equator), each for one half, by
    composite Gauss-Legendre quadrature in ψ (`droplet_quadrature.integrate`)."""
    k = np.asarray(k, float)
    psi_end = np.full_like(k, np.pi / 2) if psi_end is None else np.asarray(psi_end, float)
    k, psi_end = np.broadcast_arrays(k, psi_end)
    out = _quadrature().integrate(np.ascontiguousarray(k).ravel(), np.ascontiguousarray(psi_end).ravel(),
                                  _GL_X, _GL_W, _INTERVALS, _GROWTH)
    return tuple(x.reshape(k.shape) for x in out)


def _h_tilde_of_k(k):
    """h̃ as a function of k = R_c/R_eq (shape only, scale free)."""
    z, vol, _ = _half_integrals(k)
    return _quadrature().height_ratio(z, vol)


@lru_cache(maxsize=1)
def _inverse_table():
    """The table (u, k) of k(u) with u = sqrt(1 - h̃), k smooth in u at the
    sphere (k ∝ u there): 801 shapes, dense near both ends."""
    t = np.linspace(0.0, 1.0, 801)
    k = _K_MAX * np.sin(0.5 * np.pi * t) ** 1.5
    u = np.sqrt(np.clip(1.0 - _h_tilde_of_k(k), 0.0, None))
    return u, k


def _solve(h_tilde):
    """k with h̃(k) = h_tilde, and that shape's half integrals (z, V, A) to the
    equator, each the shape of h_tilde: a start from the cubic through the four
    table points (u, k) around u = sqrt(1 - h̃) (accurate to O(h⁴) like a
    spline; the start is within ~1e-11 of k for h̃ < 0.95), then Newton steps on
    u with the cubic's slope; a step that moves k by less than 1e-9 (relative)
    leaves it converged to round-off, so a second step is taken only where the
    first moved k more (near the sphere). Compiled, one shape at a time
    (`droplet_quadrature.solve`)."""
    table_u, table_k = _inverse_table()
    h = np.asarray(h_tilde, float)
    out = _quadrature().solve(np.ravel(h), table_u, table_k, _K_MAX, _GL_X, _GL_W, _INTERVALS, _GROWTH)
    return tuple(x.reshape(h.shape) for x in out)


def _check(volume, height):
    volume = np.asarray(volume, float)
    height = np.asarray(height, float)
    if not (np.all(np.isfinite(volume)) and np.all(np.isfinite(height))):
        raise InputError("volume and height must be finite numbers (got NaN or inf)")
    if np.any(volume <= 0):
        raise InputError(f"volume must be > 0 um^3 (got {volume.min():g})")
    if np.any(height <= 0):
        raise InputError(f"height must be > 0 um (got {height.min():g})")
    top = sphere_height(volume)
    over = height > top * (1.0 + 1e-12)
    if np.any(over):
        i = np.flatnonzero(np.broadcast_to(over, np.broadcast(volume, height).shape).ravel())[0]
        hb, vb = np.broadcast_arrays(height, volume)
        raise InputError(
            f"height {hb.ravel()[i]:g} um exceeds the free sphere's diameter "
            f"{sphere_height(vb.ravel()[i]):.6g} um for volume {vb.ravel()[i]:g} um^3")
    return np.broadcast_arrays(volume, np.minimum(height, top))


@dataclass(frozen=True)
class Droplet:
    """The droplet shape's numbers (arrays broadcast over volume and height)."""

    height_um: np.ndarray
    volume_um3: np.ndarray
    contact_radius_um: np.ndarray        # R_c
    equator_radius_um: np.ndarray        # R_eq
    mean_curvature_per_um: np.ndarray    # H
    surface_area_um2: np.ndarray         # A = A_free + 2 π R_c²
    contact_area_um2: np.ndarray         # A_c = π R_c²
    force_per_tension_um: np.ndarray     # F_a / γ_a = 2 H A_c
    free_area_um2: np.ndarray            # A_free
    cell_radius_um: np.ndarray           # R_cell
    h_tilde: np.ndarray                  # h / (2 R_cell)

    JSON_KEYS = ("height_um", "volume_um3", "contact_radius_um", "equator_radius_um",
                 "mean_curvature_per_um", "surface_area_um2", "contact_area_um2",
                 "force_per_tension_um")

    def row(self, i: int | tuple[int, ...] = ()) -> dict[str, float]:
        """One shape as a dict of floats with the interface's JSON keys."""
        return {key: float(np.asarray(getattr(self, key))[i]) for key in self.JSON_KEYS}


def droplet(volume: npt.ArrayLike, height: npt.ArrayLike) -> Droplet:
    """Solve the droplet shape for volume V (µm³) and plate gap h (µm).

    Raises InputError for V ≤ 0, h ≤ 0, h above the free sphere's diameter
    2 R_cell, NaN or inf. Heights below h̃ ≈ 0.026 are refused too (the cell
    would be a thin pancake, far outside the model's range). One (V, h) is
    solved once per process and kept (`_droplet_one`)."""
    if np.ndim(volume) == 0 and np.ndim(height) == 0:
        return _droplet_one(float(volume), float(height))  # type: ignore[arg-type]  # 0-d: numbers
    return _droplet(volume, height)


@lru_cache(maxsize=4096)
def _droplet_one(volume, height):
    """`droplet` of one (V, h), kept: every compression asks for the shapes
    at h0 and h1 (its modulus, the fast solver's contact prediction), and a
    campaign for the same few gaps again and again. Its arrays are read-only,
    as every caller shares them. (An invalid input raises every time: an
    exception is not kept.)"""
    d = _droplet(volume, height)
    for value in vars(d).values():
        if isinstance(value, np.ndarray):
            value.setflags(write=False)
    return d


def _droplet(volume, height):
    """`droplet` computed (module docstring)."""
    volume, height = _check(volume, height)
    R_cell = cell_radius(volume)
    h_tilde = height / (2.0 * R_cell)
    k, z, vol, area = _solve(h_tilde)
    if np.any(k >= _K_MAX):
        raise InputError(f"height too small: h/(2 R_cell) = {h_tilde.min():.3g} is below "
                         f"{_h_tilde_of_k(np.array(_K_MAX)):.3g}, the flattest shape supported")
    R_eq = height / (2.0 * z)
    R_c = k * R_eq
    H = 1.0 / (R_eq * (1.0 - k * k))
    A_c = np.pi * R_c**2
    A_free = 2.0 * area * R_eq**2
    return Droplet(height_um=height, volume_um3=volume, contact_radius_um=R_c,
                   equator_radius_um=R_eq, mean_curvature_per_um=H,
                   surface_area_um2=A_free + 2.0 * A_c, contact_area_um2=A_c,
                   force_per_tension_um=2.0 * H * A_c, free_area_um2=A_free,
                   cell_radius_um=R_cell, h_tilde=h_tilde)


def volume_from_image(height: float, equator_radius: float) -> float:
    """The volume V (µm³) of the droplet of gap h and equatorial radius R_eq (µm),
    as an image of a confined cell measures them.

    With R_eq = 1 the shape is k = R_c/R_eq alone: its half height z(k) falls
    from 1 at the free sphere (k = 0) to 0 as the cell flattens, so k solves
    2 z(k) = h / R_eq (Brent's method on [0, k_max]) and V = 2 v(k) R_eq³, v the
    half volume. Raises InputError for h or R_eq not positive and finite, h
    above the sphere's 2 R_eq, or a shape flatter than `droplet` supports."""
    h, r = float(height), float(equator_radius)
    if not (np.isfinite(h) and np.isfinite(r) and h > 0 and r > 0):
        raise InputError(f"height and equator radius must be positive numbers of um (got {h:g}, {r:g})")
    eta = h / r
    if eta > 2.0 * (1.0 + 1e-12):
        raise InputError(f"height {h:g} um exceeds twice the equator radius {r:g} um (a free sphere's is 2 R_eq)")

    def half_height(k):
        return float(_half_integrals(k)[0]) - eta / 2.0

    if half_height(_K_MAX) > 0:
        raise InputError(f"height {h:g} um against equator radius {r:g} um: flatter than the flattest "
                         "shape supported")
    from scipy.optimize import brentq
    k = 0.0 if eta >= 2.0 else brentq(half_height, 0.0, _K_MAX, xtol=1e-14)
    return 2.0 * float(_half_integrals(k)[1]) * r**3


def meridian(volume: float, height: float, psi: npt.ArrayLike) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """The upper free surface at tangent angles ψ (0 at the contact line, π/2 at
    the equator) of the shape for one (V, h): returns (r, z, s) in µm with z
    measured from the mid-plane (h/2 at the plate, 0 at the equator) and s the
    arc length from the contact line. The lower half is its mirror image.
    At ψ = π/2 z is 0 by definition (the rise there is h/2), not the
    quadrature's round-off of it."""
    d = droplet(float(volume), float(height))
    R_eq, H = float(d.equator_radius_um), float(d.mean_curvature_per_um)
    k = float(d.contact_radius_um) / R_eq
    psi = np.asarray(psi, float)
    if np.any((psi < 0) | (psi > np.pi / 2 + 1e-15)):
        raise InputError("tangent angles must lie in [0, pi/2]")
    beta = 2.0 * H * float(d.contact_radius_um)
    s_ = np.sin(psi)
    q = np.sqrt(s_ * s_ + beta * beta)
    r = (s_ + q) / (2.0 * H)
    rise, _, _ = _half_integrals(np.full(psi.shape, k), np.clip(psi, 1e-300, None))
    z = np.where(psi >= np.pi / 2, 0.0, float(height) / 2.0 - rise * R_eq)
    m = np.sqrt(1.0 + beta * beta)
    s = (psi + np.arcsin(1.0 / m) - np.arcsin(np.cos(psi) / m)) / (2.0 * H)
    return r, z, s


def profile(volume: float, height: float, n: int = 201) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """The whole free surface r(z) from the lower plate (z = 0) to the upper
    plate (z = h), n points (odd n puts one at the equator), µm."""
    half = (n + 1) // 2
    psi = np.linspace(0.0, np.pi / 2, half)
    r, z, _ = meridian(volume, height, psi)
    z_up = float(height) / 2.0 + z            # from the lower plate
    r_all = np.concatenate([r, r[::-1][1:] if n % 2 else r[::-1]])
    z_all = np.concatenate([float(height) - z_up, z_up[::-1][1:] if n % 2 else z_up[::-1]])
    return r_all, z_all
