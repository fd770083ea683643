"""The options several commands share, said one way: `--out DIR`'s help, `--bending`, the
measurement errors of the intervals (`--volume-sd`, `--height-sd`: `afm tension` too), and the
inversion options of `cortex analysis invert` and `cortex afm analyze` with what they parse to.
Their choices are the name lists of `common.names` (no numpy: `cortex --help` stays fast)."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING, TypeAlias

from analysis.invert.measurement_errors import DRAWS, HEIGHT_SD_UM, VOLUME_SD
from common.names import BENDINGS, INVERSION_METHODS

if TYPE_CHECKING:
    from analysis.invert.measurement_errors import MeasurementErrors
    from analysis.calibration.file import CalibrationFile

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
                   help="calibration bundle (default: the one shipped with the package): the parts it holds or "
                        "names replace the shipped ones; a part it does not name comes from the shipped bundle only "
                        "where its manifest says \"shipped\" (docs/calibration.md)")
    p.add_argument("--method", choices=INVERSION_METHODS, default=None, metavar="METHOD",
                   help="inversion method, %(choices)s: emulator (the default: K_B and K_S/K_B fitted on the "
                        "solver's tables) or law "
                        "(the paper's phenomenological law, for comparison); a calibration file without "
                        "emulator tables (from `cortex analysis calibrate`) defaults to law")
    add_bending(p, "bending variant of the calibration")
    add_error_options(p, "the height offset per cell")
    p.add_argument("--draws", type=int, default=DRAWS, help=f"Monte-Carlo draws per cell (default {DRAWS})")
    p.add_argument("--seed", type=int, default=0, help="seed of the interval draws (default 0)")


def add_error_options(p: argparse.ArgumentParser, height: str) -> None:
    """--volume-sd and --height-sd, the measurement errors of the 95 % intervals (`MeasurementErrors`);
    `height` says which height's SD it is."""
    p.add_argument("--volume-sd", type=float, default=VOLUME_SD, metavar="REL",
                   help="relative SD of the cell volume in the 95 %% intervals (default %(default)s)")
    p.add_argument("--height-sd", type=float, default=HEIGHT_SD_UM, metavar="UM",
                   help=f"SD of {height} in the intervals, um (default %(default)s)")


def measurement_errors(args: argparse.Namespace, draws: int, seed: int = 0) -> MeasurementErrors:
    """The checked `MeasurementErrors` of --volume-sd and --height-sd, with `draws` draws."""
    from analysis.invert.measurement_errors import MeasurementErrors
    return MeasurementErrors(volume_rel_sd=args.volume_sd, height_sd_um=args.height_sd, draws=draws,
                             seed=seed).check()


def inversion_settings(args: argparse.Namespace) -> tuple[CalibrationFile, MeasurementErrors]:
    """(the `CalibrationFile`, read once, and the `MeasurementErrors`) from the shared options."""
    from analysis.calibration.file import load_calibration
    file = load_calibration(args.calibration)
    errors = measurement_errors(args, args.draws, args.seed)
    return file, errors
