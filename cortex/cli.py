"""The `cortex` command: one argparse tree, filled in by the command modules.

Each module of `cortex.commands` has a `register(commands)` that adds its
sub-commands and sets `handler=function` on them (`REGISTRARS`); a handler
imports the work (numpy, HDF5, MPI) only when its command runs, so
`cortex --help` and `cortex geometry` stay fast and never load MPI or HDF5.

Errors from bad input (`common.errors.InputError`, missing or unreadable files)
become one line on stderr and exit status 2; a solver that finds no
equilibrium, status 4; a write that fails (disk full), status 5; SIGTERM
or Ctrl-C, status 3 (`cortex campaign run` handles them itself and stops
cleanly). Under `mpiexec -n N` (N > 1) only the commands whose parser sets `ranks`
run (campaign run, afm analyze, afm synth, doctor); any other is one line from
rank 0 and status 2 on every rank. The whole table is in `common.errors` and in every `--help`. A
reader that stops early (`cortex campaign status STORE | head -1`) ends the
command quietly, status 0.

Conventions of every command (docs/cli.md): results on stdout, as one JSON
object or list (JSON lines for `geometry` and `afm import`) with `--json`;
`--out DIR` is always a folder; the same option names for the same things
(`--solver`, `--bending`, `--method`, `--calibration`), their choices taken
from `common.names`.
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
from collections.abc import Callable, Sequence
from types import FrameType
from typing import Any, NoReturn, cast

from common.errors import (EXIT_BAD_INPUT, EXIT_DONE, EXIT_NO_EQUILIBRIUM, EXIT_SIGNAL, EXIT_STATUS_HELP, EXIT_WRITE_FAILED,
                           InputError, SolverError, is_write_failure)
from common.pool import launched_rank, launched_ranks
from cortex.commands import afm, analysis, campaign, doctor, shell
from cortex.options import Commands

REGISTRARS: tuple[Callable[[Commands], None], ...] = (
    shell.register, campaign.register, analysis.register, afm.register, doctor.register)


class _Version(argparse.Action):
    """--version, the package metadata read only when asked for."""

    def __init__(self, option_strings: Sequence[str], dest: str, **kwargs: Any) -> None:
        super().__init__(option_strings, dest, nargs=0, help="show the version and exit")

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace, values: Any,
                 option_string: str | None = None) -> NoReturn:
        import cortex
        print(f"cortex {cortex.__version__}")
        parser.exit(0)


class Parser(argparse.ArgumentParser):
    """argparse, but a usage error is one line (and exit status 2)."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message} (see --help)\n")


def build_parser() -> Parser:
    """The whole command tree: every command module's `register`, every --help ending with the exit statuses."""
    parser = Parser(prog="cortex", description=(
        "Simulate compressed cortical shells, run campaigns of them under MPI, "
        "calibrate the laws that link the effective area modulus to the Poisson "
        "ratio, and invert AFM recordings. Units: um, mN/m, nN, s."))
    parser.add_argument("--version", action=_Version)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for register in REGISTRARS:         # (their parsers are `Parser`s: they use no more than argparse's API)
        register(cast(Commands, sub))
    _add_exit_statuses(parser)
    return parser


def _add_exit_statuses(parser: argparse.ArgumentParser) -> None:
    """Every command's --help ends with the one exit-status table (common.errors)."""
    parser.epilog = "\n".join(filter(None, (parser.epilog, EXIT_STATUS_HELP)))
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for child in action.choices.values():
                _add_exit_statuses(child)


def _silence_stdout() -> None:
    """Point stdout at /dev/null, so that the interpreter's last flush at exit
    does not meet the closed pipe again (and print a traceback)."""
    try:
        fd = sys.stdout.fileno()
    except (AttributeError, ValueError, OSError):   # not a file (captured): nothing to flush at exit
        return
    null = os.open(os.devnull, os.O_WRONLY)
    os.dup2(null, fd)
    os.close(null)


def _interrupt(signum: int, frame: FrameType | None) -> NoReturn:
    raise KeyboardInterrupt


def main(argv: Sequence[str] | None = None) -> int:
    """Run `cortex ARGV`; returns the exit status (also of a usage error, --help or --version)."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as stop:      # argparse has printed its one line (or the help): its status
        return stop.code if isinstance(stop.code, int) else EXIT_BAD_INPUT * bool(stop.code)
    where = " ".join(a for a in (args.command, getattr(args, "subcommand", None)) if a)
    if launched_ranks() > 1 and not getattr(args, "ranks", False):
        if launched_rank() == 0:        # each rank would run the whole command and write the same files
            print(f"cortex {where}: error: runs in one process; under mpiexec only `campaign run`, `afm analyze`, "
                  "`afm synth` and `doctor` run (docs/cli.md)", file=sys.stderr)
        return EXIT_BAD_INPUT
    previous = signal.signal(signal.SIGTERM, _interrupt)   # SIGTERM stops like Ctrl-C: status 3
    try:
        status = args.handler(args)
        sys.stdout.flush()          # here, so that a closed pipe is met inside this try
    except BrokenPipeError:         # the reader of stdout stopped early: nothing more to say
        _silence_stdout()
        return EXIT_DONE
    except InputError as err:
        print(f"cortex {where}: error: {err}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except SolverError as err:
        print(f"cortex {where}: no equilibrium found: {err}", file=sys.stderr)
        return EXIT_NO_EQUILIBRIUM
    except (FileNotFoundError, IsADirectoryError, NotADirectoryError, PermissionError) as err:
        print(f"cortex {where}: error: {err.strerror or err}: {err.filename}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except OSError as err:
        if not is_write_failure(err):
            raise
        name = f": {err.filename}" if err.filename else ""
        print(f"cortex {where}: could not write{name}: {err.strerror or err}; free space, then rerun the same "
              "command to resume", file=sys.stderr)
        return EXIT_WRITE_FAILED
    except KeyboardInterrupt:
        print(f"cortex {where}: stopped by a signal; rerun the same command to resume", file=sys.stderr)
        return EXIT_SIGNAL
    finally:
        signal.signal(signal.SIGTERM, previous)
    return int(status or 0)


if __name__ == "__main__":
    sys.exit(main())
