"""The exception types that say *whose* fault a stop is, and the exit statuses
every `cortex` command maps them to.

`EXIT_STATUSES` is the one table of (status, meaning): every `--help` ends
with it (`EXIT_STATUS_HELP`) and docs/cli.md shows it (`exit_status_table()`,
checked by tests/test_exit_statuses.py). The command line turns `InputError`
into one line on stderr and status 2, `SolverError` into status 4 and
`WriteError` (or an `OSError` with ENOSPC, EDQUOT or EIO) into status 5;
every package raises them (or a subclass).
"""

import errno

EXIT_DONE = 0
EXIT_SOME_FAILED = 1
EXIT_BAD_INPUT = 2
EXIT_SIGNAL = 3
EXIT_NO_EQUILIBRIUM = 4
EXIT_WRITE_FAILED = 5

EXIT_STATUSES = (
    (EXIT_DONE, "done"),
    (EXIT_SOME_FAILED, "done, but some tasks (or cells) failed: see the report or `cortex campaign status` "
                       "(`campaign run --retry-failed` reruns them); `campaign verify`: damaged rows found "
                       "(`campaign repair` rewrites them)"),
    (EXIT_BAD_INPUT, "bad input: a malformed file, an impossible parameter, a path that is not ours to write "
                     "(nothing was written)"),
    (EXIT_SIGNAL, "stopped by a signal (SIGTERM, SIGINT/Ctrl-C): rerun the same command to resume"),
    (EXIT_NO_EQUILIBRIUM, "no equilibrium found (`cortex compress`: the solver did not converge)"),
    (EXIT_WRITE_FAILED, "could not write (disk full, quota, I/O error): free space, then rerun the same "
                        "command to resume"),
)


def exit_status_table() -> str:
    """`EXIT_STATUSES` as the Markdown table docs/cli.md shows."""
    rows = [f"| {status} | {meaning} |" for status, meaning in EXIT_STATUSES]
    return "\n".join(["| status | meaning |", "|---|---|", *rows])


EXIT_STATUS_HELP = "exit status: " + "; ".join(f"{status} {meaning.replace('`', '')}"
                                               for status, meaning in EXIT_STATUSES)

WRITE_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EIO, errno.EFBIG, errno.EROFS})


class InputError(ValueError):
    """Bad input from a user: an impossible parameter, a malformed file, an
    output path that is not ours to overwrite."""


class SolverError(RuntimeError):
    """A solve that did not converge: the message says why."""


class WriteError(OSError):
    """A write that failed for want of room (or an I/O error): the message
    names the file and says to free space and rerun to resume."""


def is_write_failure(err: BaseException) -> bool:
    """True for an OSError that a full or failing disk raises (ENOSPC, EDQUOT, EIO, ...)."""
    return isinstance(err, WriteError) or (isinstance(err, OSError) and err.errno in WRITE_ERRNOS)
