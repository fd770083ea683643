"""A batch of compressions sent as columns (campaign.entry_batch) stands for
its entries exactly: the same journal record byte for byte, the same rows,
the same entries back; and a task process sends one for a batch that
finished (a failed task or a trial task in it: the entries as they are)."""

import h5py
import numpy as np

from campaign.entry_batch import CompressionBatch
from campaign.store import journal, schema
from campaign.store.rows import write_entries
from test_journal import compression, same, trial_task


def done(rows, rank=1):
    return [{**compression(r), "rank": rank} for r in rows]


def rows_written(campaign_rows, items):
    """Every dataset of a new store's rows after `items` are written into it."""
    with h5py.File("rows.h5", "w", driver="core", backing_store=False) as f:
        for key in schema.RESULTS + ("state", "attempts", "rank", "converged", "started_unix_s"):
            f[key] = np.full(campaign_rows, np.nan if key in schema.RESULTS + ("started_unix_s",) else 0,
                             schema.BOOKKEEPING.get(key, np.int8 if key == "converged" else float))
        f.create_dataset("error", data=np.zeros(campaign_rows, schema.error_dtype()), dtype=schema.error_dtype())
        write_entries(f, items, 0)
        return {k: f[k][:] for k in f}


def test_a_batch_is_its_entries():
    entries = done(range(10, 30))
    batch = CompressionBatch.of(entries)
    assert batch is not None and len(batch) == 20
    for a, b in zip(batch.entries(), entries):
        same(a, b)
    assert batch.keys() == {("compression", r) for r in range(10, 30)}
    assert batch.failed() == 0
    part = batch.part(5, 9)
    assert [e["row"] for e in part] == [15, 16, 17, 18]


def test_journal_record_and_rows_are_byte_for_byte_those_of_the_entries():
    first, second = done(range(0, 12)), done(range(12, 20), rank=0)
    failed = compression(3, "failed", "RuntimeError: injected fault (rank 1 on host)")   # a row again: last wins
    other = {**compression(25), "results": {"force_nN": 2.5, "converged": False, "iterations": 7}}
    b1, b2 = CompressionBatch.of(first), CompressionBatch.of(second)
    as_entries = first + [failed, other] + second + [trial_task(1)]
    mixed = [b1.part(0, 5), b1.part(5, 12), failed, other, b2, trial_task(1)]
    assert journal.encode(mixed) == journal.encode(as_entries)
    written, expected = rows_written(30, mixed[:-1]), rows_written(30, as_entries[:-1])
    for key in expected:
        assert written[key].dtype == expected[key].dtype and written[key].tobytes() == expected[key].tobytes(), key
    assert written["state"][3] == schema.FAILED and b"injected fault" in written["error"][3]


def test_only_finished_compressions_with_the_same_result_names_make_a_batch():
    ok = done(range(3))
    assert CompressionBatch.of(ok + [compression(5, "failed", "x")]) is None         # no results
    assert CompressionBatch.of(ok + [trial_task(0)]) is None
    renamed = {**compression(9), "results": {**compression(9)["results"], "extra": 1.0}}
    del renamed["results"]["force_nN"]
    assert CompressionBatch.of(ok + [renamed]) is None                               # as many names, another one
    assert CompressionBatch.of([{**compression(1), "results": {"force_nN": "n/a"}}]) is None
    assert CompressionBatch.of([]) is None


def test_the_store_journals_a_batch_as_it_journals_its_entries(tmp_path, monkeypatch):
    """Record by record (journal.RECORD_BYTES each), then the rows: the same files (both stores
    given one mark, which their journals' first records carry)."""
    from campaign import config
    from campaign.store import Store
    monkeypatch.setattr("campaign.store.store.new_mark", lambda: "0" * 32)
    cfg = tmp_path / "grid.toml"
    cfg.write_text('[campaign]\nname = "g"\n[grid]\nh0_um = [10.0, 11.0, 12.0, 13.0]\nbulk_mN_per_m = 25.0\n'
                   f'shear_mN_per_m = [{", ".join(str(5.0 + i) for i in range(25))}]\n'
                   f'tension_mN_per_m = [{", ".join(str(0.5 + i / 10) for i in range(20))}]\n')
    campaign = config.load(str(cfg))
    entries = done(range(1900), rank=0)
    files = {}
    for how in ("entries", "batch"):
        store = Store(str(tmp_path / f"{how}.h5"), campaign, ranks=1)
        store.mark_running([("compression", r) for r in range(1900)])
        if how == "entries":
            for e in entries[:700]:
                store.record(e)
            store.record_all(entries[700:])
        else:
            store.record_all(CompressionBatch.of(entries[:700]))
            store.record_all(CompressionBatch.of(entries[700:]))
        assert not store.running
        store.close()
        files[how] = (tmp_path / f"{how}.h5.journal").read_bytes(), rows_of(tmp_path / f"{how}.h5")
    assert files["batch"][0] == files["entries"][0] and len(files["entries"][0]) > 4 * journal.RECORD_BYTES
    for key, values in files["entries"][1].items():
        assert files["batch"][1][key].tobytes() == values.tobytes(), key


def rows_of(path):
    with h5py.File(path, "r") as f:
        return {k: f[k][:] for k in ("state", "attempts", "rank", "converged", "error") + schema.RESULTS}
