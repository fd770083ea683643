"""The exception types that say *whose* fault a stop is, and the exit statuses
every `cortex` command maps them to (one table, shown in the README and in
each `--help`).

| status | meaning                                                        |
|--------|----------------------------------------------------------------|
| 0      | done                                                           |
| 1      | done, but some tasks (or cells) failed: see the report/status  |
| 2      | bad input: a malformed file, an impossible parameter, a path   |
|        | that is not ours to write; nothing was written                 |
| 3      | stopped by a signal (SIGTERM/SIGINT): rerun the same command   |
|        | to resume                                                      |
| 4      | no equilibrium found (a solver did not converge)               |
| 5      | could not write (disk full, quota, I/O error): free space, then|
|        | rerun the same command to resume                               |

The command line turns `InputError` into one line on stderr and status 2,
`SolverError` into status 4 and `WriteError` (or an `OSError` with ENOSPC,
EDQUOT or EIO) into status 5; every package raises them (or a subclass).
"""

import errno

EXIT_DONE = 0
EXIT_SOME_FAILED = 1
EXIT_BAD_INPUT = 2
EXIT_SIGNAL = 3
EXIT_NO_EQUILIBRIUM = 4
EXIT_WRITE_FAILED = 5

EXIT_STATUS_HELP = ("exit status: 0 done; 1 some tasks or cells failed; 2 bad input (nothing written); "
                    "3 stopped by a signal (rerun to resume); 4 no equilibrium found; "
                    "5 could not write (free space, then rerun to resume)")

WRITE_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EIO, errno.EFBIG, errno.EROFS})


class InputError(ValueError):
    """Bad input from a user: an impossible parameter, a malformed file, an
    output path that is not ours to overwrite."""


class SolverError(RuntimeError):
    """A solve that did not converge: the message says why."""


class WriteError(OSError):
    """A write that failed for want of room (or an I/O error): the message
    names the file and says to free space and rerun to resume."""


def is_write_failure(err):
    """True for an OSError that a full or failing disk raises (ENOSPC, EDQUOT, EIO, ...)."""
    return isinstance(err, WriteError) or (isinstance(err, OSError) and err.errno in WRITE_ERRNOS)
