"""The journal codec (campaign.store.journal): entries come back bit for bit, a
record cut anywhere is ignored and trimmed, what is not a journal is not
ours; and the engine's version comes from package metadata, not from the
command-line package."""

import subprocess
import sys

import numpy as np
import pytest

from campaign.store import journal
from campaign.store.schema import RESULTS
from conftest import ROOT


def compression(row, state="done", error=""):
    rng = np.random.default_rng(row)
    results = {key: float(v) for key, v in zip(RESULTS, rng.normal(size=len(RESULTS)))} if state == "done" else {}
    if results:
        results["converged"] = True
    return {"row": row, "results": results, "state": state, "error": error, "attempts": 2, "rank": 1,
            "started": 1.7e9 + row / 3}


def trial_task(task, N=5, m=3):
    rng = np.random.default_rng(100 + task)
    cells = {"state": ["done"] * (N - 1) + ["failed"], "error": [""] * (N - 1) + ["compression 3 failed: x"],
             "tension_mN_per_m": rng.normal(size=N), "volume_used_um3": rng.normal(size=N),
             **{key: rng.normal(size=(N, m)) for key in ("h0_used_um", "h1_used_um", "force_nN", "h_tilde",
                                                          "modulus_mN_per_m", "gamma_eff_mN_per_m",
                                                          "tension_seen_mN_per_m")}}
    return {"task": task, "cells": cells, "state": "done", "error": "", "attempts": 1, "rank": 0,
            "started": 1.7e9 + 0.125}


def same(a, b):
    """Entries equal value for value, arrays bit for bit, NaN equal to NaN."""
    assert a.keys() == b.keys(), (a.keys(), b.keys())
    for key in a:
        if isinstance(a[key], dict):
            same(a[key], b[key])
        elif isinstance(a[key], np.ndarray):
            assert a[key].tobytes() == np.asarray(b[key], float).tobytes(), key
        elif isinstance(a[key], float):
            assert np.float64(a[key]).tobytes() == np.float64(b[key]).tobytes(), key
        else:
            assert a[key] == b[key], key


def entries():
    return [compression(3), compression(7, "failed", "RuntimeError: injected fault"), trial_task(0),
            compression(4), trial_task(2)]


def test_entries_come_back_bit_for_bit(tmp_path):
    path = tmp_path / "j"
    with open(path, "ab") as fh:
        journal.append(fh, entries()[:2])
        journal.append(fh, entries()[2:])
    back = journal.read(path)
    # compressions first within a record; a failed one's results are NaN
    want = [entries()[i] for i in (0, 1, 3, 2, 4)]
    assert [("row" in e, e.get("row", e.get("task"))) for e in back] == \
        [("row" in e, e.get("row", e.get("task"))) for e in want]
    for got, exp in zip(back, want):
        if exp.get("state") == "failed":
            assert all(np.isnan(v) for k, v in got["results"].items() if k != "converged")
            assert got["results"]["converged"] is False and got["error"] == exp["error"]
            continue
        same(exp, got)


@pytest.mark.parametrize("cut", [1, 4, 12, 20, -5, -1])
def test_a_cut_record_is_ignored_and_trimmed(tmp_path, cut):
    whole, last = journal.encode(entries()[:2]), journal.encode(entries()[2:])
    path = tmp_path / "j"
    path.write_bytes(whole + last[:cut])
    assert len(journal.read(path)) == 2
    journal.trim_cut(path)
    assert path.read_bytes() == whole
    with open(path, "ab") as fh:                     # what a rerun appends stays readable
        journal.append(fh, entries()[2:])
    assert len(journal.read(path)) == 5


def test_a_corrupt_last_record_is_ignored(tmp_path):
    """A record whose bytes are all there but wrong (CRC) ends the journal."""
    last = bytearray(journal.encode(entries()[2:]))
    last[len(last) // 2] ^= 0xFF
    path = tmp_path / "j"
    path.write_bytes(journal.encode(entries()[:2]) + bytes(last))
    assert len(journal.read(path)) == 2


def test_the_first_record_marks_its_store(tmp_path):
    """`mark` reads the store's mark from the first record; the entries are the same with it; a
    first record without one gives '', an empty journal or a damaged first record None."""
    path = tmp_path / "j"
    with open(path, "ab") as fh:
        journal.append(fh, entries()[:2], "f00d")
        journal.append(fh, entries()[2:])
    assert journal.mark(path) == "f00d"
    plain = tmp_path / "plain"
    with open(plain, "ab") as fh:
        journal.append(fh, entries()[:2])
        journal.append(fh, entries()[2:])
    marked, unmarked = journal.read(path), journal.read(plain)
    assert len(marked) == len(unmarked) == 5
    for a, b in zip(marked, unmarked):
        same(a, b)                                                      # the same entries, bit for bit
    assert len(journal.encode(entries(), "f00d")) == len(journal.encode(entries())) + len(',"store":"f00d"')
    path.write_bytes(journal.encode(entries()))
    assert journal.mark(path) == ""
    damaged = bytearray(journal.encode(entries()[:2], "f00d"))
    damaged[-8] ^= 0x01
    path.write_bytes(bytes(damaged) + journal.encode(entries()[2:]))
    assert journal.mark(path) is None and len(journal.read(path)) == 3
    path.write_bytes(b"")
    assert journal.mark(path) is None and journal.mark(tmp_path / "missing") is None


def test_what_is_not_a_journal(tmp_path):
    for text in (b"hello\n", b'{"a": 1}\n', b"\x00cxk"):
        (tmp_path / "j").write_bytes(text)
        assert not journal.is_ours(tmp_path / "j")
    (tmp_path / "j").write_bytes(b"")
    assert journal.is_ours(tmp_path / "j")


def test_the_engine_does_not_import_the_command_line_package():
    code = ("import sys, campaign.store, campaign.store.reader, campaign.scheduler, campaign.store.provenance as p; "
            "assert 'cortex' not in sys.modules, 'cortex imported'; "
            "from importlib.metadata import version; assert p.code_version() == version('cortex-poisson')")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT)
    assert done.returncode == 0, done.stderr


def test_results_table_fills_missing_keys_with_nan():
    """One pass when every dict has every key, NaN where one lacks a key: the
    journal's and the rows' result columns."""
    from campaign.store.schema import results_table
    full = results_table([{"a": 1.0, "b": 2}, {"a": 3.0, "b": 4}], ["a", "b"])
    assert full.dtype == np.float64 and full.tolist() == [[1.0, 2.0], [3.0, 4.0]]
    gaps = results_table([{"a": 1.0}, {"b": 2.0}], ["a", "b"])
    assert np.isnan(gaps[0, 1]) and np.isnan(gaps[1, 0]) and gaps[0, 0] == 1.0 and gaps[1, 1] == 2.0
    assert results_table([{"a": 5.0}], ["a"]).tolist() == [[5.0]]
    assert results_table([{}, {}], []).shape == (2, 0)


@pytest.mark.parametrize("rows", [[3, 4, 5, 9], list(range(0, 60, 2))])   # few runs; more than RUNS_MAX
def test_put_by_runs_or_scattered_writes_the_same(tmp_path, rows):
    import h5py
    from campaign.store.rows import RUNS_MAX, put, runs
    rows = np.array(rows)
    values = np.arange(len(rows), dtype=float) + 0.5
    with h5py.File(tmp_path / "f.h5", "w") as f:
        for contiguous in (False, True):
            d = f.create_dataset(f"x{contiguous}", data=np.full(64, np.nan))
            put(d, rows, values, contiguous)
            expect = np.full(64, np.nan)
            expect[rows] = values
            np.testing.assert_array_equal(d[:], expect)
    assert (len(runs(rows)) > RUNS_MAX) == (len(rows) == 30)
