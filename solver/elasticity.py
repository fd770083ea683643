"""The isotropic cortex's elastic constants and how they relate (SPEC section 2).

An isotropic shell of thickness t and Young's modulus E has the area bulk and
shear moduli

    K_B = t E / (2(1 - ν)),     K_S = t E / (2(1 + ν)),

so the Poisson ratio and the shear-to-bulk ratio K̃_S = K_S / K_B determine
each other:

    ν = (K_B - K_S) / (K_B + K_S) = (1 - K̃_S) / (1 + K̃_S),
    K̃_S = (1 - ν) / (1 + ν),      K_S = K_B (1 - ν) / (1 + ν),

and its bending stiffness is B = t³ E / (24 (1 - ν²)) = t² (K_B + K_S) / 24
(the `standard` variant; SPEC's `double` is 2B, `none` is 0).

Units: moduli in mN/m, t in µm, B in mN/m·µm². Every function takes scalars
or numpy arrays.
"""

from typing import TypeVar

import numpy as np
import numpy.typing as npt

Num = TypeVar("Num", float, npt.NDArray[np.float64])    # a number, or an array of them: returned alike


def poisson_ratio(bulk: Num, shear: Num) -> Num:
    """ν = (K_B - K_S) / (K_B + K_S) from the two moduli (mN/m)."""
    return (bulk - shear) / (bulk + shear)


def poisson_of_ratio(ks_tilde: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """ν = (1 - K̃_S) / (1 + K̃_S) from the ratio K̃_S = K_S / K_B (array in, array out)."""
    ks_tilde = np.asarray(ks_tilde, float)
    return (1.0 - ks_tilde) / (1.0 + ks_tilde)


def shear_ratio(nu: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """K̃_S = (1 - ν) / (1 + ν), the inverse of `poisson_of_ratio`."""
    nu = np.asarray(nu, float)
    return (1.0 - nu) / (1.0 + nu)


def shear_ratio_slope(nu: Num) -> Num:
    """|dK̃_S/dν| = 2 / (1 + ν)², the Jacobian that maps a density of K̃_S to one of ν."""
    return 2.0 / (1 + nu) ** 2


def shear_modulus(nu: Num, bulk: Num) -> Num:
    """K_S = K_B (1 - ν) / (1 + ν) (mN/m) for a Poisson ratio ν and a bulk modulus K_B."""
    return bulk * (1 - nu) / (1 + nu)


def bending_stiffness(thickness: Num, bulk: Num, shear: Num) -> Num:
    """B = t² (K_B + K_S) / 24 (mN/m·µm², t in µm): the `standard` variant's B."""
    return thickness**2 * (bulk + shear) / 24.0
