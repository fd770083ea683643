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
    return run_config(config, store, *extra)


def run_config(config, store, *extra):
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


def other_campaign(tmp_path, name="other.toml", tension="2.0, 3.0"):
    """A campaign file of another grid than TINY's (another fingerprint), `tension` its tensions."""
    config = tmp_path / name
    config.write_text(TINY.replace("tension_mN_per_m = 1.0", f"tension_mN_per_m = [{tension}]"))
    return config


def stored(store, name):
    with h5py.File(store, "r") as f:
        return f[name][:]


def test_a_new_store_takes_no_stale_journal(tmp_path):
    """A store moved away leaves its journal: a new store at its path, of another campaign, does
    not take the journal's tasks as its own (one line, exit 2, nothing written); with the store
    back beside its journal the run resumes, and --new keeps the journal as a backup."""
    store = tmp_path / "s.h5"
    assert run_campaign(tmp_path, store).returncode == 0
    first_force = stored(store, "force_nN")
    store.rename(tmp_path / "v1.h5")
    config = other_campaign(tmp_path)
    journal = tmp_path / "s.h5.journal"
    before, old_bytes = snapshot(tmp_path), journal.read_bytes()
    assert old_bytes
    out = run_config(config, store)
    assert out.returncode == 2, out.stderr
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and str(journal) in lines[0] and "--store" in lines[0], lines
    assert snapshot(tmp_path) == before and not store.exists()      # the journal byte for byte, nothing made

    (tmp_path / "v1.h5").rename(store)                               # the store back beside its journal
    out = run_config(tmp_path / "tiny.toml", store)
    assert out.returncode == 0, out.stderr
    assert (stored(store, "attempts") == 1).all() and (stored(store, "state") == 2).all()   # resumed, not redone
    np.testing.assert_array_equal(stored(store, "force_nN"), first_force)

    store.rename(tmp_path / "v1.h5")
    stale = journal.read_bytes()
    assert stale.startswith(old_bytes)
    out = run_config(config, store, "--new")
    assert out.returncode == 0, out.stderr
    kept = [p for p in tmp_path.iterdir() if p.name.startswith("s.h5.journal.bak-")]
    assert len(kept) == 1 and kept[0].read_bytes() == stale != journal.read_bytes()
    assert (stored(store, "state") == 2).all() and (stored(store, "attempts") == 1).all()
    np.testing.assert_array_equal(np.sort(stored(store, "tension_mN_per_m")), [2.0, 2.0, 3.0, 3.0])
    assert not np.isin(stored(store, "force_nN"), first_force).any()   # computed for this campaign


def test_a_journal_shorter_than_its_store_holds_is_refused(tmp_path):
    """A store beside another store's shorter journal: its rows hold more of its journal than is
    there, so the journal is not its own; refused, both left as they were."""
    store, small = tmp_path / "s.h5", tmp_path / "small.h5"
    assert run_config(other_campaign(tmp_path), store).returncode == 0
    assert run_config(other_campaign(tmp_path, "small.toml", "2.0"), small).returncode == 0
    journal = tmp_path / "s.h5.journal"
    assert 0 < (tmp_path / "small.h5.journal").stat().st_size < journal.stat().st_size
    journal.write_bytes((tmp_path / "small.h5.journal").read_bytes())
    before = snapshot(tmp_path)
    out = run_config(tmp_path / "other.toml", store)
    assert out.returncode == 2, out.stderr
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and str(journal) in lines[0], lines
    assert snapshot(tmp_path) == before
    out = subprocess.run([str(BIN / "cortex"), "campaign", "repair", str(store)], capture_output=True, text=True,
                         cwd=ROOT, timeout=300)         # repair takes no other store's entries either
    assert out.returncode == 2 and len(out.stderr.strip().splitlines()) == 1, out.stderr
    assert snapshot(tmp_path) == before


def test_a_store_beside_another_stores_longer_journal_is_refused(tmp_path):
    """A store moved back where a later store left its (longer) journal: the journal's first record
    carries the other store's mark; refused, both left as they were, `repair` too. A store made
    before records were marked (no `journal_mark`) resumes beside its own journal."""
    store = tmp_path / "s.h5"
    assert run_campaign(tmp_path, store).returncode == 0
    store.rename(tmp_path / "v1.h5")
    (tmp_path / "s.h5.journal").rename(tmp_path / "v1.h5.journal")
    assert run_config(other_campaign(tmp_path), store).returncode == 0      # another store, a longer journal
    store.rename(tmp_path / "v2.h5")
    (tmp_path / "v1.h5").rename(store)
    assert (tmp_path / "s.h5.journal").stat().st_size > int(h5py.File(store, "r").attrs["journal_bytes"])
    before = snapshot(tmp_path)
    for command in ("run", "repair"):
        args = ["run", str(tmp_path / "tiny.toml"), "--store"] if command == "run" else ["repair"]
        out = subprocess.run([str(BIN / "cortex"), "campaign", *args, str(store)], capture_output=True, text=True,
                             cwd=ROOT, timeout=300)
        assert out.returncode == 2, out.stderr
        lines = out.stderr.strip().splitlines()
        assert len(lines) == 1 and "another store's journal" in lines[0], lines
        assert snapshot(tmp_path) == before

    (tmp_path / "s.h5.journal").rename(tmp_path / "v2.h5.journal")
    (tmp_path / "v1.h5.journal").rename(tmp_path / "s.h5.journal")          # each beside its own
    with h5py.File(store, "r+") as f:
        del f.attrs["journal_mark"]
    out = run_config(tmp_path / "tiny.toml", store)
    assert out.returncode == 0, out.stderr
    assert (stored(store, "attempts") == 1).all() and (stored(store, "state") == 2).all()


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


def test_a_rebuild_the_disk_refuses_leaves_the_unreadable_store_in_place(tmp_path, monkeypatch):
    """The store is never missing beside its journal (a new store would not take it): a rebuild
    that fails (a full disk) leaves the unreadable file at its path, and the next run rebuilds it."""
    from campaign import config
    from campaign.store import store as store_module
    from common.errors import WriteError
    store = tmp_path / "s.h5"
    assert run_campaign(tmp_path, store).returncode == 0
    store.write_bytes(b"\x89HDF\r\n\x1a\n" + b"\x00" * 200)
    campaign = config.load(str(tmp_path / "tiny.toml"))
    before = snapshot(tmp_path)

    def full(self, *args):
        raise WriteError(28, "No space left on device", self.path)
    monkeypatch.setattr(store_module.Store, "_create", full)
    with pytest.raises(WriteError):
        store_module.Store(store, campaign)
    assert {p: v for p, v in snapshot(tmp_path).items() if p != str(tmp_path)} == \
        {p: v for p, v in before.items() if p != str(tmp_path)}     # the same files, the same bytes
    monkeypatch.undo()
    out = run_campaign(tmp_path, store)
    assert out.returncode == 0, out.stderr
    assert (stored(store, "state") == 2).all() and (stored(store, "attempts") == 1).all()   # from the journal


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
