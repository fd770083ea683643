"""The approach ramp: the plate force of an elastic shell pressed from its free sphere.

A cell of volume V (radius R = (3V/4π)^(1/3)) whose cortex is stress-free as
the free sphere is squeezed between plates at gap h = 2R - δ; δ (µm) is the
deformation, from 0 to about R. The shell is that of SPEC section 2 (energy
E = γ_a A + ∫ w dA0 + 2B ∫ (H - H0)² dA at constant volume, frictionless
contact), its plate force F(δ) = -dE*/dh the envelope derivative of the fast
solver (`solver.fast`). At δ → 0, F → 0; a tension-only shell gives the
droplet's F = 2 γ_a H(h) A_c(h) (SPEC section 1).

Reference height. The fast solver labels material by the droplet at h0, whose
contact disc has radius a0 → 0 at the sphere, so the reference is the droplet
at h0 = 2R (1 - SPHERE_GAP): ε = 2 R · SPHERE_GAP = 2e-6 R below the sphere
(a0 ≈ 2e-4 R... 1e-3 R), a sphere with flattened poles of depth ε/2. Each
depth is measured from the sphere, h = 2R - δ, so the shell is compressed by
δ - ε from its reference. Measured effect of ε (ten times larger against
this one): 0.1 % on F at δ/R = 0.005, 5e-5 at δ/R = 0.1, falling as ε/δ; at
this ε it is ten times smaller.

Continuation. The equilibria at the depths, in increasing order, are one path
of `solver.fast.advance` (adaptive plate steps of at most 0.015/H_d ≈ 0.015 R,
halved on a rejected step, the contact label found at each), each depth
started from the last, so a ramp of 50 depths costs one compression to the
deepest. Mesh: `resolution` (of `solver.model.Shell`; RESOLUTION by default)
changes F by < 0.5 % against twice that resolution over δ/R 0.01-1 (docs/ramp.md).
"""

import numpy as np
import numpy.typing as npt

from common.errors import InputError
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
    if shell.bulk_mN_per_m + shell.shear_mN_per_m == 0.0:    # tension-only: each depth on its own
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
    return Shell(**{**shell.to_dict(), "dh_um": shell.h0_um - h1_um})
