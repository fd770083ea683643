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
- `Protocol(start_um, steps)` of `Ramp`, `Hold`, `Oscillate` steps: what the plate does
  (`solver.protocol`); `simulate(shell, cortex, protocol, resolution)` -> `Recording`: it run
  in time on the shell with a viscoelastic `Cortex` (`power_law_cortex`), at the `FINE` or the
  `REPLAY` resolution (`solver.protocol_simulation`, SPEC 12).
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
    from solver.protocol import Hold, Oscillate, Protocol, Ramp
    from solver.protocol_simulation import FINE, LINEARISED, REPLAY, Recording, Resolution, Sampling, simulate
    from solver.ramp import ramp_forces_nN
    from solver.time_domain import Cortex, power_law_cortex

__all__, __getattr__, __dir__ = lazy_exports(__name__, {
    "droplet": "solver.geometry", "Droplet": "solver.geometry", "cell_radius": "solver.geometry",
    "sphere_height": "solver.geometry", "profile": "solver.geometry",
    "Shell": "solver.model", "BENDING_VARIANTS": "solver.model",
    "compress": "solver.compression", "Compression": "solver.compression", "METHODS": "solver.compression",
    "effective_modulus": "solver.modulus", "ramp_forces_nN": "solver.ramp",
    **{name: "solver.protocol" for name in ("Protocol", "Ramp", "Hold", "Oscillate")},
    **{name: "solver.protocol_simulation" for name in ("simulate", "Recording", "Resolution", "Sampling",
                                                        "FINE", "REPLAY", "LINEARISED")},
    "Cortex": "solver.time_domain", "power_law_cortex": "solver.time_domain",
    "InputError": "common.errors", "SolverError": "common.errors", "WriteError": "common.errors",
})
