"""A full disk stops cleanly: one line naming the file and saying to free
space and rerun, exit status 5, no segmentation fault; after freeing space
the rerun ends with the rows of an uninterrupted run (1 and 2 ranks, both
write paths: mpio where h5py has MPI, as under `make test-mpi-parallel`). Runs on
a 4 MB tmpfs filled with a ballast file (needs root to mount; skipped
otherwise, saying why)."""

import errno
import json
import os
import shutil
import subprocess

import h5py
import pandas as pd
import pytest

from analysis.calibration.law import Calibration
from studies.synthetic import reference_law
from campaign.store import journal
from campaign.store.journal import read as read_journal
from campaign.store.reader import read_results, read_trials
from outputs.ownership import MANIFEST
from conftest import ROOT, cortex
from outputs.writing import ROOM_MARGIN_BYTES

CAMPAIGN = ROOT / "campaigns" / "demo.toml"     # 60 compressions, 20 Monte-Carlo studies of 20 cells
MOVING = {"wall_s", "rank", "attempts", "started_unix_s"}   # differ between any two runs
needs_mpio = pytest.mark.skipif(not h5py.get_config().mpi, reason="h5py here was built without MPI "
                                "(make test-mpi-parallel runs this with .venv-mpio, which has it)")


@pytest.fixture
def tmpfs(tmp_path):
    """A 4 MB tmpfs at tmp_path/disk, unmounted afterwards."""
    disk = tmp_path / "disk"
    disk.mkdir()
    if shutil.which("mount") is None:
        pytest.skip("no mount command: cannot make a small file system")
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=4m", "tmpfs", str(disk)], capture_output=True,
                          text=True)
    if done.returncode != 0:
        pytest.skip(f"cannot mount a 4 MB tmpfs here (needs root): {done.stderr.strip()}")
    yield disk
    subprocess.run(["umount", str(disk)], check=True)


def fill(disk, keep_bytes):
    """A ballast file that leaves `keep_bytes` free on `disk`; returns its path."""
    ballast = disk / "ballast"
    free = shutil.disk_usage(disk).free
    assert free > keep_bytes, (free, keep_bytes)
    with open(ballast, "wb") as fh:
        fh.truncate(0)
        fh.write(b"\0" * (free - keep_bytes))
    return ballast


def fake_campaign(tmp_path):
    """The demo campaign with every compression made up (`[test] fake_law`): seconds, not a minute."""
    text = CAMPAIGN.read_text().replace("[solver]", "[test]\nfake_law = true\n\n[solver]", 1)
    path = tmp_path / "demo-fake.toml"
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """An uninterrupted run of the fake demo campaign: (config, store)."""
    d = tmp_path_factory.mktemp("ref")
    config = fake_campaign(d)
    out = cortex("campaign", "run", str(config), "--store", str(d / "s.h5"), "--quiet")
    assert out.returncode == 0, out.stderr
    return config, d / "s.h5"


def assert_same_rows(store, reference):
    a, b = read_results(reference), read_results(store)
    assert (b["state"] == "done").all()
    columns = [c for c in a.columns if c not in MOVING]
    pd.testing.assert_frame_equal(a[columns], b[columns])
    ta, tb = read_trials(reference), read_trials(store)
    assert (tb["state"] == "done").all()
    columns = [c for c in ta.columns if c not in MOVING]
    pd.testing.assert_frame_equal(ta[columns], tb[columns])


def one_line(stderr, path):
    lines = stderr.strip().splitlines()
    assert len(lines) == 1, lines
    assert "could not write" in lines[0] and str(path) in lines[0] and "free space" in lines[0], lines
    assert "rerun the same command" in lines[0]
    return lines[0]


@pytest.mark.parametrize("ranks,path", [(1, "rank0"), (2, "rank0"), pytest.param(2, "mpio", marks=needs_mpio)])
def test_disk_full_during_a_campaign_then_rerun(reference, tmpfs, ranks, path):
    config, ref_store = reference
    store = tmpfs / "s.h5"
    journal_bytes = os.path.getsize(str(ref_store) + ".journal")
    # room for the store and a quarter of its journal beyond the margin (which the journal may use too,
    # and which is about half the lean journal of the demo): the journal fills the disk mid-run
    ballast = fill(tmpfs, os.path.getsize(ref_store) + ROOM_MARGIN_BYTES + journal_bytes // 4)
    args = ("campaign", "run", str(config), "--store", str(store), "--quiet", "--write-path", path)
    full = cortex(*args, mpi=ranks if ranks > 1 else 0)
    assert full.returncode == 5, full.stderr
    one_line(full.stderr, str(store) + ".journal")
    status = cortex("campaign", "status", str(store), "--json")
    assert status.returncode == 0, status.stderr
    info = json.loads(status.stdout)
    assert info["pending"] + info["trials"]["pending"] > 0 and info["trials"]["done"] > 0   # stopped part way
    ballast.unlink()                                                   # free space, rerun
    rerun = cortex(*args, mpi=ranks if ranks > 1 else 0)
    assert rerun.returncode == 0, rerun.stderr
    assert_same_rows(store, ref_store)


def test_disk_too_full_to_create_the_store(reference, tmpfs):
    config, ref_store = reference
    store = tmpfs / "s.h5"
    ballast = fill(tmpfs, os.path.getsize(ref_store) // 2)
    args = ("campaign", "run", str(config), "--store", str(store), "--quiet")
    full = cortex(*args)
    assert full.returncode == 5, full.stderr
    one_line(full.stderr, store)
    assert set(os.listdir(tmpfs)) <= {"ballast", "s.h5.lock"}              # nothing half-written
    ballast.unlink()
    assert cortex(*args).returncode == 0
    assert_same_rows(store, ref_store)


def test_analysis_outputs_on_a_full_disk(reference, tmpfs):
    """`cortex analysis calibrate` into a full disk: status 5, one line naming the
    file; after freeing space the same command writes everything."""
    _, ref_store = reference
    out = tmpfs / "analysis"
    ballast = fill(tmpfs, 16 * 1024)
    args = ("analysis", "calibrate", str(ref_store), "--out", str(out))
    full = cortex(*args)
    assert full.returncode == 5, full.stderr
    errors = [line for line in full.stderr.splitlines() if not line.startswith("[analysis")]  # progress lines
    line = one_line("\n".join(errors), out)
    assert "Traceback" not in full.stderr and line == full.stderr.strip().splitlines()[-1]
    ballast.unlink()
    again = cortex(*args)
    assert again.returncode == 0, again.stderr
    assert (out / "report.md").is_file() and (out / "calibration.json").is_file()


def test_afm_synth_on_a_full_disk(tmpfs, tmp_path):
    calibration = Calibration({"standard": reference_law("standard")}).save(tmp_path / "cal.json")
    ballast = fill(tmpfs, 16 * 1024)
    out = tmpfs / "exp"
    full = cortex("afm", "synth", "--cells", "20", "--solver", "law", "--calibration", str(calibration),
                  "--out", str(out))
    assert full.returncode == 5, full.stderr
    one_line(full.stderr, out)
    assert sorted(os.listdir(tmpfs)) in (["ballast"], ["ballast", "exp"])
    assert set(os.listdir(out) if out.exists() else []) <= {MANIFEST}      # nothing half-written
    ballast.unlink()


def test_a_journal_record_cut_by_a_full_disk_is_trimmed(reference, tmp_path):
    """The rerun cuts the journal's unfinished last record, so what it appends
    after it stays readable, and ends with the uninterrupted rows. The
    reference's entries are journalled again one record each (the most
    records a run writes: one per flush), so the cut falls among them."""
    config, ref_store = reference
    store = tmp_path / "s.h5"
    shutil.copy(ref_store, store)
    entries = read_journal(str(ref_store) + ".journal")
    with h5py.File(store, "r") as f:
        mark = f.attrs["journal_mark"]                 # the first record carries its store's mark
    records = [journal.encode([e], mark if i == 0 else "") for i, e in enumerate(entries)]
    with open(str(store) + ".journal", "wb") as fh:     # the last 20 entries lost, one of them cut
        fh.writelines(records[:-20])
        fh.write(records[-20][: len(records[-20]) // 2])
    with h5py.File(store, "r+") as f:                  # rows only up to the journal's first 10 entries
        f.attrs["journal_bytes"] = sum(map(len, records[:10]))
        for name in ("state", "trials/state"):
            f[name][:] = 0
    assert journal.encode(read_journal(str(store) + ".journal")[-1:]) == records[-21]
    done = cortex("campaign", "run", str(config), "--store", str(store), "--quiet")
    assert done.returncode == 0, done.stderr
    assert len(read_journal(str(store) + ".journal")) >= len(entries)
    assert_same_rows(store, ref_store)


class _Refusing:
    """A file whose disk takes `room` bytes, then refuses every write (ENOSPC)."""

    def __init__(self, raw, room):
        self.raw, self.room = raw, room

    def write(self, data):
        if len(data) > self.room:
            raise OSError(errno.ENOSPC, "No space left on device")
        self.room -= len(data)
        return self.raw.write(data)

    def __getattr__(self, name):
        return getattr(self.raw, name)


@pytest.mark.parametrize("room", [0, 4096, 600_000])
def test_a_new_hdf5_file_refused_part_way_is_kept_from_hdf5(tmp_path, monkeypatch, capfd, room):
    """`outputs.writing.write_hdf5` (how a new store is made) on a disk that
    refuses its writes after `room` bytes (at the first write, among the
    metadata, in the middle of a 1.6 MB dataset): HDF5 never sees the
    failure (nothing on stderr, no exception from it), the half-made file is
    removed and WriteError names the file; with room it writes the file."""
    import numpy as np
    from common.errors import WriteError
    from outputs import writing

    def build(f):
        f["x"] = np.arange(200_000, dtype=float)
        f.create_dataset("error", (1000,), "S256", fill_time="alloc")
        f.attrs["text"] = "y" * 5000

    shielded = writing._Shielded.__init__
    monkeypatch.setattr(writing._Shielded, "__init__", lambda self, raw: shielded(self, _Refusing(raw, room)))
    with pytest.raises(WriteError) as refused:
        writing.write_hdf5(tmp_path / "s.h5", build)
    assert str(tmp_path / "s.h5") in str(refused.value) and refused.value.errno == errno.ENOSPC
    assert os.listdir(tmp_path) == []
    assert capfd.readouterr().err == ""
    monkeypatch.undo()
    writing.write_hdf5(tmp_path / "s.h5", build)
    with h5py.File(tmp_path / "s.h5") as f:
        assert f["x"][-1] == 199_999 and f["error"][0] == b"" and len(f.attrs["text"]) == 5000
    assert os.listdir(tmp_path) == ["s.h5"]
