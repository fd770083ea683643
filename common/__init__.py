"""The base every package may import: the error types and exit statuses
(`common.errors`), the lazy public names of a package (`common.lazy_exports`)
and the name lists the command line offers as choices (`common.names`).
Nothing here imports numpy, so `cortex --help` stays fast."""

from common.lazy_exports import lazy_exports

__all__, __getattr__, __dir__ = lazy_exports(__name__, {
    "InputError": "common.errors", "SolverError": "common.errors", "WriteError": "common.errors",
    "is_write_failure": "common.errors", "exit_status_table": "common.errors", "EXIT_STATUSES": "common.errors",
    "lazy_exports": "common.lazy_exports",
    "BENDINGS": "common.names", "SOLVERS": "common.names", "INVERSION_METHODS": "common.names",
    "RAMP_MODELS": "common.names",
})
