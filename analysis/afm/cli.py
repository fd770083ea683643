"""`cortex afm synth` and `cortex afm analyze` (argparse only; the work is
imported when the command runs)."""


def register(sub):
    p = sub.add_parser("afm", help="measured cells: synthetic recordings, per-cell inversion, statistics",
                       description="AFM recordings of confined cells (SPEC 6).")
    s = p.add_subparsers(dest="subcommand", metavar="SUBCOMMAND", required=True)
    g = s.add_parser("synth", help="write a synthetic experiment (HDF5) and truth.json beside it")
    g.add_argument("--cells", type=int, default=85, help="number of cells (default 85, the published size)")
    g.add_argument("--seed", type=int, default=0)
    g.add_argument("--out", required=True, metavar="FILE", help="experiment file (.h5)")
    g.add_argument("--no-errors", action="store_true", help="no measurement errors (round trip)")
    g.add_argument("--forward", choices=("fast", "law"), default="fast",
                   help="forward model: the fast solver (default) or a calibration law (needs --calibration)")
    g.add_argument("--calibration", metavar="CAL.json", help="calibration whose law is the forward model")
    g.add_argument("--bending", default="standard", help="bending variant of the forward model")
    g.set_defaults(handler="analysis.afm.cli:synth")
    a = s.add_parser("analyze", help="invert every cell, population statistics, DIR/report.md",
                     description="Invert every cell and frequency (default: on the emulator of the shipped "
                                 "calibration, with 95 % intervals), population statistics, figures and "
                                 "DIR/report.md.")
    a.add_argument("data", metavar="DATA", help="experiment (.h5) or single-cell CSV")
    a.add_argument("--out", required=True, metavar="DIR")
    from analysis.cli import add_inversion_options
    add_inversion_options(a)
    a.set_defaults(handler="analysis.afm.cli:analyze")


def synth(args):
    import json
    from pathlib import Path

    from analysis.afm import synth as sy
    from analysis.afm.h5format import write_experiment
    from solver.errors import InputError
    if args.cells < 1:
        raise InputError(f"--cells must be >= 1 (got {args.cells})")
    out = Path(args.out)
    if out.exists():
        raise InputError(f"{out}: exists; refusing to overwrite")
    if args.forward == "law":
        if not args.calibration:
            raise InputError("--forward law needs --calibration CAL.json")
        from analysis.calibration import Calibration
        forward = sy.law_forward(Calibration.load(args.calibration)[args.bending])
    else:
        forward = sy.solver_forward(args.bending)
    cells, truth = sy.generate(args.cells, args.seed, errors=not args.no_errors, forward=forward)
    write_experiment(out, cells)
    (out.parent / "truth.json").write_text(json.dumps(truth, indent=1, default=float) + "\n")
    print(f"wrote {out} ({len(cells)} cells) and {out.parent / 'truth.json'}")
    return 0


def analyze(args):
    from analysis.afm.report import run
    from analysis.cli import inversion_settings
    _, _, _, errors = inversion_settings(args)          # also settles the default --method
    result = run(args.data, args.calibration, args.out, args.bending, method=args.method, errors=errors)
    print(f"report: {result['report']}")
    return 0
