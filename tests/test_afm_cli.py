"""`cortex afm`: synth and analyze end to end; the tension filter's tolerance; malformed input ->
one line, status 2."""

import dataclasses
import json
import os
import subprocess

import h5py
import numpy as np
import pandas as pd
import pytest

from analysis.afm.analyze import TENSION_TOLERANCE
from analysis.afm.formats.csvcell import write_csv_cell
from analysis.afm.formats.h5 import write_experiment
from analysis.afm.provenance import FREQUENCY_DOMAIN
from analysis.afm.synth.cells import generate, law_forward
from analysis.calibration.law import Calibration
from studies.synthetic import reference_law
from conftest import BIN, ROOT
from cortex.cli import main

BORROW = ("emulator", "viscoelastic_table")      # a law-only file that borrows the shipped emulator and table


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    d = tmp_path_factory.mktemp("afm")
    cal = d / "cal.json"
    Calibration({b: reference_law(b) for b in ("standard", "double", "none")}).save(cal, borrow=BORROW)
    cells, _ = generate(4, seed=2, errors=True, forward=law_forward(reference_law()))
    good = d / "good.h5"
    write_experiment(good, cells, FREQUENCY_DOMAIN)
    return d, cal, good, cells


def test_synth_and_analyze(setup, tmp_path, capsys):
    d, cal, _, _ = setup
    data = tmp_path / "exp"
    assert main(["afm", "synth", "--cells", "6", "--seed", "1", "--out", str(data), "--solver", "law",
                 "--calibration", str(cal)]) == 0
    truth = json.loads((data / "truth.json").read_text())
    assert len(truth["cells"]) == 6
    assert main(["afm", "analyze", str(data), "--calibration", str(cal), "--out", str(tmp_path / "out")]) == 0
    s = json.loads((tmp_path / "out/summary.json").read_text())
    keys = {"frequency_hz", "n_cells", "n_excluded", "median_nu", "iqr_nu", "lognormal_mu", "lognormal_sigma"}
    assert s["frequencies"] and all(keys <= set(r) for r in s["frequencies"])
    assert (tmp_path / "out/report.md").read_text().count("|") > 20
    assert s["calibration_parts"] == {"law": str(cal), "emulator": "shipped", "viscoelastic_table": "shipped"}
    assert "| emulator | shipped |" in (tmp_path / "out/report.md").read_text()
    for name in ("nu_histograms.png", "nu_boxplots.png", "k_curves.png", "cells_double.csv", "cells_none.csv"):
        assert (tmp_path / "out" / name).is_file()
    # refuses to overwrite
    capsys.readouterr()
    assert main(["afm", "synth", "--cells", "2", "--out", str(data), "--solver", "law",
                 "--calibration", str(cal)]) == 2


def test_the_batch_job_reads_on_its_ranks_as_one_process_does(setup, tmp_path):
    """jobs/afm-analyze.sbatch, run as SLURM runs it (outside SLURM here: two ranks by default):
    `mpiexec -n 2 cortex afm analyze DATA --out DIR OPTIONS`, the same cells.csv as one process
    writes; without DATA and DIR its usage line and status 2."""
    _, cal, good, _ = setup
    job = [str(ROOT / "jobs" / "afm-analyze.sbatch")]
    env = {**os.environ, "CORTEX_VENV": str(BIN.parent)}
    options = ["--calibration", str(cal), "--no-phase"]
    run = subprocess.run(["bash", *job, str(good), "ranks", *options], cwd=tmp_path, env=env, capture_output=True,
                         text=True, timeout=600, stdin=subprocess.DEVNULL)
    assert run.returncode == 0, run.stdout + run.stderr
    assert f"mpiexec -n 2 {BIN / 'cortex'} afm analyze {good} --out ranks --calibration" in run.stdout
    assert main(["afm", "analyze", str(good), "--out", str(tmp_path / "one"), *options]) == 0
    assert (tmp_path / "ranks" / "cells.csv").read_bytes() == (tmp_path / "one" / "cells.csv").read_bytes()
    usage = subprocess.run(["bash", *job], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=60)
    assert usage.returncode == 2 and usage.stderr.startswith("afm-analyze.sbatch: usage:"), usage.stderr


def test_tension_tolerance_excludes_or_keeps_a_blebbing_cell(setup, tmp_path, capsys):
    """Seed 0's cell002 blebs: its segments' mean tension deviates 34 % from its median (the
    others 0.7-4.6 %). The published 0.1 excludes it (the reason names the limit); 0.5 and inf
    keep it; summary.json says which tolerance (null for inf)."""
    _, cal, _, _ = setup
    data = tmp_path / "exp"
    assert main(["afm", "synth", "--cells", "4", "--seed", "0", "--out", str(data), "--solver", "law",
                 "--calibration", str(cal), "--json"]) == 0
    for given, written, kept in ((None, 0.1, False), ("0.5", 0.5, True), ("inf", None, True)):
        out = tmp_path / f"out{given}"
        option = [] if given is None else ["--tension-tolerance", given]
        assert main(["afm", "analyze", str(data), "--calibration", str(cal), "--out", str(out), "--no-phase",
                     "--method", "law", *option]) == 0
        table = pd.read_csv(out / "cells.csv")
        assert table.loc[table["cell_id"] == "cell002", "tension_deviation"].iloc[0] == pytest.approx(0.343, abs=0.01)
        by_tension = table["excluded_reason"].astype("string").str.contains("tension", na=False)
        assert set(table.loc[by_tension, "cell_id"]) == (set() if kept else {"cell002"}), given
        assert json.loads((out / "summary.json").read_text())["tension_tolerance"] == written
    assert "limit 10 %" in pd.read_csv(tmp_path / "outNone" / "cells.csv")["excluded_reason"].dropna().iloc[0]


def test_the_help_names_the_published_tolerance(capsys):
    assert main(["afm", "analyze", "--help"]) == 0
    assert f"(default {TENSION_TOLERANCE:g}, as published;" in " ".join(capsys.readouterr().out.split())


@pytest.mark.parametrize("value", ["-0.1", "nan"])
def test_impossible_tension_tolerance_is_refused(setup, tmp_path, capsys, value):
    _, cal, good, _ = setup
    assert main(["afm", "analyze", str(good), "--calibration", str(cal), "--out", str(tmp_path / "o"),
                 "--tension-tolerance", value]) == 2
    err = capsys.readouterr().err
    assert "tension tolerance" in err and "Traceback" not in err and not (tmp_path / "o").exists()


def _h5(path, cells, edit):
    write_experiment(path, cells)
    with h5py.File(path, "r+") as f:
        edit(f, f["cells"][cells[0].cell_id])
    return path


def _replace(name, fn):
    def edit(f, g):
        data = fn(g[name][()])
        del g[name]
        g.create_dataset(name, data=data)
    return edit


def _csv(path, cell, edit):
    write_csv_cell(path, cell)
    path.write_text(edit(path.read_text()))
    return path


def _bad_time(t):
    t = t.copy()
    t[10] = t[9]
    return t


def _nan(x):
    x = x.copy()
    x[5] = np.nan
    return x


BAD = {
    "missing file": lambda d, c: d / "nope.h5",
    "unknown suffix": lambda d, c: (d / "x.dat").write_text("1") and d / "x.dat",
    "truncated h5": lambda d, c: (d / "t.h5").write_bytes(
        (write_experiment(d / "full.h5", c[:1]) or (d / "full.h5")).read_bytes()[:3000]) and d / "t.h5",
    "not hdf5": lambda d, c: (d / "txt.h5").write_text("hello") and d / "txt.h5",
    "wrong format attr": lambda d, c: _h5(d / "f.h5", c, lambda f, g: f.attrs.__setitem__("format", "x")),
    "wrong version": lambda d, c: _h5(d / "v.h5", c, lambda f, g: f.attrs.__setitem__("version", 9)),
    "no cells": lambda d, c: _h5(d / "n.h5", c, lambda f, g: [f["cells"].__delitem__(k) for k in list(f["cells"])]),
    "missing volume": lambda d, c: _h5(d / "mv.h5", c, lambda f, g: g.attrs.__delitem__("volume_um3")),
    "negative volume": lambda d, c: _h5(d / "nv.h5", c, lambda f, g: g.attrs.__setitem__("volume_um3", -5.0)),
    "missing force": lambda d, c: _h5(d / "mf.h5", c, lambda f, g: g.__delitem__("force_nN")),
    "NaN force": lambda d, c: _h5(d / "nan.h5", c, _replace("force_nN", _nan)),
    "non-monotonic time": lambda d, c: _h5(d / "nm.h5", c, _replace("time_s", _bad_time)),
    "heights in m": lambda d, c: _h5(d / "m.h5", c, _replace("height_um", lambda h: h * 1e-6 - 1e-9)),
    "short column": lambda d, c: _h5(d / "sc.h5", c, _replace("height_um", lambda h: h[:-5])),
    "segment out of range": lambda d, c: _h5(d / "so.h5", c, _replace(
        "segments", lambda s: np.array([tuple(r) for r in s[:-1]] + [(b"oscillation", 0, 10 ** 9, 1.0)], s.dtype))),
    "segment too short": lambda d, c: _h5(d / "st.h5", c, _replace(
        "segments", lambda s: np.array([(b"oscillation", 0, 3, 0.1)], s.dtype))),
    "zero frequency": lambda d, c: _h5(d / "zf.h5", c, _replace(
        "segments", lambda s: np.array([(k, a, b, 0.0 if k == b"oscillation" else f) for k, a, b, f in s], s.dtype))),
    "unknown segment kind": lambda d, c: _h5(d / "uk.h5", c, _replace(
        "segments", lambda s: np.array([(b"wiggle", a, b, f) for k, a, b, f in s], s.dtype))),
    "height above sphere": lambda d, c: _h5(d / "hs.h5", c, _replace("height_um", lambda h: h + 30.0)),
    "csv missing volume": lambda d, c: _csv(d / "a.csv", c[0], lambda t: t.replace("# volume_um3:", "# vol:")),
    "csv volume not a number": lambda d, c: _csv(d / "b.csv", c[0], lambda t: t.replace(
        f"# volume_um3: {c[0].volume_um3!r}", "# volume_um3: big")),
    "csv wrong unit column": lambda d, c: _csv(d / "u.csv", c[0], lambda t: t.replace("force_nN", "force_N")),
    "csv non-numeric": lambda d, c: _csv(d / "nn.csv", c[0], lambda t: t.replace("\n1.0", "\nabc", 1)),
    "csv empty": lambda d, c: (d / "e.csv").write_text("") or d / "e.csv",
    "csv binary": lambda d, c: (d / "bin.csv").write_bytes(b"\xff\xfe\x00\x81" * 50) and d / "bin.csv",
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_malformed_input_one_line_status_2(setup, tmp_path, capsys, case):
    d, cal, _, cells = setup
    data = BAD[case](tmp_path, cells)
    capsys.readouterr()
    status = main(["afm", "analyze", str(data), "--calibration", str(cal), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert status == 2, err
    assert len(err.strip().splitlines()) == 1 and "error" in err and "Traceback" not in err


def test_bad_calibration_and_variant(setup, tmp_path, capsys):
    d, cal, good, _ = setup
    (tmp_path / "c.json").write_text("{")
    assert main(["afm", "analyze", str(good), "--calibration", str(tmp_path / "c.json"), "--out", str(tmp_path)]) == 2
    assert main(["afm", "analyze", str(good), "--calibration", str(cal), "--out", str(tmp_path),
                 "--bending", "triple"]) == 2
    assert main(["afm", "synth", "--cells", "0", "--out", str(tmp_path / "z")]) == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 3


def test_a_law_only_calibration_does_not_borrow_the_shipped_emulator(setup, tmp_path, capsys):
    """A law-only file without a manifest: the viscoelastic reading (on by default) is refused in one
    line, before any output; with --no-phase it reads with its law, and summary.json says so."""
    _, _, good, _ = setup
    law_only = Calibration({b: reference_law(b) for b in ("standard", "double", "none")}).save(tmp_path / "law.json")
    capsys.readouterr()
    assert main(["afm", "analyze", str(good), "--calibration", str(law_only), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "viscoelastic reading" in err and '"shipped"' in err
    assert not (tmp_path / "o").exists()
    assert main(["afm", "analyze", str(good), "--calibration", str(law_only), "--out", str(tmp_path / "o"),
                 "--no-phase"]) == 0
    said = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert said["method"] == "law" and said["calibration_parts"] == {"law": str(law_only)}


def test_analyze_reads_the_calibration_file_once(setup, tmp_path, monkeypatch):
    """The calibration file is read and parsed once per `afm analyze` and handed down."""
    import analysis.calibration.file
    _, cal, good, _ = setup
    reads = []
    real = analysis.calibration.file.read_document
    monkeypatch.setattr(analysis.calibration.file, "read_document", lambda path: reads.append(path) or real(path))
    analysis.calibration.file._shipped.cache_clear()            # as in a new process
    assert main(["afm", "analyze", str(good), "--calibration", str(cal), "--no-phase",
                 "--out", str(tmp_path / "out")]) == 0
    from analysis.calibration.file import shipped_path
    assert [str(p) for p in reads] == [str(cal), str(shipped_path())]      # the file, and the bundle it borrows from


def test_the_second_process_changes_no_byte(setup, tmp_path, monkeypatch, capsys):
    """afm analyze inverts the other bending variants in a forked child (`common.beside`)
    where two CPUs serve: every table and summary is byte for byte the serial run's."""
    import common.beside
    assert common.beside.forking(), "this test needs fork and two CPUs"
    d, _, good, _ = setup
    assert main(["afm", "analyze", str(good), "--out", str(tmp_path / "forked")]) == 0
    monkeypatch.setattr(common.beside, "forking", lambda: False)
    assert main(["afm", "analyze", str(good), "--out", str(tmp_path / "serial")]) == 0
    names = sorted(p.name for p in (tmp_path / "serial").iterdir() if p.suffix in (".csv", ".json", ".md"))
    assert {"cells_double.csv", "cells_none.csv", "summary_double.json", "population.json"} <= set(names)
    for name in names:
        assert (tmp_path / "forked" / name).read_bytes() == (tmp_path / "serial" / name).read_bytes(), name


def test_a_tip_cantilever_warns_once_on_stderr_and_in_the_report(setup, tmp_path, capsys):
    """A cell recorded with a 0.01 N/m cantilever (tip microrheology's) gets one warning line on
    stderr and in report.md; the plate cells none."""
    d, cal, _, cells = setup
    tipped = [dataclasses.replace(c, spring_constant_N_per_m=0.01) if i == 1 else c for i, c in enumerate(cells)]
    write_experiment(tmp_path / "tip.h5", tipped, FREQUENCY_DOMAIN)
    capsys.readouterr()
    assert main(["afm", "analyze", str(tmp_path / "tip.h5"), "--calibration", str(cal), "--out",
                 str(tmp_path / "out"), "--no-phase"]) in (0, 1)
    said = [x for x in capsys.readouterr().err.splitlines() if "plate confinement" in x]
    assert len(said) == 1 and cells[1].cell_id in said[0] and "spring constant 0.01 N/m" in said[0]
    report = (tmp_path / "out" / "report.md").read_text()
    assert report.count("does not look like plate confinement") == 1 and said[0] in report
