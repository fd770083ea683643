"""`cortex afm synth`, `cortex afm import` and `cortex afm analyze` (argparse
only; the work is imported when the command runs)."""


def _jpk_options(p):
    """The volume and dish-reference options of JPK recordings (docs/jpk.md)."""
    v = p.add_mutually_exclusive_group()
    v.add_argument("--volumes", metavar="TABLE.csv",
                   help="cell volumes: CSV with columns cell_id, volume_um3[, volume_source]")
    v.add_argument("--volume", type=float, metavar="UM3", help="one volume (um^3) for every cell")
    d = p.add_mutually_exclusive_group()
    d.add_argument("--dish-height-um", type=float, metavar="Z",
                   help="height channel value (um) at which the cantilever touches the bare dish (default 0): "
                        "cell height h = z + F/k - Z")
    d.add_argument("--dish-curve", metavar="FILE",
                   help="a JPK force curve on the bare dish: Z = z + F/k at its largest approach force")


def jpk_options(args):
    """`import_cells` keyword arguments from the parsed options."""
    from solver.errors import InputError
    if args.volume is not None and not args.volume > 0:
        raise InputError(f"--volume must be a positive number of um^3 (got {args.volume})")
    return {"volume_um3": args.volume, "volumes_csv": args.volumes, "dish_um": args.dish_height_um,
            "dish_curve": args.dish_curve}


def register(sub):
    p = sub.add_parser("afm", help="measured cells: synthetic recordings, per-cell inversion, statistics",
                       description="AFM recordings of confined cells (SPEC 6).")
    s = p.add_subparsers(dest="subcommand", metavar="SUBCOMMAND", required=True)
    g = s.add_parser("synth", help="write a synthetic experiment (HDF5) and truth.json beside it")
    g.add_argument("--cells", type=int, default=85, help="number of cells (default 85, the published size)")
    g.add_argument("--seed", type=int, default=0)
    g.add_argument("--out", required=True, metavar="FILE", help="experiment file (.h5), new: an existing one "
                   "is never overwritten; truth.json beside it is replaced only if cortex wrote it")
    g.add_argument("--no-errors", action="store_true", help="no measurement errors (round trip)")
    g.add_argument("--forward", choices=("fast", "law"), default="fast",
                   help="forward model: the fast solver (default) or a calibration law (needs --calibration)")
    g.add_argument("--calibration", metavar="CAL.json", help="calibration whose law is the forward model")
    g.add_argument("--bending", default="standard", help="bending variant of the forward model")
    g.set_defaults(handler="analysis.afm.cli:synth")
    m = s.add_parser("import", help="JPK text exports and binary JPK files into an experiment file (HDF5)",
                     description="Read JPK text exports (.txt), .jpk-force, .jpk-force-map and .jpk-qi-data (-series) "
                                 "files (each map or QI pixel its own recording) into the native experiment "
                                 "format. Every cell needs a volume. See docs/jpk.md.")
    m.add_argument("files", nargs="+", metavar="FILES", help="JPK files or folders of them")
    m.add_argument("--out", required=True, metavar="EXPERIMENT.h5", help="experiment file to write (new)")
    _jpk_options(m)
    m.add_argument("--json", action="store_true", help="one JSON object per recording: cell_id, "
                   "spring_constant_N_per_m, segments [{kind, duration_s, n_samples, frequency_hz, amplitude_um}]")
    m.set_defaults(handler="analysis.afm.cli:import_")
    a = s.add_parser("analyze", help="invert every cell, population statistics, DIR/report.md",
                     description="Invert every cell and frequency (default: on the emulator of the shipped "
                                 "calibration, with 95 % intervals), population statistics, figures and "
                                 "DIR/report.md. Recordings without a modulation segment are listed in the "
                                 "report (exit status 1).")
    a.add_argument("data", nargs="+", metavar="DATA",
                   help="experiment (.h5), single-cell CSV, or JPK files and folders of them")
    a.add_argument("--out", required=True, metavar="DIR", help="output directory (created if missing); a "
                   "non-empty folder cortex did not write is refused (DIR/.cortex-outputs lists what it wrote)")
    from analysis.cli import add_inversion_options
    add_inversion_options(a)
    _jpk_options(a)
    a.set_defaults(handler="analysis.afm.cli:analyze")


def synth(args):
    import json
    from pathlib import Path

    import os

    from analysis.afm import synth as sy
    from analysis.afm.h5format import write_experiment
    from outputs.ownership import check_file
    from outputs.writing import write_atomically
    from solver.errors import InputError
    if args.cells < 1:
        raise InputError(f"--cells must be >= 1 (got {args.cells})")
    out = Path(args.out)
    if os.path.lexists(out):
        raise InputError(f"{out}: exists; refusing to overwrite (it is left as it is)")
    truth_path = check_file(out.parent / "truth.json", _is_our_truth, "truth.json beside --out")
    if args.forward == "law":
        if not args.calibration:
            raise InputError("--forward law needs --calibration CAL.json")
        from analysis.calibration import Calibration
        forward = sy.law_forward(Calibration.load(args.calibration)[args.bending])
    else:
        forward = sy.solver_forward(args.bending)
    cells, truth = sy.generate(args.cells, args.seed, errors=not args.no_errors, forward=forward)
    write_experiment(out, cells)
    text = json.dumps({"format": TRUTH_FORMAT, **truth}, indent=1, default=float) + "\n"
    write_atomically(truth_path, text.encode())
    print(f"wrote {out} ({len(cells)} cells) and {truth_path}")
    return 0


def import_(args):
    import json
    from pathlib import Path

    from analysis.afm.h5format import write_experiment
    from analysis.afm.jpk_import import import_cells
    from solver.errors import InputError
    out = Path(args.out)
    if out.exists() or out.with_name(out.name + ".tmp").exists():
        raise InputError(f"{out}: exists; refusing to overwrite")
    recs, cells = import_cells(args.files, **jpk_options(args))
    write_experiment(out, cells)
    for r in recs:
        if args.json:
            print(json.dumps(r.summary()))
        else:
            print(_summary_line(r))
    if not args.json:
        print(f"wrote {out} ({len(cells)} cells)")
    return 0


def _summary_line(rec):
    """cell, spring constant and segments by kind (count, samples, total duration, frequencies)."""
    parts = []
    for kind in ("approach", "pause", "modulation", "retract"):
        segs = [s for s in rec.segments if s.kind == kind]
        if not segs:
            continue
        text = f"{len(segs)} {kind} ({sum(s.n_samples for s in segs)} samples, {sum(s.duration_s for s in segs):g} s"
        if kind == "modulation":
            text += ", at " + ", ".join(f"{f:g}" for f in sorted({s.frequency_hz for s in segs})) + " Hz"
        parts.append(text + ")")
    return f"{rec.cell_id}: k {rec.spring_constant_N_per_m:.4g} N/m; " + "; ".join(parts)


TRUTH_FORMAT = "cortex-afm-truth"      # the key that says a truth.json is ours (may be replaced)


def _is_our_truth(path):
    from outputs.ownership import json_document
    return json_document(path).get("format") == TRUTH_FORMAT


def analyze(args):
    from analysis.afm.analyze_pipeline import Settings, run
    from analysis.cli import inversion_settings
    from solver.errors import EXIT_DONE, EXIT_SOME_FAILED
    _, _, _, errors = inversion_settings(args)          # also settles the default --method
    result = run(args.data, args.calibration, args.out, Settings(bending=args.bending, method=args.method,
                                                                 errors=errors, jpk_options=jpk_options(args)))
    for cell, reason in result["skipped"].items():
        print(f"not analysed: {cell}: {reason}")
    print(f"report: {result['report']}")
    return EXIT_SOME_FAILED if result["skipped"] else EXIT_DONE
