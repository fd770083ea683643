"""The approach ramp: the plate force of an elastic shell pressed from its free sphere.

A cell of volume V (radius R = (3V/4π)^(1/3)) whose cortex is stress-free as
the free sphere is squeezed between plates at gap h = 2R - δ; δ (µm) is the
deformation, from 0 to about R. The shell is that of SPEC section 2 (energy
E = γ_a A + ∫ w dA0 + 2B ∫ (H - H0)² dA at constant volume, frictionless
contact), its plate force F(δ) = -dE*/dh the envelope derivative of the fast
solver (`solver.fast`). At δ → 0, F → 0; a tension-only shell (K_B = K_S =
B = 0) is the droplet, F = 2 γ_a H(h) A_c(h) (SPEC section 1), returned as
that (`solver.droplet_table`).

Reference height. The fast solver labels material by the droplet at h0, whose
contact disc has radius a0 = R_c(h0) → 0 at the sphere (and the mesh with
it), so the reference is the droplet at h0 = 2R (1 - SPHERE_GAP),
ε = 2R · SPHERE_GAP = 2e-6 R below the sphere: a sphere with flattened poles
of radius a0 ≈ 3e-4 R. Each depth is measured from the sphere, h = 2R - δ, so
the shell is compressed by δ - ε from its reference. Measured effect of ε
(R = 6.8 µm, K_B = 10, K_S = 5, γ_a = 0.5 mN/m): ten times this ε lowers F by
1.0e-3 at δ/R = 0.005, 4.6e-4 at 0.01, 1.6e-4 at 0.03, 4.5e-5 at 0.1 (about
as ε/δ), so this ε is within ~1e-4 of the exact sphere from δ/R = 0.005 on.

Continuation. The equilibria at the depths, in increasing order, are one path
of `solver.fast.advance` (adaptive plate steps of at most 0.015/H_d ≈ 0.015 R,
halved on a rejected step, the contact label found at each), each depth
started from the last, so a ramp of 50 depths costs one compression to the
deepest. Mesh: `resolution` (of `solver.model.Shell`; RESOLUTION by default)
is within 0.25 % of twice that resolution for δ/R 0.03-1 and 0.6 % for 0.01-0.03 over the
corners of the physiological range (docs/ramp.md, bench/ramp_solver.py).
"""

import dataclasses

import numpy as np
import numpy.typing as npt

from common.errors import InputError
from solver.droplet_table import force_per_tension_um
from solver.geometry import cell_radius
from solver.model import Shell

SPHERE_GAP = 1e-6     # reference gap h0 = 2R (1 - SPHERE_GAP)
RESOLUTION = 2.0      # the ramp's default mesh resolution (1 is the compressions' default)


def reference_height_um(volume_um3: float) -> float:
    """h0 = 2R (1 - SPHERE_GAP), the ramp's reference (module docstring), µm."""
    return float(2.0 * cell_radius(volume_um3) * (1.0 - SPHERE_GAP))


def _depths(volume_um3: float, depths_um: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """The depths as an array, or InputError unless increasing in (ε, 2R)."""
    depths = np.atleast_1d(np.asarray(depths_um, dtype=float))
    two_r = float(2.0 * cell_radius(volume_um3))
    eps = two_r - reference_height_um(volume_um3)
    if depths.ndim != 1 or depths.size == 0 or not np.all(np.isfinite(depths)):
        raise InputError("depths must be a non-empty list of finite numbers (um)")
    if np.any(np.diff(depths) <= 0) or depths[0] <= eps or depths[-1] >= two_r:
        raise InputError(f"depths must increase within ({eps:.3g}, {two_r:.4g}) um "
                         f"(the free sphere's diameter 2R; got {depths[0]:g} ... {depths[-1]:g})")
    return depths


def ramp_forces_nN(volume_um3: float, depths_um: npt.ArrayLike, bulk_mN_per_m: float,
                   shear_mN_per_m: float, tension_mN_per_m: float, bending: str = "standard",
                   thickness_um: float = 0.2, resolution: float = RESOLUTION,
                   bending_pN_um: float | None = None) -> npt.NDArray[np.float64]:
    """The plate force F (nN) at each deformation δ (µm, increasing) of the
    shell whose reference is the free sphere (module docstring), at gap
    h = 2R - δ. Moduli and bending as in `solver.model.Shell`. InputError for
    bad input, SolverError if the continuation stalls."""
    from solver import fast       # here: it loads numba

    depths = _depths(volume_um3, depths_um)
    h0 = reference_height_um(volume_um3)
    top = h0 / (1.0 - SPHERE_GAP)
    shell = Shell(volume_um3=float(volume_um3), h0_um=h0, dh_um=float(depths[-1] - (top - h0)),
                  bulk_mN_per_m=float(bulk_mN_per_m), shear_mN_per_m=float(shear_mN_per_m),
                  tension_mN_per_m=float(tension_mN_per_m), bending=bending,
                  bending_pN_um=bending_pN_um, thickness_um=float(thickness_um),
                  resolution=float(resolution))
    if shell.bulk_mN_per_m + shell.shear_mN_per_m == 0.0:
        if shell.bending_stiffness == 0.0:      # tension only: the droplet, exactly
            return shell.tension_mN_per_m * force_per_tension_um(shell.volume_um3, top - depths)
        return np.array([fast.solve(_at(shell, top - d)).force_nN for d in depths])
    lag = fast.problem(shell)
    u, h, step, last = fast.reference_state(lag), h0, None, None
    forces = np.empty(depths.size)
    for i, depth in enumerate(depths):
        u, _, step, last = fast.advance(lag, shell, u, h, top - depth, step, last)
        h = top - depth
        forces[i] = fast.plate_force_nN(lag, u, h)
    return forces


def _at(shell: Shell, h1_um: float) -> Shell:
    """`shell` compressed to the gap h1 instead."""
    return dataclasses.replace(shell, dh_um=shell.h0_um - h1_um)
