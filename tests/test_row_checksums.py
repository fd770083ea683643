"""Rows that check themselves (`campaign.store.checksum`, `campaign.store.verify`): a bit flipped
in any float column of a done row of a finished store, or of a trial row, is reported by
`cortex campaign verify` (one line, exit 1), never read as a result (read as pending, said in one
line), and `cortex campaign repair` rewrites the row from the journal to the store's very bytes; a
damaged journal record is skipped (the records after it kept) and its tasks are computed again. A
bit flipped in a parameter (a task row's or a trial row's) is reported, never read, and repaired from
the campaign's grid to the store's very bytes."""

import json
import shutil

import h5py
import numpy as np
import pytest

from conftest import cortex

CAMPAIGN = """
[campaign]
name = "checked"
[grid]
h0_um = [15.0, 14.0, 13.0, 12.0, 11.0]
bulk_mN_per_m = 25.0
shear_mN_per_m = [8.33, 15.0, 25.0]
tension_mN_per_m = [0.5, 1.5, 2.5, 3.0]
[montecarlo]
nu = [0.5, 0.25]
cells = 12
studies = 20
seed = 7
[test]
fake_law = true
"""
ROW = 7


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    """A finished store of 60 compressions and 80 trial tasks (the made-up law), with its journal."""
    tmp = tmp_path_factory.mktemp("checked")
    (tmp / "c.toml").write_text(CAMPAIGN)
    done = cortex("campaign", "run", tmp / "c.toml", "--store", tmp / "s.h5", "--quiet")
    assert done.returncode == 0, done.stderr
    return tmp


def _copy(finished, tmp_path):
    for name in ("c.toml", "s.h5", "s.h5.journal"):
        shutil.copy(finished / name, tmp_path / name)
    return tmp_path / "s.h5"


def _flip(store, name, index, bit):
    """Flip bit `bit` of element `index` (flat) of dataset `name` in the file's bytes, as a disk would."""
    with h5py.File(store, "r") as f:
        d = f[name]
        at = d.id.get_offset() + index * d.dtype.itemsize + bit // 8
    with open(store, "r+b") as fh:
        fh.seek(at)
        byte = fh.read(1)[0]
        fh.seek(at)
        fh.write(bytes([byte ^ (1 << (bit % 8))]))


def test_a_flipped_force_is_reported_never_read_and_repaired(finished, tmp_path):
    from campaign.store.reader import read_results
    store = _copy(finished, tmp_path)
    before, good = store.read_bytes(), read_results(store).loc[ROW, "force_nN"]
    _flip(store, "force_nN", ROW, 52)                # the exponent's lowest bit: the force halved or doubled
    with h5py.File(store, "r") as f:
        assert f["force_nN"][ROW] in (good / 2, good * 2)
    status = cortex("campaign", "status", store)
    assert "59 done" in status.stdout and "1 pending" in status.stdout, status.stdout
    assert len(status.stderr.strip().splitlines()) == 1 and "1 damaged rows" in status.stderr
    rows = read_results(store)
    assert rows.loc[ROW, "state"] == "pending" and np.isnan(rows.loc[ROW, "force_nN"])
    check = cortex("campaign", "verify", store)
    assert check.returncode == 1 and check.stdout.strip().splitlines() == [
        f"{store}: row {ROW} (task {rows.loc[ROW, 'task_id']}): damaged, its checksum fails"], check.stdout
    found = cortex("campaign", "verify", store, "--json")
    assert found.returncode == 1 and json.loads(found.stdout) == {
        "store": str(store), "rows": [[ROW, rows.loc[ROW, "task_id"]]], "trial_rows": [], "journal": [],
        "param_rows": [], "trial_param_rows": []}
    fixed = cortex("campaign", "repair", store)
    assert fixed.returncode == 0 and f"row {ROW} rewritten from the journal" in fixed.stdout, fixed.stderr
    assert store.read_bytes() == before
    clean = cortex("campaign", "verify", store)
    assert clean.returncode == 0 and "no damaged row" in clean.stdout


def test_a_bit_flipped_in_any_float_column_is_seen_and_repaired(finished, tmp_path):
    from campaign.store.schema import RESULTS
    from campaign.store.verify import repair, verify
    store = _copy(finished, tmp_path)
    before = store.read_bytes()
    for k, name in enumerate(RESULTS + ("started_unix_s", "checksum")):
        for bit in (0, 31, 52, 63):
            _flip(store, name, (ROW + k) % 60, bit)
            lines = verify(store)
            assert len(lines) == 1 and f"row {(ROW + k) % 60} " in lines[0], (name, bit, lines)
            assert repair(store) == [f"{store}: row {(ROW + k) % 60} rewritten from the journal"]
            assert store.read_bytes() == before, (name, bit)


def test_a_flipped_trial_value_is_reported_never_read_and_repaired(finished, tmp_path):
    from campaign.store.reader import read_trials
    from campaign.store.verify import repair, verify
    store = _copy(finished, tmp_path)
    before = store.read_bytes()
    heights = 5
    for name, index in (("trials/force_nN", 14 * heights + 3), ("trials/volume_used_um3", 20),
                        ("trials/h_tilde", 30 * heights)):
        _flip(store, name, index, 52)
        row = index // heights if name != "trials/volume_used_um3" else index
        assert verify(store) == [f"{store}: trial row {row} (trial task {row // 12}, cell {row % 12}): "
                                 "damaged, its checksum fails"]
        trials = read_trials(store)
        mine = trials[(trials["study"] == trials["study"].iloc[row * heights]) & (trials["cell"] == row % 12)
                      & (trials["trial_id"] == trials["trial_id"].iloc[row * heights])]
        assert set(mine["state"]) == {"pending"} and mine["modulus_mN_per_m"].isna().all()
        assert (trials["state"] == "done").sum() == len(trials) - heights
        assert repair(store) == [f"{store}: trial row {row} rewritten from the journal"]
        assert store.read_bytes() == before


def test_a_run_computes_a_damaged_row_again(finished, tmp_path):
    from campaign.store.reader import read_results
    store = _copy(finished, tmp_path)
    good = read_results(store)
    _flip(store, "modulus_mN_per_m", ROW, 3)
    again = cortex("campaign", "run", tmp_path / "c.toml", "--store", store, "--quiet")
    assert again.returncode == 0 and "1 damaged rows and 0 damaged trial rows" in again.stdout, again.stdout
    rows = read_results(store)
    assert (rows["state"] == "done").all() and rows.loc[ROW, "attempts"] == 2
    np.testing.assert_array_equal(rows["modulus_mN_per_m"], good["modulus_mN_per_m"])


def test_a_damaged_journal_record_is_skipped_and_its_tasks_run_again(finished, tmp_path):
    from campaign.store import journal
    from campaign.store.reader import read_results, read_trials
    from campaign.store.verify import verify
    store = _copy(finished, tmp_path)
    path = str(store) + ".journal"
    records = journal.read_all(path)
    assert len(records) >= 3 and all(e is not None for _, _, e in records)
    start, end, lost = records[1]
    raw = bytearray(open(path, "rb").read())
    raw[(start + end) // 2] ^= 0x10                  # a bit of the second record's data
    open(path, "wb").write(bytes(raw))
    kept = journal.read(path)
    assert len(kept) == sum(len(e) for _, _, e in records) - len(lost)
    key = lambda e: ("row", e["row"]) if "row" in e else ("task", e["task"])   # noqa: E731
    assert [key(e) for e in kept] == [key(e) for i, (_, _, es) in enumerate(records) if i != 1 for e in es]
    assert verify(store) == [f"{store}.journal: bytes {start}-{end} damaged (no record there checks); its tasks "
                             "are pending unless their rows hold them"]
    journal.trim_cut(path)
    assert open(path, "rb").read() == bytes(raw)      # not a cut tail: kept whole
    good, good_trials = read_results(store), read_trials(store)
    store.write_bytes(b"\x89HDF\r\n\x1a\n" + b"\x00" * 200)   # the rows gone (as a kill mid-write may leave
    (tmp_path / "s.h5.lock").touch()                  # the file, its lock beside it): rebuilt from the journal
    again = cortex("campaign", "run", tmp_path / "c.toml", "--store", store, "--quiet")
    assert again.returncode == 0, again.stderr
    redone = journal.read(path, len(raw))             # what this run computed: the damaged record's tasks
    assert sorted(map(key, redone)) == sorted(map(key, lost))
    rows, trials = read_results(store), read_trials(store)
    assert (rows["state"] == "done").all()
    np.testing.assert_array_equal(rows["force_nN"], good["force_nN"])
    np.testing.assert_array_equal(trials["modulus_mN_per_m"], good_trials["modulus_mN_per_m"])


def test_a_bit_flipped_in_any_parameter_is_seen_and_repaired(finished, tmp_path):
    from campaign.store.checksum import TRIAL_PARAM_COVERED
    from campaign.store.schema import PARAM_CHECKSUM, PARAMS
    from campaign.store.verify import repair, verify
    store = _copy(finished, tmp_path)
    before = store.read_bytes()
    flips = [(name, (ROW + k) % 60, f"row {(ROW + k) % 60} ") for k, name in enumerate(PARAMS + (PARAM_CHECKSUM,))]
    flips += [("task_id", ROW, f"row {ROW} "), ("bending", ROW + 1, f"row {ROW + 1} ")]
    flips += [(f"trials/{name}", 5 * (k + 3) if name == "h0_true_um" else k + 3, f"trial row {k + 3} ")
              for k, name in enumerate(TRIAL_PARAM_COVERED + (PARAM_CHECKSUM,))]
    for name, index, row in flips:
        with h5py.File(store, "r") as f:
            bits = (0, 31, 52, 63) if f[name].dtype.itemsize == 8 else (0, 6)
        for bit in bits:
            _flip(store, name, index, bit)
            lines = verify(store)
            assert len(lines) == 1 and row in lines[0] and "parameters are damaged" in lines[0], (name, bit, lines)
            assert repair(store) == [f"{store}: {row}parameters rewritten from the campaign's grid"], (name, bit)
            assert store.read_bytes() == before, (name, bit)


def test_a_damaged_parameter_is_never_read(finished, tmp_path, capsys):
    from campaign.store.reader import read_results, read_trials
    store = _copy(finished, tmp_path)
    _flip(store, "shear_mN_per_m", ROW, 52)
    _flip(store, "trials/nu_true", 4, 62)
    rows, trials = read_results(store), read_trials(store)
    assert rows.loc[ROW, "state"] == "pending" and rows.loc[[ROW], ["shear_mN_per_m", "force_nN"]].isna().all(axis=None)
    assert (rows.drop(ROW)["state"] == "done").all()
    assert trials.loc[trials["trial_id"] == trials["trial_id"].iloc[4 * 5], "nu_true"].isna().all()
    said = capsys.readouterr().err.splitlines()
    assert len(said) == 2 and "1 damaged rows' parameters (checksum fails: 7)" in said[0], said
    assert "1 damaged trial rows' parameters (checksum fails: 4)" in said[1], said
