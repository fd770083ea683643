"""A path that is not ours is never moved or replaced: `--store` naming a
folder, a text file or another program's HDF5 file, and `--out` folders and
files of the analyses, are refused with one line and exit status 2 and left
byte for byte as they were; what cortex wrote itself may be replaced."""

import hashlib
import os
import subprocess

import h5py
import numpy as np
import pytest

from analysis.afm.formats.h5 import write_experiment
from analysis.afm.provenance import FREQUENCY_DOMAIN
from analysis.afm.synth.cells import generate, law_forward
from analysis.calibration.law import Calibration
from studies.synthetic import reference_law
from conftest import BIN, ROOT
from cortex.cli import main
from outputs.ownership import MANIFEST

TINY = """
[grid]
h0_um = [12.0, 11.0]
bulk_mN_per_m = 25.0
shear_mN_per_m = 10.0
tension_mN_per_m = 1.0
[test]
fake_law = true
"""


def snapshot(root):
    """Every path under (and including) `root` with its kind, mode and content hash."""
    root = str(root)
    walk = [(root, [], [])] if os.path.isfile(root) else os.walk(root)
    out = {}
    for folder, dirs, files in walk:
        out[folder] = ("dir" if os.path.isdir(folder) else "file", os.stat(folder).st_mode, os.stat(folder).st_mtime_ns)
        for name in files:
            p = os.path.join(folder, name)
            out[p] = ("file", os.stat(p).st_mode, os.stat(p).st_mtime_ns,
                      hashlib.sha256(open(p, "rb").read()).hexdigest())
    if os.path.isfile(root):
        out[root] += (hashlib.sha256(open(root, "rb").read()).hexdigest(),)
    return out


def run_campaign(tmp_path, store, *extra):
    config = tmp_path / "tiny.toml"
    config.write_text(TINY)
    return subprocess.run([str(BIN / "cortex"), "campaign", "run", str(config), "--store", str(store), "--quiet",
                           *extra], capture_output=True, text=True, cwd=ROOT, timeout=300)


def foreign_hdf5(path):
    with h5py.File(path, "w") as f:
        f["state"] = np.arange(4)             # looks a little like ours, but is not
        f.attrs["owner"] = "another program"
    return path


def make_folder(path):
    path.mkdir()
    (path / "notes.txt").write_text("my notes\n")
    return path


def make_text(path):
    path.write_text("not a store\n")
    return path


@pytest.mark.parametrize("make", [make_folder, make_text, foreign_hdf5], ids=["folder", "text", "foreign-hdf5"])
@pytest.mark.parametrize("new", [False, True], ids=["run", "new"])
def test_store_that_is_not_ours_is_refused_and_untouched(tmp_path, make, new):
    (tmp_path / "place").mkdir()
    target = make(tmp_path / "place" / "results")
    before, neighbours = snapshot(target), sorted(os.listdir(target.parent))
    out = run_campaign(tmp_path, target, *(["--new"] if new else []))
    assert out.returncode == 2, out.stderr
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and "--store" in lines[0] and str(target) in lines[0], lines
    assert snapshot(target) == before
    assert sorted(os.listdir(target.parent)) == neighbours            # nothing set aside or made beside it


def test_a_folder_given_with_a_trailing_slash_is_refused(tmp_path):
    target = make_folder(tmp_path / "results")
    before = snapshot(target)
    out = run_campaign(tmp_path, str(target) + "/")
    assert out.returncode == 2 and len(out.stderr.strip().splitlines()) == 1, out.stderr
    assert snapshot(target) == before


def test_a_foreign_journal_beside_the_store_is_refused(tmp_path):
    store = tmp_path / "s.h5"
    journal = make_text(tmp_path / "s.h5.journal")
    before = snapshot(journal)
    out = run_campaign(tmp_path, store)
    assert out.returncode == 2 and "journal" in out.stderr, out.stderr
    assert snapshot(journal) == before and not store.exists()


def test_our_unreadable_store_is_set_aside_and_rebuilt(tmp_path):
    """A store a kill left unreadable, with our journal and lock beside it, is ours: rebuilt."""
    store = tmp_path / "s.h5"
    assert run_campaign(tmp_path, store).returncode == 0
    store.write_bytes(b"\x89HDF\r\n\x1a\n" + b"\x00" * 200)     # what a kill mid-write may leave
    out = run_campaign(tmp_path, store)
    assert out.returncode == 0, out.stderr
    assert any(p.name.startswith("s.h5.unreadable-") for p in tmp_path.iterdir())
    with h5py.File(store, "r") as f:
        assert (f["state"][:] == 2).all()                      # rebuilt from the journal: all done


def test_an_unreadable_file_without_our_journal_is_not_ours(tmp_path):
    store = tmp_path / "s.h5"
    store.write_bytes(b"\x89HDF\r\n\x1a\n" + b"\x00" * 200)
    (tmp_path / "s.h5.lock").write_text("")                    # a lock alone is not enough
    before = snapshot(store)
    assert run_campaign(tmp_path, store).returncode == 2
    assert snapshot(store) == before


# -- analysis outputs --------------------------------------------------------

@pytest.fixture(scope="module")
def afm(tmp_path_factory):
    d = tmp_path_factory.mktemp("afm")
    cal = d / "cal.json"
    Calibration({b: reference_law(b) for b in ("standard", "double", "none")}).save(
        cal, borrow=("emulator", "viscoelastic_table"))      # the shipped emulator and table, named
    cells, _ = generate(3, seed=2, errors=False, forward=law_forward(reference_law()))
    data = write_experiment(d / "exp.h5", cells, FREQUENCY_DOMAIN)
    return cal, data


def _refused(capsys, command):
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"cortex {command}: error:"), err
    return err[0]


def test_afm_analyze_refuses_a_folder_it_did_not_write(afm, tmp_path, capsys):
    cal, data = afm
    out = make_folder(tmp_path / "out")
    before = snapshot(out)
    assert main(["afm", "analyze", str(data), "--calibration", str(cal), "--out", str(out)]) == 2
    assert MANIFEST in _refused(capsys, "afm analyze")
    assert snapshot(out) == before


def test_afm_analyze_refuses_a_file(afm, tmp_path, capsys):
    cal, data = afm
    out = make_text(tmp_path / "out")
    before = snapshot(out)
    assert main(["afm", "analyze", str(data), "--calibration", str(cal), "--out", str(out)]) == 2
    _refused(capsys, "afm analyze")
    assert snapshot(out) == before


def test_afm_analyze_reruns_into_its_own_folder_but_keeps_a_stranger(afm, tmp_path, capsys):
    cal, data = afm
    out = tmp_path / "out"
    args = ["afm", "analyze", str(data), "--calibration", str(cal), "--out", str(out)]
    assert main(args) == 0
    listed = set((out / MANIFEST).read_text().split())
    assert {"report.md", "summary.json", "cells.csv", "k_curves.png"} <= listed
    assert listed >= {p.name for p in out.iterdir()} - {MANIFEST}   # every file it wrote is listed
    assert main(args) == 0                                           # ours: replaced
    (out / "report.md").unlink()
    (out / "report.md").write_text("mine now\n")                     # still listed: ours to replace
    (out / "summary_none.json").unlink()
    stranger = out / "cells.csv"
    stranger.unlink()
    stranger.write_text("a user's table\n")
    manifest = [n for n in (out / MANIFEST).read_text().splitlines() if n != "cells.csv"]
    (out / MANIFEST).write_text("\n".join(manifest) + "\n")          # cells.csv: no longer ours
    before = snapshot(out)
    capsys.readouterr()
    assert main(args) == 2
    assert "cells.csv" in _refused(capsys, "afm analyze")
    assert snapshot(out) == before                                    # refused before writing anything


def test_afm_synth_refuses_a_foreign_truth_file(afm, tmp_path, capsys):
    cal, _ = afm
    out = tmp_path / "a"
    out.mkdir()
    (out / MANIFEST).write_text("experiment.h5\n")                   # ours, but truth.json is not
    truth = out / "truth.json"
    truth.write_text('{"my": "experiment"}\n')
    before = snapshot(truth)
    args = ["afm", "synth", "--cells", "2", "--solver", "law", "--calibration", str(cal)]
    assert main(args + ["--out", str(out)]) == 2
    assert "truth.json" in _refused(capsys, "afm synth")
    assert snapshot(truth) == before and not (out / "experiment.h5").exists()
    truth.unlink()
    assert main(args + ["--out", str(out)]) == 0
    (out / "experiment.h5").unlink()
    assert main(args + ["--out", str(out)]) == 0                      # our own truth.json: replaced
    capsys.readouterr()


def test_afm_synth_never_replaces_an_experiment(afm, tmp_path, capsys):
    cal, _ = afm
    args = ["afm", "synth", "--cells", "2", "--solver", "law", "--calibration", str(cal), "--out", str(tmp_path / "e")]
    assert main(args) == 0
    before = snapshot(tmp_path / "e")
    capsys.readouterr()
    assert main(args) == 2                                            # even ours: measurements are kept
    assert "experiment.h5" in _refused(capsys, "afm synth")
    assert snapshot(tmp_path / "e") == before


def test_afm_synth_refuses_a_folder(afm, tmp_path, capsys):
    cal, _ = afm
    out = make_folder(tmp_path / "exp.h5")
    before = snapshot(out)
    assert main(["afm", "synth", "--cells", "2", "--solver", "law", "--calibration", str(cal),
                 "--out", str(out)]) == 2
    _refused(capsys, "afm synth")
    assert snapshot(out) == before


def test_a_store_is_never_set_aside_onto_an_existing_file(tmp_path):
    """--new keeps the old store as STORE.bak-<time>; a file already of that name is kept too."""
    from campaign.store.files import set_aside
    store = tmp_path / "s.h5"
    assert run_campaign(tmp_path, store).returncode == 0
    taken = make_text(tmp_path / "s.h5.bak-20260101-000000")
    before = snapshot(taken)
    set_aside(str(store), str(taken))
    assert snapshot(taken) == before
    assert (tmp_path / "s.h5.bak-20260101-000000-2").is_file() and not store.exists()
