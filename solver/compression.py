"""One compression h0 -> h1 of the cortical shell, whichever solver computes it.

A solver (`solver.fast`, `solver.explicit`) returns a `Solution`: the plate
force and the final shape. `compress` turns that into a `Compression`, adding
the effective modulus of SPEC section 3 (from the droplet geometry, via
`solver.modulus`), the volume error |V - V0| / V0, the simulated shell's area
increase next to the droplet estimate, and the equator's shear-to-dilation
ratio |e1 - e2| / (e1 + e2) with e_i = λ_i - 1. A shell with a viscosity and a
frequency also gets the complex modulus K*(ω) of `solver.viscous` (|K*| as
`modulus_mN_per_m`, the secant K above as `compression_modulus_mN_per_m`).

`METHODS` is the table of solvers by name (`common.names.SOLVERS`): one
function each, which imports its solver when first called, so importing
this module loads no numba.
"""

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from common.errors import InputError
from common.names import SOLVERS
from solver.model import Shell
from solver.modulus import effective_modulus
from solver.solution import Solution


def solve_fast(shell: Shell) -> Solution:
    """The fast solver, `solver.fast.solve` (imported here, on first use: it loads numba)."""
    from solver.fast import solve
    return solve(shell)


def solve_explicit(shell: Shell) -> Solution:
    """The explicit reference scheme, `solver.explicit.solve` (imported on first use)."""
    from solver.explicit import solve
    return solve(shell)


def warm_up_fast(shell: Shell) -> None:
    """`solver.fast.warm_up`: the fast solver's compiled functions loaded by one solve."""
    from solver.fast import warm_up
    warm_up(shell)


def warm_up_explicit(shell: Shell) -> None:
    """`solver.explicit` imported: it has no warm-up of its own (a solve takes minutes)."""
    import solver.explicit  # noqa: F401


METHODS: dict[str, Callable[[Shell], Solution]] = dict(zip(SOLVERS, (solve_fast, solve_explicit)))
WARM_UPS: dict[str, Callable[[Shell], None]] = dict(zip(SOLVERS, (warm_up_fast, warm_up_explicit)))


@dataclass
class Compression:
    """A finished compression: the model, its solution and the derived numbers."""

    shell: Shell
    method: str
    solution: Solution
    wall_s: float
    derived: dict[str, float] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """Scalars with the interface's JSON keys (units in the names)."""
        s = self.solution
        out = {"method": self.method, "force_nN": float(s.force_nN)}
        out.update({k: float(v) for k, v in self.derived.items()})
        out.update(converged=bool(s.converged), iterations=int(s.iterations),
                   wall_s=float(self.wall_s))
        return out


def equator_shear_ratio(lambda1: npt.NDArray[np.float64], lambda2: npt.NDArray[np.float64]) -> float:
    """|e1 - e2| / (e1 + e2) at the equator (the last node)."""
    e1, e2 = lambda1[-1] - 1.0, lambda2[-1] - 1.0
    return abs(e1 - e2) / (e1 + e2) if e1 + e2 != 0 else float("nan")


def compress(shell: Shell, method: str = "fast") -> Compression:
    """Solve one compression with `method` (`fast` or `explicit`)."""
    if method not in METHODS:
        raise InputError(f"solver must be one of {', '.join(METHODS)} (got {method!r})")
    if shell.viscosity_Pa_s is not None and method != "fast":     # refused before any work
        raise InputError("a viscous cell needs the fast solver (its linear response uses the Hessian)")
    solve = METHODS[method]
    start = time.perf_counter()
    sol = solve(shell)
    wall = time.perf_counter() - start
    modulus = effective_modulus(shell.volume_um3, shell.h0_um, shell.h1_um,
                                shell.tension_mN_per_m, sol.force_nN)
    derived = {k: float(v) for k, v in modulus.items()}
    derived["area_strain_shell"] = (sol.area_um2 - sol.area0_um2) / sol.area0_um2
    derived["volume_error"] = abs(sol.volume_um3 - shell.volume_um3) / shell.volume_um3
    derived["equator_shear_ratio"] = equator_shear_ratio(sol.lambda1, sol.lambda2)
    if shell.viscosity_Pa_s is not None:        # the oscillated viscous cell (solver.viscous)
        from solver.viscous import viscous_keys     # only here: it loads scikit-fem
        derived["compression_modulus_mN_per_m"] = derived["modulus_mN_per_m"]
        derived.update(viscous_keys(shell))
    return Compression(shell=shell, method=method, solution=sol, wall_s=wall, derived=derived)


def warm_up(shell: Shell, method: str) -> None:
    """Import `method`'s solver and load what it compiles before the first
    timed compression (`WARM_UPS`: the fast solver solves `shell` once and
    throws the result away)."""
    WARM_UPS[method](shell)
