"""The command groups of `cortex`, one module each: `shell` (geometry, compress,
poroelastic), `campaign`, `analysis`, `afm` and `doctor`. Each has a `register(commands)`
that adds its sub-commands with their handlers (functions of the same module, which
import the work only when the command runs); the shared options are in `cortex.options`,
the printing of results in `cortex.results`. No command module imports another."""
