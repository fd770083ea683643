"""One convention for every command (docs/cli.md): each result-producing
command takes `--json`; every `--out` is a folder (metavar DIR, and it
behaves as one); the same things have the same option names and their
choices come from the name lists' homes; every --help ends with the exit
statuses; a reader that stops early ends a command quietly."""

import argparse
import json
import subprocess

import h5py
import pytest

from analysis.calibration.law import Calibration
from analysis.invert.table import METHODS as INVERSION_METHODS
from studies.synthetic import reference_law
from conftest import CORTEX, ROOT, cortex
from cortex.cli import build_parser, main
from solver.compression import METHODS as SOLVERS
from common.errors import EXIT_BAD_INPUT, EXIT_STATUS_HELP
from solver.model import BENDING_VARIANTS

TINY = """
[campaign]
name = "conventions"
[grid]
h0_um = [12.0, 11.0]
bulk_mN_per_m = 25.0
shear_mN_per_m = [10.0, 25.0]
tension_mN_per_m = 1.0
[test]
fake_law = true
"""


def commands(parser=None, path=()):
    """(command words, parser) of every command that runs (a leaf of the tree)."""
    parser = parser or build_parser()
    subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    if not subs:
        yield path, parser
        return
    for name, child in subs[0].choices.items():
        yield from commands(child, (*path, name))


def options(parser):
    """{option string: action} of a command's parser."""
    return {s: a for a in parser._actions for s in a.option_strings}


COMMANDS = list(commands())
IDS = [" ".join(words) for words, _ in COMMANDS]


def test_the_tree_has_every_command():
    assert {"geometry", "compress", "poroelastic", "campaign run", "campaign status", "campaign verify",
            "campaign repair", "analysis calibrate",
            "analysis viscosity", "analysis build-calibration", "analysis build-viscoelastic-table",
            "analysis build-ramp-table", "analysis build-powerlaw-table", "analysis build-protocol-map", "analysis invert",
            "afm synth", "afm import",
            "afm analyze", "afm tension", "doctor"} == set(IDS)


@pytest.mark.parametrize("words,parser", COMMANDS, ids=IDS)
def test_every_command_takes_json_and_out_is_a_folder(words, parser):
    opts = options(parser)
    assert "--json" in opts and opts["--json"].nargs == 0, words
    if "--out" in opts:
        assert opts["--out"].metavar == "DIR", (words, opts["--out"].metavar)
    assert parser.epilog and EXIT_STATUS_HELP in parser.epilog


@pytest.mark.parametrize("words,parser", COMMANDS, ids=IDS)
def test_same_things_have_the_same_names_and_checked_choices(words, parser):
    opts = options(parser)
    assert "--forward" not in opts
    if "--bending" in opts:
        assert tuple(opts["--bending"].choices) == tuple(BENDING_VARIANTS), words
    if "--solver" in opts:
        assert set(SOLVERS) <= set(opts["--solver"].choices), words
    if "--method" in opts:
        assert tuple(opts["--method"].choices) == tuple(INVERSION_METHODS), words


def test_a_bending_variant_that_does_not_exist_is_refused_everywhere(capsys):
    for words, parser in COMMANDS:
        if "--bending" not in options(parser):
            continue
        assert main([*words, "--bending", "triple"]) == EXIT_BAD_INPUT, words
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "invalid choice: 'triple'" in err[0], (words, err)


def test_out_is_a_folder_in_behaviour(tmp_path, capsys):
    """afm synth writes DIR/experiment.h5 and DIR/truth.json, afm analyze reads that
    folder; an --out that is a file is refused with one line, before any work."""
    cal = Calibration({b: reference_law(b) for b in BENDING_VARIANTS}).save(tmp_path / "cal.json",
                                                                         borrow=("emulator", "viscoelastic_table"))
    exp = tmp_path / "exp"
    assert main(["afm", "synth", "--cells", "3", "--seed", "4", "--solver", "law", "--calibration", str(cal),
                 "--out", str(exp), "--json"]) == 0
    said = json.loads(capsys.readouterr().out)
    assert said == {"experiment": str(exp / "experiment.h5"), "truth": str(exp / "truth.json"), "n_cells": 3}
    with h5py.File(exp / "experiment.h5", "r") as f:
        assert len(f["cells"]) == 3
    assert len(json.loads((exp / "truth.json").read_text())["cells"]) == 3
    status = main(["afm", "analyze", str(exp), "--calibration", str(cal), "--method", "law",
                   "--out", str(tmp_path / "an"), "--json"])
    result = json.loads(capsys.readouterr().out)
    assert status in (0, 1) and result["report"] == str(tmp_path / "an" / "report.md")
    assert {r["frequency_hz"] for r in result["frequencies"]} and all("median_nu" in r for r in result["frequencies"])
    a_file = tmp_path / "a-file"
    a_file.write_text("mine\n")
    for args in (["afm", "synth", "--cells", "1", "--solver", "law", "--calibration", str(cal)],
                 ["afm", "analyze", str(exp), "--calibration", str(cal), "--method", "law"]):
        assert main([*args, "--out", str(a_file)]) == EXIT_BAD_INPUT
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "not a directory" in err[0], err
    assert a_file.read_text() == "mine\n"


def test_campaign_json_and_a_reader_that_stops_early(tmp_path):
    """`campaign run --json` prints the store's summary; `campaign status STORE | head -1`
    (here: a pipe whose reader has already gone) ends quietly, no traceback."""
    (tmp_path / "c.toml").write_text(TINY)
    store = tmp_path / "s.h5"
    run = cortex("campaign", "run", tmp_path / "c.toml", "--store", store, "--quiet", "--json")
    assert run.returncode == 0, run.stderr
    info = json.loads(run.stdout)
    assert info["store"] == str(store) and info["exit_status"] == 0 and info["tasks"] == info["done"] == 4
    for args in (["campaign", "status", str(store)], ["campaign", "status", str(store), "--json"]):
        proc = subprocess.Popen([str(CORTEX), *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=ROOT)
        proc.stdout.close()                          # the reader stops before the first line
        err = proc.stderr.read().decode()
        assert proc.wait(timeout=120) == 0 and err == "", err


def test_the_command_line_is_the_top_floor():
    """Nothing below cortex/ imports `cortex` (the version comes from package metadata)."""
    import ast
    offenders = []
    for path in ROOT.glob("*/**/*.py"):
        top = path.relative_to(ROOT).parts[0]
        if top in ("cortex", "tests", ".venv", "build") or top.startswith(".venv"):
            continue
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                     else [node.module or ""] if isinstance(node, ast.ImportFrom) and not node.level else [])
            offenders += [f"{path.relative_to(ROOT)}:{node.lineno}" for n in names if n.split(".")[0] == "cortex"]
    assert not offenders, offenders


def test_help_and_the_packages_load_no_numpy():
    """`cortex --help` (the whole parser) and `import solver, campaign, analysis` stay light;
    each package's public names (`__all__`) resolve when asked for."""
    code = ("import sys; import cortex.cli, solver, campaign, analysis, analysis.afm, outputs; "
            "cortex.cli.build_parser(); print(sorted(m for m in ('numpy', 'numba', 'h5py', 'mpi4py') "
            "if m in sys.modules))")
    done = subprocess.run([str(CORTEX.with_name("python")), "-c", code], capture_output=True, text=True,
                          cwd=ROOT, timeout=120)
    assert done.returncode == 0 and done.stdout.strip() == "[]", (done.stdout, done.stderr)
    import importlib
    for name in ("solver", "campaign", "analysis", "analysis.afm", "outputs", "cortex"):
        package = importlib.import_module(name)
        assert package.__all__, name
        for public in package.__all__:
            assert getattr(package, public) is not None, (name, public)


def test_every_command_runs_a_function_of_its_own_command_module():
    """A command's handler is a function reference (no "module:function" string), of the command
    module that registers it; no command module imports another as a library."""
    import ast
    import inspect
    for words, parser in COMMANDS:
        handler = parser.get_default("handler")
        assert inspect.isfunction(handler), (words, handler)
        assert handler.__module__.startswith("cortex.commands."), (words, handler.__module__)
    for path in sorted((ROOT / "cortex" / "commands").glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.ImportFrom) and node.level:
                raise AssertionError(f"{path.name}:{node.lineno}: a relative import")
            names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                     else [node.module or ""] if isinstance(node, ast.ImportFrom) else [])
            assert not [n for n in names if n.startswith("cortex.commands")], f"{path.name}:{node.lineno}"


def test_under_mpiexec_a_one_process_command_is_one_line_and_a_ranked_one_writes_once(tmp_path):
    """Under `mpiexec -n 2` every rank would run the whole command: a command that does not use
    ranks (`geometry`) is one line from rank 0 and status 2; `afm synth` (rank 0 writes, the other
    ranks simulate where it is in time) writes its experiment once, status 0."""
    one = cortex("geometry", "--volume", 4300, "--height", 12, mpi=2)
    assert one.returncode == EXIT_BAD_INPUT and one.stdout == ""
    assert one.stderr.splitlines() == ["cortex geometry: error: runs in one process; under mpiexec only `campaign run`, "
                                       "`afm analyze`, `afm synth` and `doctor` run (docs/cli.md)"]
    made = cortex("afm", "synth", "--cells", 2, "--out", tmp_path / "exp", mpi=2)
    assert made.returncode == 0, made.stderr
    assert made.stdout.count("wrote ") == 1 and (tmp_path / "exp" / "experiment.h5").is_file()
