"""`cortex analysis calibrate STORE --out DIR [--partial]`, `cortex analysis
viscosity STORE --out DIR`, `cortex analysis build-calibration` and `cortex
analysis invert TABLE.csv --out DIR` (argparse only; the work is imported when
the command runs)."""


def register(sub):
    p = sub.add_parser("analysis", help="calibration laws and Monte-Carlo study of a finished campaign",
                       description="Analyse a campaign store: calibration laws (SPEC 4), reconstruction "
                                   "check, Monte-Carlo error study (SPEC 5), figures and a report.")
    s = p.add_subparsers(dest="subcommand", metavar="SUBCOMMAND", required=True)
    c = s.add_parser("calibrate", help="fit the calibration laws, check them, write DIR/report.md",
                     description="Fit K(h~) = K_B (1 + alpha exp(h~/lambda)) per bending variant, "
                                 "alpha = C ln(K_S/K_B) + D with cubic C, D in gamma_a/K_B; check the "
                                 "reconstruction of nu; summarise the Monte-Carlo trials. Writes "
                                 "DIR/calibration.json, CSV tables, figures and DIR/report.md.")
    c.add_argument("store", metavar="STORE", help="campaign store (HDF5)")
    c.add_argument("--out", required=True, metavar="DIR",
                   help="output directory (created if missing); a non-empty folder cortex did not write is "
                        "refused (DIR/.cortex-outputs lists what cortex wrote there)")
    c.add_argument("--partial", action="store_true",
                   help="analyse an unfinished store with what is done, saying what was left out")
    c.set_defaults(handler="analysis.cli:calibrate")
    v = s.add_parser("viscosity", help="|K*|/K and loss angle of a viscous-interior campaign",
                     description="Tabulate and plot the viscous-interior study (SPEC 7) of a campaign "
                                 "with viscosity_Pa_s and frequency_hz grid axes: |K*|/K and the loss "
                                 "angle against eta, one line per frequency, and the largest viscosity "
                                 "per frequency at which the elastic calibration holds to 1 %. Writes "
                                 "DIR/viscosity.csv, DIR/viscosity.png/.pdf and DIR/viscosity.md.")
    v.add_argument("store", metavar="STORE", help="campaign store (HDF5)")
    v.add_argument("--out", required=True, metavar="DIR", help="output directory (created if missing)")
    v.set_defaults(handler="analysis.cli:viscosity")
    b = s.add_parser("build-calibration", help="the calibration file: emulator tables + paper law + provenance",
                     description="Build a calibration file (format version 2) from a finished emulator "
                                 "campaign store (campaigns/emulator.toml) and, optionally, the paper "
                                 "campaign's store (its law, for --method law). `make calibration` "
                                 "rebuilds the one shipped in the package this way.")
    b.add_argument("--emulator-store", required=True, metavar="STORE.h5")
    b.add_argument("--law-store", metavar="STORE.h5", help="store of campaigns/paper.toml (optional)")
    b.add_argument("--out", required=True, metavar="CAL.json", help="file to write (refused if it exists "
                   "and is not a calibration file)")
    b.set_defaults(handler="analysis.cli:build_calibration")
    i = s.add_parser("invert", help="nu per cell (and frequency) from a table of K(h~), with 95 %% intervals",
                     description="Invert a CSV table with columns cell_id, h_tilde, modulus_mN_per_m, "
                                 "tension_mN_per_m (optional frequency_hz, volume_um3; one row per cell "
                                 "and height) into nu per cell and frequency. Writes DIR/cells.csv; with "
                                 "--json also a JSON list on stdout.")
    i.add_argument("table", metavar="TABLE.csv")
    i.add_argument("--out", required=True, metavar="DIR", help="output directory (created if missing)")
    add_inversion_options(i)
    i.add_argument("--json", action="store_true", help="print the per-cell results as a JSON list")
    i.set_defaults(handler="analysis.cli:invert")


def add_inversion_options(p):
    """--calibration, --method, --bending and the interval's error options (shared with `cortex afm analyze`)."""
    p.add_argument("--calibration", metavar="CAL.json",
                   help="calibration file (default: the one shipped with the package)")
    p.add_argument("--method", choices=("emulator", "law"), default=None,
                   help="emulator (the default: K_B and K_S/K_B fitted on the solver's tables) or law "
                        "(the paper's phenomenological law, for comparison); a calibration file without "
                        "emulator tables (from `cortex analysis calibrate`) defaults to law")
    p.add_argument("--bending", default="standard", help="bending variant: standard (default), double, none")
    p.add_argument("--volume-sd", type=float, default=0.075, metavar="REL",
                   help="relative SD of the cell volume in the 95 %% intervals (default 0.075)")
    p.add_argument("--height-sd", type=float, default=0.5, metavar="UM",
                   help="SD of the height offset per cell in the intervals, um (default 0.5)")
    p.add_argument("--draws", type=int, default=100, help="Monte-Carlo draws per cell (default 100)")
    p.add_argument("--seed", type=int, default=0, help="seed of the interval draws (default 0)")


def inversion_settings(args):
    """(Calibration or None, Emulator or None, provenance, Errors) from the shared options."""
    from analysis.invert_table import Errors
    from analysis.shipped import load
    cal, emu, prov = load(args.calibration)
    if args.method is None:
        args.method = "emulator" if emu is not None else "law"
    errors = Errors(volume_rel_sd=args.volume_sd, height_sd_um=args.height_sd, draws=args.draws,
                    seed=args.seed).check()
    return cal, emu, prov, errors


def calibrate(args):
    from analysis.calibrate_pipeline import run
    result = run(args.store, args.out, partial=args.partial)
    print(f"report: {result['report']}")
    return 0


def viscosity(args):
    from analysis.viscosity import run
    print(f"report: {run(args.store, args.out)}")
    return 0


def build_calibration(args):
    from analysis import shipped
    from outputs.ownership import check_file
    from solver.errors import InputError

    def ours(path):
        try:
            return shipped.load(path) is not None
        except InputError:
            return False
    out = check_file(args.out, ours, "--out")       # a file that is not a calibration file is left alone
    doc = shipped.build(args.emulator_store, args.law_store, progress=_say)
    shipped.write(doc, out)
    print(f"wrote {out} (emulator: {', '.join(doc['emulator'])}; law: {', '.join(doc['variants']) or 'none'})")
    return 0


def invert(args):
    import json

    from analysis.invert_table import invert_rows
    from analysis.table_input import read_table
    from outputs.ownership import OutputDir
    rows = read_table(args.table)
    cal, emu, _, errors = inversion_settings(args)
    out = OutputDir(args.out)
    out.check(["cells.csv"])                        # refused before any work if not ours
    table = invert_rows(rows, args.method, cal, emu, args.bending, errors)
    with out.writing("cells.csv") as path:
        table.to_csv(path, index=False)
    if args.json:
        keys = ["cell_id", "frequency_hz", "nu", "nu_lo95", "nu_hi95", "ks_tilde", "bulk_mN_per_m", "r2",
                "method", "excluded_reason"]
        records = [{k: _plain(r[k]) for k in keys} for _, r in table.iterrows()]
        print(json.dumps(records))
    else:
        print(f"wrote {path} ({len(table)} curves, {int(table['excluded_reason'].isna().sum())} included)")
    return 0


def _plain(x):
    import math
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return None
    if hasattr(x, "item"):
        x = x.item()
    return None if isinstance(x, float) and math.isnan(x) else x


def _say(message):
    import sys
    print(message, file=sys.stderr)

