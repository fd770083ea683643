"""`cortex afm synth`, `cortex afm import`, `cortex afm analyze` and `cortex afm tension` (argparse
only; the work is imported when the command runs).

Conventions shared with every command: `--out` is a folder (synth and import
write DIR/experiment.h5, synth also DIR/truth.json, under the folder's
manifest rules of `outputs.ownership.OutputDir`); `--json` prints the results
on stdout; `--solver` names the forward model as in `cortex compress`
(`common.names.SOLVERS`, plus `law` and `emulator`); `--bending` is one of
`common.names.BENDINGS`."""

from __future__ import annotations

import argparse
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

from common.names import CORTEX_HISTORIES, HOLD_KINDS, RAMP_MODELS, SOLVERS
from cortex.options import (OUT_HELP, Commands, add_bending, add_error_options, add_inversion_options,
                            inversion_settings, measurement_errors)
from cortex.results import plain, say_result

if TYPE_CHECKING:
    from analysis.afm.formats.reader import ImportOptions
    from analysis.afm.provenance import Provenance
    from outputs.ownership import OutputDir

EXPERIMENT = "experiment.h5"            # what synth and import write into their --out folder
TRUTH = "truth.json"
TIME_DOMAIN_EXPONENTS = (0.1, 0.3)       # --time-domain's default (beta_B, beta_S)
TIME_DOMAIN_WAIT_S = 100.0
TIME_DOMAIN_RAMP_UM_PER_S = 0.2          # as published (SPEC 6)


def _import_options(p: argparse.ArgumentParser, free_radius: bool = False, dish_default: str = "0") -> None:
    """The volume, dish-reference and spring-constant options of instrument recordings
    (docs/jpk.md, docs/bruker.md); `free_radius` adds --radius-um to the volumes,
    `dish_default` says what stands for Z without a dish option."""
    v = p.add_mutually_exclusive_group()
    v.add_argument("--volumes", metavar="TABLE.csv",
                   help="cell volumes: CSV with columns cell_id and volume_um3, or equator_radius_um with "
                        "imaged_height_um (the confined droplet's), or diameter_um (the free cell's); "
                        "[volume_source]")
    v.add_argument("--volume", type=float, metavar="UM3", help="one volume (um^3) for every cell")
    if free_radius:
        v.add_argument("--radius-um", type=float, metavar="R", help="one free-cell radius (um) for every cell")
    d = p.add_mutually_exclusive_group()
    d.add_argument("--dish-height-um", type=float, metavar="Z",
                   help=f"height channel value (um) at which the cantilever touches the bare dish (default "
                        f"{dish_default}): cell height h = z + F/k - Z")
    d.add_argument("--dish-curve", metavar="FILE",
                   help="a force curve on the bare dish: Z = z + F/k at its largest approach force")
    p.add_argument("--spring-constant", type=float, metavar="N_PER_M",
                   help="cantilever spring constant k (N/m) of NanoScope Analysis text exports, which hold none "
                        "(default: that of the NanoScope file each was exported from, beside it; docs/bruker.md)")


def import_options(args: argparse.Namespace, contact_heights: bool = False, untimed_ramps: bool = False
                   ) -> ImportOptions:
    """The `ImportOptions` of the parsed options (checked)."""
    from analysis.afm.formats.reader import ImportOptions
    return ImportOptions(volume_um3=args.volume, volumes_csv=args.volumes, radius_um=getattr(args, "radius_um", None),
                         dish_um=args.dish_height_um, dish_curve=args.dish_curve,
                         spring_constant_N_per_m=args.spring_constant, contact_heights=contact_heights,
                         untimed_ramps=untimed_ramps).check()


def register(sub: Commands) -> None:
    p = sub.add_parser("afm", help="measured cells: synthetic recordings, per-cell inversion, statistics, "
                       "cortical tension",
                       description="AFM recordings of confined cells (SPEC 6).")
    s = p.add_subparsers(dest="subcommand", metavar="SUBCOMMAND", required=True)
    _add_synth(s)
    _add_import(s)
    _add_analyze(s)
    _add_tension(s)


def _add_synth(s: Commands) -> None:
    g = s.add_parser("synth", help="write a synthetic experiment: DIR/experiment.h5 and DIR/truth.json",
                     description="Simulate AFM recordings of --cells cells of known Poisson ratio (SPEC 6) "
                                 "into DIR/experiment.h5 and their true values into DIR/truth.json.")
    g.add_argument("--cells", type=int, default=85, help="number of cells (default 85, the published size)")
    g.add_argument("--seed", type=int, default=0)
    g.add_argument("--out", required=True, metavar="DIR", help=OUT_HELP)
    g.add_argument("--no-errors", action="store_true", help="no measurement errors (round trip)")
    g.add_argument("--solver", choices=(*SOLVERS, "law", "emulator"),
                   default="fast", metavar="SOLVER",
                   help="forward model, %(choices)s: a solver as in `cortex compress` (default fast) or law, a "
                        "calibration law (needs --calibration), or emulator (viscoelastic cells only: the shipped "
                        "emulator and complex table)")
    g.add_argument("--calibration", metavar="CAL.json", help="calibration whose law is the forward model")
    g.add_argument("--bulk-exponent", type=float, metavar="BETA_B",
                   help="viscoelastic cells: population median of beta_B, |K_B*| ~ f^beta_B and delta_B = "
                        "beta_B pi/2 (per-cell SD 0.03; with --shear-exponent; docs/viscoelastic.md; "
                        f"default {TIME_DOMAIN_EXPONENTS[0]:g} with --time-domain)")
    g.add_argument("--shear-exponent", type=float, metavar="BETA_S",
                   help="viscoelastic cells: population median of beta_S (with --bulk-exponent; "
                        f"default {TIME_DOMAIN_EXPONENTS[1]:g} with --time-domain)")
    g.add_argument("--time-domain", action="store_true",
                   help="simulate each cell's whole protocol in time (power-law cortex K(t) ~ t^-beta, one "
                        "equilibrium of the fast solver per step; about 10-45 s a cell; docs/viscoelastic.md)")
    g.add_argument("--wait-s", type=float, default=None, metavar="S",
                   help=f"--time-domain: the wait at each mean height before its oscillations (default "
                        f"{TIME_DOMAIN_WAIT_S:g} s)")
    g.add_argument("--memory-s", type=float, default=None, metavar="S",
                   help="--time-domain: the cortex's memory tau_c, K(t) ~ t^-beta e^(-t/tau_c), one for both moduli "
                        "(turnover; default inf: the pure power law, never forgetting)")
    g.add_argument("--jobs", type=int, default=None, metavar="N",
                   help="--time-domain: cells simulated in N processes at once (default 1). Under "
                        "'mpiexec -n N cortex afm synth --time-domain ...' rank 0 writes and ranks 1..N-1 simulate; "
                        "--jobs is then not given")
    g.add_argument("--history", choices=CORTEX_HISTORIES, default=None, metavar="HISTORY",
                   help="--time-domain: the cortex's history across mean heights, %(choices)s (default carried: "
                        "one history through the whole protocol; relaxed: every mean height from its own relaxed "
                        "droplet one cell step above it, as the relaxed-state reading assumes)")
    g.add_argument("--hold", choices=HOLD_KINDS, default=None, metavar="KIND",
                   help="--time-domain: each wait a hold at constant KIND, %(choices)s (default height; force: "
                        "the force the ramp reached is held while the plate creeps)")
    g.add_argument("--ramp-speed-um-per-s", type=float, default=None, metavar="V",
                   help=f"--time-domain: the speed of the ramps to each mean height (default "
                        f"{TIME_DOMAIN_RAMP_UM_PER_S:g} um/s)")
    add_bending(g, "bending variant of the forward model")
    g.add_argument("--json", action="store_true", help="one JSON object: the files written and the cell count")
    g.set_defaults(handler=synth, ranks=True)


def _add_import(s: Commands) -> None:
    m = s.add_parser("import", help="JPK and Bruker NanoScope recordings into DIR/experiment.h5",
                     description="Read JPK text exports (.txt, .txt.gz), .jpk-force, .jpk-force-map and .jpk-qi-data "
                                 "(-series) files (each map or QI pixel its own recording), Bruker NanoScope force "
                                 "curves (.000, .001, ...) and their NanoScope Analysis text exports into the "
                                 "native experiment format, DIR/experiment.h5. Every cell needs a volume. The "
                                 "first file that cannot be read stops the import (status 2, nothing written). "
                                 "See docs/jpk.md, docs/bruker.md.")
    m.add_argument("files", nargs="+", metavar="FILES", help="JPK or Bruker files, or folders of them")
    m.add_argument("--out", required=True, metavar="DIR", help=OUT_HELP)
    _import_options(m)
    m.add_argument("--json", action="store_true", help="one JSON object per recording: cell_id, "
                   "spring_constant_N_per_m, segments [{kind, duration_s, n_samples, frequency_hz, amplitude_um}]")
    m.set_defaults(handler=import_)


def _add_analyze(s: Commands) -> None:
    a = s.add_parser("analyze", help="invert every cell, population statistics, DIR/report.md",
                     description="Invert every cell and frequency (default: on the emulator of the shipped "
                                 "calibration, with 95 % intervals), population statistics, the population answer "
                                 "(DIR/population.json: the frequency trend, the populations with the "
                                 "measurement error taken out, paired tests), figures and DIR/report.md. Recordings without a modulation segment are listed in the "
                                 "report (exit status 1).")
    a.add_argument("data", nargs="+", metavar="DATA",
                   help="experiment (.h5, or the folder `afm synth`/`afm import` wrote it to), "
                        "single-cell CSV, or JPK or Bruker files and folders of them")
    a.add_argument("--out", required=True, metavar="DIR", help=OUT_HELP)
    add_inversion_options(a)
    _import_options(a)
    a.add_argument("--no-phase", action="store_true",
                   help="skip the viscoelastic reading of the loss angles (on by default: DIR/rheology.csv, "
                        "loss-angle columns in cells.csv, the paired test in summary.json)")
    ph = a.add_mutually_exclusive_group()
    ph.add_argument("--phase-reference", metavar="FILE",
                    help="a recording on the bare dish (.h5 or .csv): the instrument's phase lag per frequency, "
                         "added back to every loss angle")
    ph.add_argument("--phase-lag-rad", metavar="F=RAD,...",
                    help="the instrument's phase lag per frequency, e.g. 1=0.02,10=0.2")
    a.add_argument("--tension-tolerance", type=float, default=None, metavar="X",
                   help="the tension filter: a cell whose segments' mean tension deviates from its median by more "
                        "than the fraction X is excluded (default 0.1, as published; inf lifts the filter; "
                        "summary.json tension_tolerance)")
    a.add_argument("--wait-s", default=None, metavar="S",
                   help="the wait before each height's oscillations, for the protocol-aware viscoelastic reading: "
                        "each cell's own protocol replayed in time with its fitted power-law cortex, every segment "
                        "corrected for the stress kept from the earlier height steps, in rounds until the cells' "
                        "power laws settle (about 15 s of CPU a cell end to end with the memory read from the data, 4-5 s with "
                        "--memory-s given; docs/memory.md). Default: as the "
                        "experiment was made (its provenance; docs/afm.md): a frequency-domain 'afm synth' "
                        "experiment, relaxed at every height, as inf; a measured or time-domain one as recorded. "
                        "'recorded': each recording's own waits (from its approaches or pauses); S: a wait of S s "
                        "at every height; inf: the relaxed-state reading, no correction. summary.json 'reading' "
                        "says which was used and why")
    a.add_argument("--memory-s", default=None, metavar="S",
                   help="the protocol-aware reading's cortex memory tau_c, K(t) ~ t^-beta e^(-t/tau_c). Default: "
                        "each cell's own from the drift of its mean tension across heights, with a 95%% interval "
                        "(pooled over the cells where one cell cannot tell; cells.csv and summary.json say which; "
                        "docs/viscoelastic.md). S: tau_c = S s for every cell; inf: the pure power law, never "
                        "forgetting; 0: nothing kept, the relaxed state (as --wait-s inf)")
    a.add_argument("--jobs", type=int, default=None, metavar="N",
                   help="cells replayed in N processes at once (default: the CPUs this process may use). "
                        "Under 'mpiexec -n N cortex afm analyze ...' (on a cluster: jobs/afm-analyze.sbatch) rank 0 "
                        "reads and ranks 1..N-1 replay, on any number of nodes; --jobs is then not given")
    a.add_argument("--json", action="store_true", help="one JSON object: the report's path, the skipped "
                   "recordings and the per-frequency summary (median_nu, iqr_nu, frequency_hz, ...)")
    a.set_defaults(handler=analyze, ranks=True)


def _add_tension(s: Commands) -> None:
    t = s.add_parser("tension", help="cortical tension and pressure from approach ramps and pauses",
                     description="Cortical tension (and pressure) of every recording (SPEC 11): each approach "
                                 "ramp onto the free cell and the pause after it read as one curve of the shell "
                                 "whose cortex relaxes as a power law (active tension, K_B at 1 s, exponent: the "
                                 "headline; --no-power-law skips it), the ramp fitted by the elastic shell pressed "
                                 "from its free sphere (active tension and bulk modulus, the beta = 0 reading), by "
                                 "the exact droplet model and by the "
                                 "small-deformation formula (contact point, T, R², the automatic fit window), "
                                 "each pause from its relaxed force (its relaxation fitted, exponential or "
                                 "power law, and extrapolated; too short a pause flagged; the last half's mean "
                                 "for comparison) and the droplet shape at its height, with 95 % "
                                 "intervals. Recordings that cannot be analysed are listed (exit status 1). "
                                 "See docs/tension.md.")
    t.add_argument("files", nargs="+", metavar="FILES",
                   help="instrument files (JPK, Bruker NanoScope and their text exports) or folders of them, "
                        "experiments (.h5) or single-cell CSV files")
    _import_options(t, free_radius=True, dish_default="the first ramp's contact point less 2R")
    t.add_argument("--model", choices=RAMP_MODELS, default="shell", metavar="MODEL",
                   help="ramp model, %(choices)s (default shell: the active tension and bulk modulus of an elastic "
                        "cortex; the droplet and small-deformation apparent tensions beside it)")
    t.add_argument("--no-oscillation-priors", action="store_true",
                   help="do not take the shell's priors from the recording's own oscillation segments (by default "
                        "a recording that holds them is read as `afm analyze` reads it, and K_B and K_S/K_B at the "
                        "ramp's time scale become Gaussian priors of the shell fit; the row's prior_source says so)")
    t.add_argument("--shear-ratio", type=float, default=None, metavar="KS_OVER_KB",
                   help="K_S/K_B of the shell model when known from the same cell's oscillations (default: "
                        "fitted over the ramp table's range by its profile likelihood; the row says "
                        "whether the ramp identifies it, and the intervals of the active tension and K_B hold "
                        "every K_S/K_B it allows)")
    t.add_argument("--bulk-mN-per-m", type=float, default=None, metavar="KB",
                   help="the shell's area bulk modulus K_B in mN/m when known from the same cell's oscillations "
                        "(default: fitted)")
    t.add_argument("--max-depth-um", type=float, default=None, metavar="D",
                   help="deepest deformation of the fit window, um (default: the deepest reached, at most R; "
                        "for the shell at most 0.3 R, its table's depth; a warning when the ramp does not reach it)")
    t.add_argument("--ramp-speed-um-per-s", type=float, default=None, metavar="V",
                   help="approach speed (um/s) of recordings whose files hold no sample times (a NanoScope "
                        "Analysis export without its NanoScope file); the row's ramp_speed_um_per_s and "
                        "ramp_speed_source say which speed each ramp has; the power-law shell times such a ramp by it "
                        "(its samples taken evenly in time), the elastic shell uses it only for the time scale of "
                        "its priors from the recording's oscillations)")
    law = t.add_mutually_exclusive_group()
    law.add_argument("--power-law", action="store_true", default=None,
                     help="read each approach and the pause right after it (at constant height or force) as one "
                          "curve of the shell whose cortex relaxes as a power law (the power_law_* columns: the "
                          "active tension, K_B at 1 s and the exponent; K_S/K_B the --shear-ratio, else the "
                          "oscillations' prior, else profiled over 0.1-2 with its interval), the row's headline "
                          "tension where it reads (headline_*; the elastic shell's tension the beta = 0 reading "
                          "beside it, and the headline where it does not, power_law_note says why). The default "
                          "with --model shell; given, with every model. Seconds to a minute of CPU a ramp")
    law.add_argument("--no-power-law", dest="power_law", action="store_false", default=None,
                     help="the elastic shell alone (the beta = 0 reading, seconds faster a ramp): no power_law_* "
                          "columns, the headline the ramp model's tension")
    add_error_options(t, "a pause's height")
    t.add_argument("--calibration", metavar="CAL.json",
                   help="calibration bundle (the format `afm analyze` takes, docs/calibration.md): the shell ramp "
                        "table and the power-law table its manifest names (ramp_table, powerlaw_table) replace the "
                        "shipped ones, and where it names an emulator and a viscoelastic table they read the "
                        "oscillations for the priors; a part it does not name is the shipped one. The rows' "
                        "shell_table_source, shell_table_sha256, powerlaw_table_source, powerlaw_table_sha256 and "
                        "prior_calibration_source say which")
    t.add_argument("--out", metavar="DIR", help=OUT_HELP + "; gets tension.csv, a figure per recording and "
                   "report.md")
    t.add_argument("--json", action="store_true", help="one JSON object: rows (the columns of tension.csv), "
                   "not_analysed {file or cell: reason}, table, report")
    t.set_defaults(handler=tension)


def synth(args: argparse.Namespace) -> int:
    """Under `mpiexec -n N` rank 0 writes and the other ranks simulate its time-domain cells."""
    return on_ranks(_synth, args)


def _synth(args: argparse.Namespace) -> int:
    import json

    from analysis.afm.synth import cells as sy
    from analysis.afm.formats.h5 import write_experiment
    from outputs.writing import write_atomically
    from common.errors import InputError
    if args.cells < 1:
        raise InputError(f"--cells must be >= 1 (got {args.cells})")
    settings: dict[str, Any] = {}
    if args.time_domain:
        settings = _time_domain_settings(args)
        out = new_experiment_folder(args.out, [EXPERIMENT, TRUTH])
        from analysis.afm.synth import time_cells
        cells, truth = time_cells.generate(args.cells, args.seed, errors=not args.no_errors, **settings)
    else:
        if (args.wait_s, args.history, args.hold, args.ramp_speed_um_per_s, args.memory_s, args.jobs) != (None,) * 6:
            raise InputError("--wait-s, --memory-s, --jobs, --history, --hold and --ramp-speed-um-per-s go with --time-domain")
        out = new_experiment_folder(args.out, [EXPERIMENT, TRUTH])
        cells, truth = sy.generate(args.cells, args.seed, errors=not args.no_errors, forward=_forward(args))
    with out.writing(EXPERIMENT) as experiment:
        write_experiment(experiment, cells, _made(args, settings, truth))
    text = json.dumps({"format": TRUTH_FORMAT, **truth}, indent=1, default=float) + "\n"
    with out.writing(TRUTH) as truth_path:
        write_atomically(truth_path, text.encode())
    say_result(args, {"experiment": str(experiment), "truth": str(truth_path), "n_cells": len(cells)},
               f"wrote {experiment} ({len(cells)} cells) and {truth_path}")
    return 0


def _made(args: argparse.Namespace, settings: dict[str, Any], truth: dict[str, Any]) -> Provenance:
    """The provenance `afm synth` records: frequency-domain, or time-domain with each cell's cortex,
    its history and τ_c (the synth's `memory_s` where it has one, else inf: no turnover)."""
    from analysis.afm import provenance
    if not args.time_domain:
        return provenance.FREQUENCY_DOMAIN
    return provenance.time_domain(truth["cells"], settings["history"], settings.get("memory_s", float("inf")))


def _time_domain_settings(args: argparse.Namespace) -> dict[str, Any]:
    """`time_cells.generate`'s settings from the options (checked before any work)."""
    import math

    from common.errors import InputError
    if args.solver != "fast" or args.calibration:
        raise InputError("--time-domain simulates with the fast solver: no --solver other than fast, "
                         "no --calibration")
    bulk, shear = (TIME_DOMAIN_EXPONENTS[k] if x is None else x
                   for k, x in enumerate((args.bulk_exponent, args.shear_exponent)))
    if not all(math.isfinite(b) and 0 <= b <= 0.6 for b in (bulk, shear)):
        raise InputError(f"--bulk-exponent and --shear-exponent must be in [0, 0.6] (got {bulk:g}, {shear:g})")
    wait = TIME_DOMAIN_WAIT_S if args.wait_s is None else args.wait_s
    if not (math.isfinite(wait) and 0 <= wait <= 1e4):
        raise InputError(f"--wait-s must be a number of seconds in [0, 10000] (got {wait:g})")
    memory = math.inf if args.memory_s is None else args.memory_s
    if not memory > 0:
        raise InputError(f"--memory-s must be a number of seconds > 0, or inf (got {memory:g})")
    jobs = 1 if args.jobs is None else args.jobs
    if jobs < 1:
        raise InputError(f"--jobs must be >= 1 (got {jobs})")
    speed = TIME_DOMAIN_RAMP_UM_PER_S if args.ramp_speed_um_per_s is None else args.ramp_speed_um_per_s
    if not (math.isfinite(speed) and 0 < speed <= 100):
        raise InputError(f"--ramp-speed-um-per-s must be a speed in (0, 100] um/s (got {speed:g})")
    return {"bulk_exponent": bulk, "shear_exponent": shear, "wait_s": wait, "memory_s": memory,
            "bending": args.bending, "jobs": jobs, "progress": not args.json,
            "history": args.history or "carried", "hold": args.hold or "height", "ramp_speed_um_per_s": speed}


def new_experiment_folder(path: str, names: list[str]) -> OutputDir:
    """The --out folder (`OutputDir`) that will hold a new DIR/experiment.h5:
    refused before any work if a file of `names` there is not ours, or if the
    folder already holds an experiment (measurements are never replaced, even ours)."""
    import os

    from outputs.ownership import OutputDir
    from common.errors import InputError
    out = OutputDir(path)
    out.check(names)
    if os.path.lexists(out.path / EXPERIMENT):
        raise InputError(f"--out {out.path}: holds {EXPERIMENT} already; an experiment is never replaced "
                         "(it is left as it is; choose another folder)")
    return out


def _forward(args: argparse.Namespace) -> Any:
    """The forward model that `--solver`, `--bending` and `--calibration` name."""
    from analysis.afm.synth import cells as sy
    from common.errors import InputError
    given = (args.bulk_exponent, args.shear_exponent)
    if given != (None, None):
        return _viscoelastic_forward(args, given)
    if args.solver == "emulator":
        raise InputError("--solver emulator makes viscoelastic cells only: give --bulk-exponent and --shear-exponent")
    if args.solver != "law":
        return sy.solver_forward(args.bending, method=args.solver)
    if not args.calibration:
        raise InputError("--solver law needs --calibration CAL.json")
    from analysis.calibration.file import load_calibration
    file = load_calibration(args.calibration)
    if file.calibration is None:
        raise InputError(f"{file.where}: holds no calibration law ('variants'); --solver law needs one")
    return sy.law_forward(file.calibration[args.bending])


def _viscoelastic_forward(args: argparse.Namespace, exponents: tuple[float | None, float | None]) -> Any:
    from analysis.afm.synth import rheology as sr
    from common.errors import InputError
    bulk, shear = exponents
    if bulk is None or shear is None or not all(0 <= b <= 0.6 for b in (bulk, shear)):
        raise InputError("--bulk-exponent and --shear-exponent go together, each in [0, 0.6]")
    if args.solver not in ("fast", "emulator"):
        raise InputError("viscoelastic cells need --solver fast or emulator")
    if args.solver == "emulator":
        from analysis.calibration.file import load_calibration
        complex_forward = sr.emulator_complex(load_calibration(None).viscoelastic, args.bending)
    else:
        complex_forward = sr.solver_complex(args.bending)
    return sr.ViscoelasticForward(bulk, shear, complex_forward, seed=args.seed)


def phase_settings(args: argparse.Namespace) -> tuple[bool, dict[float, float] | None, str | None]:
    """(phase on, lags {Hz: rad} or None, where they came from) of `afm analyze`."""
    from analysis.afm import rheology
    if args.no_phase:
        return False, None, None
    if args.phase_lag_rad:
        return True, rheology.parse_lags(args.phase_lag_rad), f"--phase-lag-rad {args.phase_lag_rad}"
    if args.phase_reference:
        from analysis.afm.formats.reader import open as open_cells
        lags = rheology.reference_lags(open_cells(args.phase_reference))
        return True, lags, f"measured on the bare dish ({args.phase_reference})"
    return True, None, None


def import_(args: argparse.Namespace) -> int:
    import json

    from analysis.afm.formats.h5 import write_experiment
    from analysis.afm.formats.instruments import NAMES, is_instrument_file
    from analysis.afm.formats.reader import open as open_cells
    from analysis.afm.provenance import MEASURED
    from common.errors import InputError
    for f in args.files:                # instrument files only: an experiment is never imported again
        if not is_instrument_file(f):
            raise InputError(f"{f}: not a recording file (expected {NAMES})")
    out = new_experiment_folder(args.out, [EXPERIMENT])
    cells = open_cells(args.files, import_options(args))
    with out.writing(EXPERIMENT) as path:
        write_experiment(path, cells, MEASURED)
    for c in cells:
        assert c.recorded is not None, "an instrument cell keeps its recording's summary"
        print(json.dumps(c.recorded) if args.json else _summary_line(c.recorded))
    if not args.json:
        print(f"wrote {path} ({len(cells)} cells)")
    return 0


def _summary_line(rec: dict[str, Any]) -> str:
    """cell, spring constant and segments by kind (count, samples, total duration, frequencies) of a
    recording's summary (`formats.recording.Recording.summary`)."""
    parts = []
    for kind in ("approach", "pause", "modulation", "retract"):
        segs = [s for s in rec["segments"] if s["kind"] == kind]
        if not segs:
            continue
        text = (f"{len(segs)} {kind} ({sum(s['n_samples'] for s in segs)} samples, "
                f"{sum(s['duration_s'] for s in segs):g} s")
        if kind == "modulation":
            text += ", at " + ", ".join(f"{f:g}" for f in sorted({s["frequency_hz"] for s in segs})) + " Hz"
        parts.append(text + ")")
    return f"{rec['cell_id']}: k {rec['spring_constant_N_per_m']:.4g} N/m; " + "; ".join(parts)


TRUTH_FORMAT = "cortex-afm-truth"      # the key that says a truth.json is ours (may be replaced)


def _is_our_truth(path: Any) -> bool:
    from outputs.ownership import json_document
    return json_document(path).get("format") == TRUTH_FORMAT


def experiment_in(paths: Sequence[str]) -> Sequence[str]:
    """DATA as given, except that a single folder holding DIR/experiment.h5 (what
    `afm synth` and `afm import` write) stands for that file."""
    from pathlib import Path
    if len(paths) == 1 and Path(paths[0]).is_dir() and (Path(paths[0]) / EXPERIMENT).is_file():
        return [str(Path(paths[0]) / EXPERIMENT)]
    return paths


def seconds_option(option: str, text: str, what: str, expected: str) -> float:
    """`text` of `option` as a number of seconds >= 0 (inf allowed); InputError (one line) otherwise."""
    from common.errors import InputError
    try:
        value = float(text)
    except ValueError:
        raise InputError(f"{option}: '{text}' is not {expected}") from None
    if not value >= 0:
        raise InputError(f"{option}: {what} must be >= 0 s, or inf (got {text})")
    return value


def wait_setting(text: str | None, phase: bool) -> tuple[bool, float | None]:
    """`--wait-s` as (as made, wait): (True, None) when not given (the experiment read as its
    provenance says), else (False, None) for each recording's own waits ('recorded') or (False, the
    seconds; inf: the relaxed state); InputError (one line) if malformed, or finite with --no-phase."""
    import math

    from common.errors import InputError
    if text is None:
        return True, None
    if text == "recorded":
        return False, None
    wait = seconds_option("--wait-s", text, "the wait", "a number of seconds, 'recorded' or inf")
    if not phase and math.isfinite(wait):
        raise InputError("--wait-s corrects the viscoelastic reading: it cannot go with --no-phase")
    return False, wait


def memory_setting(text: str | None, wait_s: float | None) -> float | None:
    """`--memory-s` as τ_c in s (None: from the data); InputError (one line) if malformed, negative,
    or given with the relaxed-state reading (`--wait-s inf`)."""
    import math

    from common.errors import InputError
    if text is None:
        return None
    memory = seconds_option("--memory-s", text, "the memory", "a number of seconds or inf")
    if wait_s is not None and math.isinf(wait_s):
        raise InputError("--memory-s is the protocol-aware reading's: it cannot go with --wait-s inf")
    return memory


def on_ranks(work: Callable[[argparse.Namespace], int], args: argparse.Namespace) -> int:
    """`work(args)` on rank 0, whose pools under `mpiexec -n N` are the other ranks
    (`common.pool.ranks`); those return 0 once it is done. --jobs beside mpiexec is refused."""
    from common.errors import EXIT_DONE, InputError
    from common.pool import inside_ranks, ranks
    with ranks() as main:
        if not main:
            return EXIT_DONE
        if inside_ranks() and args.jobs is not None:
            raise InputError("--jobs goes without mpiexec: under mpiexec the ranks other than 0 do the work")
        return work(args)


def analyze(args: argparse.Namespace) -> int:
    """Under `mpiexec -n N` rank 0 reads and the other ranks replay its cells."""
    return on_ranks(_analyze, args)


def _analyze(args: argparse.Namespace) -> int:
    import json

    from analysis.afm.analyze import TENSION_TOLERANCE
    from analysis.afm.analyze_pipeline import Settings, run
    from common.errors import EXIT_DONE, EXIT_SOME_FAILED
    tolerance = TENSION_TOLERANCE if args.tension_tolerance is None else args.tension_tolerance   # Settings checks it
    file, errors = inversion_settings(args)          # --method None: the calibration's own (Settings)
    data, options = experiment_in(args.data), import_options(args)
    phase, lags, lag_source = phase_settings(args)
    as_made, wait = wait_setting(args.wait_s, phase)
    settings = Settings(bending=args.bending, method=args.method, errors=errors, import_options=options,
                        phase=phase, lags=lags, lag_source=lag_source, tension_tolerance=tolerance,
                        as_made=as_made, wait_s=wait, jobs=args.jobs, memory_s=memory_setting(args.memory_s, wait))
    result = run(data, file, args.out, settings)
    if args.json:
        print(json.dumps(plain({"report": str(result["report"]), "skipped": result["skipped"],
                                **(result["summary"] or {})})))
    else:
        for cell, reason in result["skipped"].items():
            print(f"not analysed: {cell}: {reason}")
        print(f"report: {result['report']}")
    return EXIT_SOME_FAILED if result["skipped"] else EXIT_DONE


def tension(args: argparse.Namespace) -> int:
    import json

    from analysis.afm.tension.pause import DRAWS
    from analysis.afm.tension.pipeline import Options, run
    from analysis.afm.tension.calibration_parts import tension_calibration
    from analysis.calibration.file import load_calibration
    from common.errors import EXIT_DONE, EXIT_SOME_FAILED
    bundle = load_calibration(args.calibration) if args.calibration else None
    options = Options(model=args.model, oscillation_priors=not args.no_oscillation_priors,
                      shear_tilde=args.shear_ratio, bulk_mN_per_m=args.bulk_mN_per_m,
                      max_depth_um=args.max_depth_um, ramp_speed_um_per_s=args.ramp_speed_um_per_s,
                      power_law=args.power_law,
                      import_options=import_options(args, contact_heights=True, untimed_ramps=True),
                      errors=measurement_errors(args, DRAWS),
                      calibration=tension_calibration(bundle) if bundle else None)
    result = run(args.files, options, args.out)
    if args.json:
        finite = lambda v: v if not isinstance(v, float) or v == v and abs(v) != float("inf") else None  # noqa: E731
        print(json.dumps(plain({"rows": [{k: finite(plain(v)) for k, v in r.items()} for r in result["rows"]],
                                "not_analysed": result["skipped"], "table": _str(result["table"]),
                                "report": _str(result["report"])})))
    else:
        for r in result["rows"]:
            print(_tension_line(r))
            if r.get("warning"):
                print(f"warning: {r['cell_id']}: {r['part']} {r['segment']}: {r['warning']}")
        for what, reason in result["skipped"].items():
            print(f"not analysed: {what}: {reason}")
        if result["report"]:
            print(f"report: {result['report']}")
    return EXIT_SOME_FAILED if result["skipped"] else EXIT_DONE


def _str(path: object) -> str | None:
    return None if path is None else str(path)


def _tension_line(r: dict[str, Any]) -> str:
    """One analysed part in a line: an approach's power-law reading (or why none) first, then the ramp
    model's tension (the shell's the beta = 0 reading), interval, pressure, height, and the ramp's contact
    and comparison."""
    from analysis.afm.tension.report import POWER_LAW
    text = f"{r['cell_id']}: {r['part']} {r['segment']}: "
    if r["part"] == "approach" and "power_law_hold" in r:
        text += (f"power-law gamma_a {r['power_law_tension_mN_per_m']:.4g} mN/m "
                 f"[{r['power_law_tension_lo95_mN_per_m']:.3g}, {r['power_law_tension_hi95_mN_per_m']:.3g}], "
                 f"beta {r['power_law_exponent']:.3g}" if r["headline_reading"] == POWER_LAW
                 else f"power law: {r['power_law_note']}") + "; "
    name = "beta = 0 reading: gamma_a" if r["part"] == "approach" and r["model"] == "shell" else "T"
    text += (f"{name} {r['tension_mN_per_m']:.4g} mN/m "
             f"[{r['tension_lo95_mN_per_m']:.3g}, {r['tension_hi95_mN_per_m']:.3g}], dP {r['pressure_Pa']:.4g} Pa, "
             f"h {r['height_um']:.4g} um")
    if r["part"] == "approach":
        if r["model"] == "shell":
            text += (f", K_B {r['bulk_modulus_mN_per_m']:.4g} mN/m [{r['bulk_modulus_lo95_mN_per_m']:.3g}, "
                     f"{r['bulk_modulus_hi95_mN_per_m']:.3g}], droplet T {r['droplet_tension_mN_per_m']:.4g}, "
                     f"small-deformation T {r['small_deformation_tension_mN_per_m']:.4g} mN/m, baseline slope "
                     f"{r['baseline_slope_nN_per_um']:.3g} nN/um" + (" (bimodal)" if r["bimodal"] else "")
                     + (", priors from its oscillations" if r.get("prior_source") == "oscillations" else ""))
        text += (f", contact {r['contact_um']:.5g} um, R2 {r['r2']:.4f} ({r['model']}); "
                 f"{r['compare_model']} T {r['compare_tension_mN_per_m']:.4g} mN/m, R2 {r['compare_r2']:.4f}")
    elif r["part"] == "pause":
        how = "no relaxation" if r["relaxation_model"] == "none" else \
            f"{r['relaxation_model']}, {r['relaxation_time_s']:.3g} s"
        text += (f", relaxed F {r['relaxed_force_nN']:.4g} nN ({how}); last half F {r['last_half_force_nN']:.4g} nN, "
                 f"T {r['last_half_tension_mN_per_m']:.4g} mN/m" + (f"; FLAG {r['relaxation_flag']}"
                                                                   if r["relaxation_flag"] else ""))
    return text
