"""Physics only: droplet geometry, the elastic shell model, its solvers and the
effective modulus. Imports nothing of `campaign` or `analysis`; no MPI, no files.

Public API (imported on first use):

- `droplet(V, h)` -> `Droplet`: the stress-free confined shape (SPEC 1);
  `cell_radius(V)`, `sphere_height(V)`.
- `Shell(...)`: one compression's parameters (SPEC 2); `BENDING_VARIANTS`
  (name -> factor on B).
- `compress(shell, method)` -> `Compression` (force, K, stretches); `METHODS`,
  the solvers by name (`--solver` on the command line, `[solver] method` in a
  campaign file): `solver/fast/` and `solver/explicit/`.
- `effective_modulus(V, h0, h1, gamma_a, F)`: SPEC 3.
- `ramp_forces_nN(V, depths, K_B, K_S, gamma_a, bending)`: the plate force of
  the shell pressed from its free sphere to each depth (`solver.ramp`).
- `InputError`, `SolverError`, `WriteError` and the `EXIT_*` statuses live in
  `common.errors`.
"""

from typing import TYPE_CHECKING

from common.lazy_exports import lazy_exports

if TYPE_CHECKING:     # what editors and the type checker see; at run time each is imported on first use
    from common.errors import InputError, SolverError, WriteError
    from solver.compression import METHODS, Compression, compress
    from solver.geometry import Droplet, cell_radius, droplet, profile, sphere_height
    from solver.model import BENDING_VARIANTS, Shell
    from solver.modulus import effective_modulus
    from solver.ramp import ramp_forces_nN

__all__, __getattr__, __dir__ = lazy_exports(__name__, {
    "droplet": "solver.geometry", "Droplet": "solver.geometry", "cell_radius": "solver.geometry",
    "sphere_height": "solver.geometry", "profile": "solver.geometry",
    "Shell": "solver.model", "BENDING_VARIANTS": "solver.model",
    "compress": "solver.compression", "Compression": "solver.compression", "METHODS": "solver.compression",
    "effective_modulus": "solver.modulus", "ramp_forces_nN": "solver.ramp",
    "InputError": "common.errors", "SolverError": "common.errors", "WriteError": "common.errors",
})
