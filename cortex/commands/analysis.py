"""`cortex analysis calibrate STORE --out DIR [--partial]`, `cortex analysis
viscosity STORE --out DIR`, `cortex analysis build-calibration --out DIR`,
`cortex analysis build-viscoelastic-table STORE --out DIR`, `cortex analysis
build-ramp-table STORE --out DIR`, `cortex analysis build-powerlaw-table STORE --out DIR`,
`cortex analysis build-protocol-map STORE --out DIR` and `cortex analysis invert TABLE.csv --out DIR` (argparse only; the work is
imported when the command runs). Every one takes `--json` (its results as one
JSON object or list on stdout) and writes into its `--out` folder under the
manifest rules of `outputs.ownership.OutputDir`."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import Any

from cortex.options import OUT_HELP, Commands, add_inversion_options, inversion_settings
from cortex.results import plain, say_result

CALIBRATION_FILE = "calibration.json"     # what build-calibration writes into its --out folder
TABLE_FILE = "viscoelastic_table.json"    # what build-viscoelastic-table writes into its --out folder
RAMP_TABLE_FILE = "shell_ramp_table.json"  # what build-ramp-table writes into its --out folder
POWERLAW_TABLE_FILE = "powerlaw_table.json"  # what build-powerlaw-table writes into its --out folder
PROTOCOL_MAP_FILE = "protocol_map.json"    # what build-protocol-map writes into its --out folder (and figures)


def register(sub: Commands) -> None:
    p = sub.add_parser("analysis", help="calibration laws and Monte-Carlo study of a finished campaign",
                       description="Analyse a campaign store: calibration laws (SPEC 4), reconstruction "
                                   "check, Monte-Carlo error study (SPEC 5), figures and a report.")
    s = p.add_subparsers(dest="subcommand", metavar="SUBCOMMAND", required=True)
    for add in (_add_calibrate, _add_viscosity, _add_build_calibration, _add_build_table, _add_build_ramp_table,
                _add_build_powerlaw_table, _add_build_protocol_map, _add_invert):
        add(s)


def _add_calibrate(s: Commands) -> None:
    c = s.add_parser("calibrate", help="fit the calibration laws, check them, write DIR/report.md",
                     description="Fit K(h~) = K_B (1 + alpha exp(h~/lambda)) per bending variant, "
                                 "alpha = C ln(K_S/K_B) + D with cubic C, D in gamma_a/K_B; check the "
                                 "reconstruction of nu; summarise the Monte-Carlo trials. Writes "
                                 "DIR/calibration.json, CSV tables, figures and DIR/report.md.")
    c.add_argument("store", metavar="STORE", help="campaign store (HDF5)")
    c.add_argument("--out", required=True, metavar="DIR", help=OUT_HELP)
    c.add_argument("--partial", action="store_true",
                   help="analyse an unfinished store with what is done, saying what was left out")
    c.add_argument("--json", action="store_true", help="one JSON object: report, lambda per bending variant, "
                   "left_out, wall_s")
    c.set_defaults(handler=calibrate)


def _add_viscosity(s: Commands) -> None:
    v = s.add_parser("viscosity", help="|K*|/K and loss angle of a viscous-interior campaign",
                     description="Tabulate and plot the viscous-interior study (SPEC 7) of a campaign "
                                 "with viscosity_Pa_s and frequency_hz grid axes: |K*|/K and the loss "
                                 "angle against eta, one line per frequency, and the largest viscosity "
                                 "per frequency at which the elastic calibration holds to 1 %. Writes "
                                 "DIR/viscosity.csv, DIR/viscosity.png/.pdf and DIR/viscosity.md.")
    v.add_argument("store", metavar="STORE", help="campaign store (HDF5)")
    v.add_argument("--out", required=True, metavar="DIR", help=OUT_HELP)
    v.add_argument("--json", action="store_true", help="one JSON object: report and the rows of viscosity.csv")
    v.set_defaults(handler=viscosity)


def _add_build_calibration(s: Commands) -> None:
    b = s.add_parser("build-calibration", help="the calibration file: emulator tables + paper law + provenance",
                     description="Build DIR/calibration.json (format version 2) from a finished emulator "
                                 "campaign store (campaigns/emulator.toml) and, optionally, the paper "
                                 "campaign's store (its law, for --method law). Its manifest names the viscoelastic and "
                                 "ramp tables DIR holds and borrows the shipped ones otherwise (docs/calibration.md). "
                                 "`make calibration` rebuilds the one shipped in the package this way.")
    b.add_argument("--emulator-store", required=True, metavar="STORE.h5")
    b.add_argument("--law-store", metavar="STORE.h5", help="store of campaigns/paper.toml (optional)")
    b.add_argument("--out", required=True, metavar="DIR", help=OUT_HELP + "; a folder holding only a "
                   "calibration.json cortex wrote (like analysis/calibration/data) is accepted")
    b.add_argument("--json", action="store_true", help="one JSON object: calibration, emulator and law variants")
    b.set_defaults(handler=build_calibration)


def _add_table_builder(s: Commands, name: str, help: str, description: str, what: str, json_help: str,
                       handler: Callable[[argparse.Namespace], int], needs: str = "every node done") -> None:
    """`cortex analysis NAME STORE --out DIR [--json]`: a table from its campaign's store (`needs`: of its nodes)."""
    b = s.add_parser(name, help=help, description=description)
    b.add_argument("store", metavar="STORE", help=f"store of a {what} campaign (HDF5), {needs}")
    b.add_argument("--out", required=True, metavar="DIR", help=OUT_HELP)
    b.add_argument("--json", action="store_true", help=json_help)
    b.set_defaults(handler=handler)


def _add_build_table(s: Commands) -> None:
    _add_table_builder(
        s, "build-viscoelastic-table", "the complex correspondence table from its campaign's store",
        "Build DIR/viscoelastic_table.json (the factor C of SPEC 10: ln C's polynomial coefficients per node, "
        "analysis/calibration/viscoelastic_table.py) from a finished store of campaigns/viscoelastic.toml. "
        "`make viscoelastic-table` rebuilds the one shipped in the package this way.",
        "viscoelastic-table", "one JSON object: table file, nodes, volumes", build_viscoelastic_table)


def _add_build_ramp_table(s: Commands) -> None:
    _add_table_builder(
        s, "build-ramp-table", "the shell ramp table from its campaign's store",
        "Build DIR/shell_ramp_table.json (F/(K_B R) of the shell pressed from its free sphere per depth and "
        "node, analysis/afm/tension/shell_table.py) from a finished store of campaigns/ramp.toml. `make "
        "ramp-table` rebuilds the one shipped in the package this way.",
        "ramp-table", "one JSON object: table file, nodes, depths filled", build_ramp_table)


def _add_build_powerlaw_table(s: Commands) -> None:
    _add_table_builder(
        s, "build-powerlaw-table", "the power-law ramp and hold table from its campaign's store",
        "Build DIR/powerlaw_table.json (the time-domain shell's ramp from its droplet and constant-height hold "
        "per node, the model of `afm tension`'s power-law reading; analysis/afm/tension/powerlaw_grid.py) from "
        "a finished store of campaigns/powerlaw-table.toml. `make powerlaw-table` rebuilds the one shipped in "
        "the package this way.",
        "powerlaw-table", "one JSON object: table file, nodes, nodes failed", build_powerlaw_table,
        "every node finished (a failed node is left out of the table)")


def _add_build_protocol_map(s: Commands) -> None:
    _add_table_builder(
        s, "build-protocol-map", "the protocol's bias map from its campaign's store",
        "Build DIR/protocol_map.json (per node: the segment fit of a recording simulated in time against the "
        "relaxed-state model, |K*| ratio and loss-angle error; SPEC 12, analysis/afm/synth/protocol_map.py) and "
        "its figures DIR/protocol_map_loss_angle.png/.pdf and DIR/protocol_map_modulus.png/.pdf from a "
        "finished store of campaigns/protocol.toml. `make protocol-map` runs both steps.",
        "protocol-bias", "one JSON object: map file, figures, nodes and the summary", build_protocol_map,
        "every node finished (a failed node is listed apart)")


def _add_invert(s: Commands) -> None:
    i = s.add_parser("invert", help="nu per cell (and frequency) from a table of K(h~), with 95 %% intervals",
                     description="Invert a CSV table with columns cell_id, h_tilde, modulus_mN_per_m, "
                                 "tension_mN_per_m (optional frequency_hz, volume_um3; one row per cell "
                                 "and height) into nu per cell and frequency. Writes DIR/cells.csv; with "
                                 "--json also a JSON list on stdout.")
    i.add_argument("table", metavar="TABLE.csv")
    i.add_argument("--volume", type=float, metavar="UM3",
                   help="one cell volume (um^3) for every cell of a table without a volume_um3 column")
    i.add_argument("--out", required=True, metavar="DIR", help=OUT_HELP)
    add_inversion_options(i)
    i.add_argument("--json", action="store_true", help="print the per-cell results as a JSON list")
    i.set_defaults(handler=invert)


def calibrate(args: argparse.Namespace) -> int:
    from analysis.calibration.command.pipeline import run
    result = run(args.store, args.out, partial=args.partial)
    laws = result["calibration"].laws
    say_result(args, {"report": str(result["report"]), "lambda": {b: law.lam for b, law in laws.items()},
                      "left_out": list(result["left_out"]), "wall_s": result["wall_s"]},
               f"report: {result['report']}")
    return 0


def viscosity(args: argparse.Namespace) -> int:
    import pandas as pd

    from analysis.viscosity import run
    report = run(args.store, args.out)
    rows = pd.read_csv(report.with_name("viscosity.csv")).to_dict("records") if args.json else []
    say_result(args, {"report": str(report), "rows": rows}, f"report: {report}")
    return 0


def build_calibration(args: argparse.Namespace) -> int:
    from analysis.calibration import file
    from outputs.ownership import OutputDir
    out = OutputDir(args.out)
    out.check([CALIBRATION_FILE])                   # a folder or file that is not ours is left alone
    doc = file.build(args.emulator_store, args.law_store, progress=_say, folder=args.out)
    with out.writing(CALIBRATION_FILE) as path:
        file.write(doc, path)
    say_result(args, {"calibration": str(path), "emulator_variants": list(doc["emulator"]),
                      "law_variants": list(doc["variants"])},
               f"wrote {path} (emulator: {', '.join(doc['emulator'])}; law: {', '.join(doc['variants']) or 'none'})")
    return 0


def _write_table(args: argparse.Namespace, name: str, from_store: Callable[[str], dict[str, Any]]) -> dict[str, Any]:
    """DIR/`name` (DIR = --out) from the store's document `from_store(STORE)`: that document,
    with the file written as its `path`."""
    import json

    from outputs.ownership import OutputDir
    from outputs.writing import write_atomically
    out = OutputDir(args.out)
    out.check([name])                         # refused before any work if not ours
    doc = from_store(args.store)
    with out.writing(name) as path:
        write_atomically(path, (json.dumps(doc) + "\n").encode())
    return {**doc, "path": path}


def build_viscoelastic_table(args: argparse.Namespace) -> int:
    from analysis.calibration.viscoelastic_table import from_store
    doc = _write_table(args, TABLE_FILE, from_store)
    path = doc.pop("path")
    nodes = len(doc["volume_um3"]) * len(doc["h_tilde"]) * len(doc["ks_tilde"]) * len(doc["gamma_tilde"])
    say_result(args, {"table": str(path), "nodes": nodes, "volume_um3": doc["volume_um3"]},
               f"wrote {path} ({nodes} nodes)")
    return 0


def build_ramp_table(args: argparse.Namespace) -> int:
    from analysis.afm.tension.shell_table import from_store
    doc = _write_table(args, RAMP_TABLE_FILE, from_store)
    nodes = len(doc["radius_um"]) * len(doc["gamma_tilde"]) * len(doc["shear_tilde"])
    say_result(args, {"table": str(doc["path"]), "nodes": nodes, "filled": doc["filled"]},
               f"wrote {doc['path']} ({nodes} nodes, {doc['filled']} depths filled)")
    return 0


def build_powerlaw_table(args: argparse.Namespace) -> int:
    import numpy as np

    from analysis.afm.tension.powerlaw_grid import from_store
    doc = _write_table(args, POWERLAW_TABLE_FILE, from_store)
    r = np.asarray(doc["hold_ratio"], dtype=float)
    nodes, failed = r[..., 0].size, int(np.isnan(r[..., 0]).sum())
    say_result(args, {"table": str(doc["path"]), "nodes": nodes, "failed": failed},
               f"wrote {doc['path']} ({nodes} nodes, {failed} failed)")
    return 0


def build_protocol_map(args: argparse.Namespace) -> int:
    from analysis.afm.synth.protocol_map import FIGURES, figures, from_store
    from outputs.ownership import OutputDir
    OutputDir(args.out).check([f"{n}.{e}" for n in FIGURES for e in ("png", "pdf")])   # before any work
    doc = _write_table(args, PROTOCOL_MAP_FILE, from_store)
    shown = figures(doc, OutputDir(args.out))
    summary = doc["summary"]
    say_result(args, {"map": str(doc["path"]), "figures": [str(p) for p in shown], "summary": summary},
               f"wrote {doc['path']} ({summary['nodes']} nodes done, {summary['nodes_failed']} failed; "
               f"{summary['nodes_off']} off the relaxed-state "
               f"model by more than {summary['loss_angle_tolerance_rad']:g} rad or "
               f"{summary['modulus_tolerance']:.0%})")
    return 0


def invert(args: argparse.Namespace) -> int:
    import json

    from analysis.invert.method import invert_rows
    from analysis.invert.table_input import read_table
    from outputs.ownership import OutputDir
    rows = read_table(args.table, args.volume)
    file, errors = inversion_settings(args)
    out = OutputDir(args.out)
    out.check(["cells.csv"])                        # refused before any work if not ours
    table = invert_rows(rows, args.method or file.default_method, file.calibration, file.emulator, args.bending, errors)
    with out.writing("cells.csv") as path:
        table.to_csv(path, index=False)
    if args.json:
        keys = ["cell_id", "frequency_hz", "nu", "nu_lo95", "nu_hi95", "ks_tilde", "bulk_mN_per_m", "r2",
                "method", "excluded_reason"]
        records = [{k: plain(r[k]) for k in keys} for _, r in table.iterrows()]
        print(json.dumps(records))
    else:
        print(f"wrote {path} ({len(table)} curves, {int(table['excluded_reason'].isna().sum())} included)")
    return 0


def _say(message: str) -> None:
    import sys
    print(message, file=sys.stderr)

