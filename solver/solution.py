"""What a solver returns: the plate force and the final shape of one compression.

Every solver (`solver.fast`, `solver.explicit`) fills a `Solution`;
`solver.compression` derives the effective modulus from it. Units: µm, µm²,
µm³, nN; stretches are dimensionless (`solver.frustum.nodal_stretches`).
"""

from dataclasses import dataclass

import numpy as np


@dataclass
class Solution:
    """What a solver computes. Arrays run along the upper half meridian from the
    pole on the plate (r = 0) to the equator; z is measured from the mid-plane."""

    force_nN: float           # F_tot, force on one plate
    volume_um3: float         # enclosed volume of the final shape
    area_um2: float           # total area of the final shape (both halves, contact discs included)
    area0_um2: float          # total area of the reference shape at h0, same mesh
    r_um: np.ndarray
    z_um: np.ndarray
    lambda1: np.ndarray       # meridional stretch ds/ds0 at the nodes
    lambda2: np.ndarray       # circumferential stretch r/r0 at the nodes
    converged: bool
    iterations: int
    message: str = ""
