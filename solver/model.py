"""One compression of the elastic cortical shell (SPEC section 2), as data.

Isotropic material of thickness t_c (`solver.elasticity`): ν = (K_B - K_S)/(K_B + K_S),
bending stiffness B = t_c² (K_B + K_S) / 24 for the `standard` variant, 2B for
`double`, 0 for `none` (`BENDING_VARIANTS`), or given explicitly.

Units: µm, mN/m; B internally in mN/m·µm² (= 1e-15 J = 1000 pN·µm).
"""

import math
from collections.abc import Iterable
from dataclasses import MISSING, dataclass, fields
from functools import lru_cache

import numpy as np

from solver.elasticity import bending_stiffness, poisson_ratio
from common.errors import InputError
from solver.geometry import sphere_height
from common.names import BENDINGS

BENDING_VARIANTS = dict(zip(BENDINGS, (1.0, 2.0, 0.0)))   # name -> factor on B
PN_UM_PER_MN_PER_M_UM2 = 1000.0   # 1 mN/m·µm² = 1000 pN·µm


@dataclass(frozen=True)
class Shell:
    """Everything that defines one compression h0 -> h1 = h0 - Δh.

    volume_um3, h0_um, dh_um: cell volume V, initial gap h0, compression Δh.
    bulk_mN_per_m, shear_mN_per_m: area bulk and shear moduli K_B, K_S (0 allowed).
    tension_mN_per_m: active tension γ_a (> 0).
    bending: `standard`, `double` or `none`; bending_pN_um, if given, overrides it.
    thickness_um: t_c.  resolution: mesh refinement factor (1 = default, the
    resolution at which K is converged to 0.1 %; 2 halves every element).
    viscosity_Pa_s, frequency_hz: a viscous interior oscillated at f around
    h0 - Δh/2 (`solver.viscous`), both or neither; left out of `to_dict` when
    not given, so an elastic cell's identity (campaign task ids) is unchanged."""

    volume_um3: float
    h0_um: float
    bulk_mN_per_m: float
    shear_mN_per_m: float
    tension_mN_per_m: float
    dh_um: float = 0.5
    bending: str = "standard"
    bending_pN_um: float | None = None
    thickness_um: float = 0.2
    resolution: float = 1.0
    viscosity_Pa_s: float | None = None
    frequency_hz: float | None = None

    def __post_init__(self):
        for name in ("volume_um3", "h0_um", "dh_um", "bulk_mN_per_m", "shear_mN_per_m",
                     "tension_mN_per_m", "thickness_um", "resolution"):
            value = getattr(self, name)
            if not isinstance(value, (int, float, np.floating, np.integer)) or not math.isfinite(value):
                raise InputError(f"{name} must be a finite number (got {value!r})")
        if self.volume_um3 <= 0:
            raise InputError(f"volume must be > 0 um^3 (got {self.volume_um3:g})")
        if self.h0_um <= 0 or self.dh_um <= 0:
            raise InputError(f"h0 and dh must be > 0 um (got h0={self.h0_um:g}, dh={self.dh_um:g})")
        if self.dh_um >= self.h0_um:
            raise InputError(f"dh = {self.dh_um:g} um must be smaller than h0 = {self.h0_um:g} um")
        top = _sphere_height(self.volume_um3)
        if self.h0_um > top:
            raise InputError(f"h0 = {self.h0_um:g} um exceeds the free sphere's diameter "
                             f"{top:.4g} um for V = {self.volume_um3:g} um^3")
        if self.bulk_mN_per_m < 0 or self.shear_mN_per_m < 0:
            raise InputError("moduli K_B and K_S must be >= 0 mN/m")
        if self.tension_mN_per_m <= 0:
            raise InputError(f"active tension must be > 0 mN/m (got {self.tension_mN_per_m:g})")
        if self.bending not in BENDING_VARIANTS:
            raise InputError(f"bending must be one of {', '.join(BENDING_VARIANTS)} "
                             f"(got {self.bending!r})")
        if self.bending_pN_um is not None and not (np.isfinite(self.bending_pN_um)
                                                   and self.bending_pN_um >= 0):
            raise InputError("bending stiffness must be >= 0 pN um")
        if self.thickness_um <= 0 or self.resolution <= 0:
            raise InputError("thickness and resolution must be > 0")
        if (self.viscosity_Pa_s is None) != (self.frequency_hz is None):
            raise InputError("viscosity and frequency go together (a viscous cell needs both)")
        if self.viscosity_Pa_s is not None and self.frequency_hz is not None:
            check_viscous_inputs(self.viscosity_Pa_s, self.frequency_hz)

    @property
    def h1_um(self) -> float:
        return self.h0_um - self.dh_um

    @property
    def bending_stiffness(self) -> float:
        """B in mN/m·µm²: t_c² (K_B + K_S)/24 times the variant's factor."""
        if self.bending_pN_um is not None:
            return self.bending_pN_um / PN_UM_PER_MN_PER_M_UM2
        base = bending_stiffness(self.thickness_um, self.bulk_mN_per_m, self.shear_mN_per_m)
        return BENDING_VARIANTS[self.bending] * base

    @property
    def poisson_ratio(self) -> float:
        """ν = (K_B - K_S)/(K_B + K_S); NaN for a tension-only cell."""
        if self.bulk_mN_per_m + self.shear_mN_per_m > 0:
            return poisson_ratio(self.bulk_mN_per_m, self.shear_mN_per_m)
        return float("nan")

    @classmethod
    def unchecked(cls, *parts: dict[str, object] | Iterable[tuple[str, object]]) -> "Shell":
        """A shell of the fields in `parts` (dicts or (name, value) pairs, the
        later winning), its other fields at their defaults, made without the
        checks of `__init__`: for values checked another way (`campaign.grid`
        checks a grid on a cover of its points). 0.5 µs instead of 3.4 µs."""
        shell = object.__new__(cls)
        fields_ = shell.__dict__
        fields_.update(_DEFAULTS)
        for part in parts:
            fields_.update(part)
        return shell

    def to_dict(self) -> dict[str, object]:
        """The fields as a dict (the viscous two left out when not given). The
        fields are plain numbers and a name, so no deep copy (`dataclasses.asdict`,
        ten times slower) is needed: a campaign calls this for every task."""
        out = {name: getattr(self, name) for name in _FIELDS}
        for key in ("viscosity_Pa_s", "frequency_hz"):
            if out[key] is None:
                del out[key]
        return out


_FIELDS = tuple(f.name for f in fields(Shell))
_DEFAULTS = {f.name: f.default for f in fields(Shell) if f.default is not MISSING}


@lru_cache(maxsize=64)
def _sphere_height(volume_um3):
    """`solver.geometry.sphere_height` as a float, once per volume: a campaign
    checks every one of its (up to 10^5) shells, and a grid has few volumes."""
    return float(sphere_height(volume_um3))


def check_viscous_inputs(viscosity_Pa_s: float, frequency_hz: float) -> None:
    """η ≥ 0 and f > 0, finite, or InputError."""
    for name, value, zero in (("viscosity", viscosity_Pa_s, True), ("frequency", frequency_hz, False)):
        if not np.isfinite(value) or value < 0 or (value == 0 and not zero):
            raise InputError(f"{name} must be a finite number {'>=' if zero else '>'} 0 "
                             f"({'Pa s' if zero else 'Hz'}; got {value:g})")
