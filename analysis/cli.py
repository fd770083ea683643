"""`cortex analysis calibrate STORE --out DIR [--partial]` and `cortex analysis
viscosity STORE --out DIR` (argparse only; the work is imported when the command runs)."""


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


def calibrate(args):
    from analysis.report import run
    result = run(args.store, args.out, partial=args.partial)
    print(f"report: {result['report']}")
    return 0


def viscosity(args):
    from analysis.viscosity import run
    print(f"report: {run(args.store, args.out)}")
    return 0
