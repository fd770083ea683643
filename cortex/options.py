"""The options several commands share, said one way: `--out DIR`'s help, `--bending`, and the
inversion options of `cortex analysis invert` and `cortex afm analyze` with what they parse to.
Their choices are the name lists of `common.names` (no numpy: `cortex --help` stays fast)."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING, TypeAlias

from analysis.invert.measurement_errors import HEIGHT_SD_UM, VOLUME_SD
from common.names import BENDINGS, INVERSION_METHODS

if TYPE_CHECKING:
    from analysis.invert.intervals import Errors
    from analysis.shipped import CalibrationFile

Commands: TypeAlias = "argparse._SubParsersAction[argparse.ArgumentParser]"   # what add_subparsers returns

OUT_HELP = ("output folder (created if missing); a non-empty folder cortex did not write is refused "
            "(DIR/.cortex-outputs lists what cortex wrote there, which a rerun may replace)")


def add_bending(p: argparse.ArgumentParser, what: str = "bending variant") -> None:
    """`--bending VARIANT`, one of `common.names.BENDINGS` (default standard)."""
    p.add_argument("--bending", choices=BENDINGS, default="standard", metavar="VARIANT",
                   help=f"{what}: %(choices)s (default %(default)s)")


def add_inversion_options(p: argparse.ArgumentParser) -> None:
    """--calibration, --method, --bending and the interval's error options (shared with `cortex afm analyze`)."""
    p.add_argument("--calibration", metavar="CAL.json",
                   help="calibration file (default: the one shipped with the package)")
    p.add_argument("--method", choices=INVERSION_METHODS, default=None, metavar="METHOD",
                   help="inversion method, %(choices)s: emulator (the default: K_B and K_S/K_B fitted on the "
                        "solver's tables) or law "
                        "(the paper's phenomenological law, for comparison); a calibration file without "
                        "emulator tables (from `cortex analysis calibrate`) defaults to law")
    add_bending(p, "bending variant of the calibration")
    p.add_argument("--volume-sd", type=float, default=VOLUME_SD, metavar="REL",
                   help="relative SD of the cell volume in the 95 %% intervals (default %(default)s)")
    p.add_argument("--height-sd", type=float, default=HEIGHT_SD_UM, metavar="UM",
                   help="SD of the height offset per cell in the intervals, um (default %(default)s)")
    p.add_argument("--draws", type=int, default=100, help="Monte-Carlo draws per cell (default 100)")
    p.add_argument("--seed", type=int, default=0, help="seed of the interval draws (default 0)")


def inversion_settings(args: argparse.Namespace) -> tuple[CalibrationFile, Errors]:
    """(the `CalibrationFile`, read once, and the `Errors`) from the shared options."""
    from analysis.invert.intervals import Errors
    from analysis.shipped import read
    file = read(args.calibration)
    if args.method is None:
        args.method = "emulator" if file.emulator is not None else "law"
    errors = Errors(volume_rel_sd=args.volume_sd, height_sd_um=args.height_sd, draws=args.draws,
                    seed=args.seed).check()
    return file, errors
