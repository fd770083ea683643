"""The campaign store: rank 0's view of one HDF5 file and its journal.

The file holds one row per task (`campaign.store.schema`); its attributes keep
the campaign file's text, its fingerprint, the code and library versions,
host and ranks (`campaign.store.provenance`). Monte-Carlo trials live in the group
`trials`; its attribute `trials_fingerprint` identifies them: a store made
without trials gains them when the campaign file gets a [montecarlo]
section (its compressions kept); one with other trials is refused.

Kill safety: finished tasks are kept in memory (`record`) and, once per
batch (`flush`) or every 64 KiB of entries, appended to `STORE.journal` as
one record (`campaign.store.journal`), which a killed process cannot lose (the
operating system holds it). Rows follow at most once per ROWS_S on the
rank0 path (at every flush on the mpio path): the journal is fsync'd, and
only then are the rows of every entry since the last row write written
(`campaign.store.rows`) and the file flushed, after which its attribute
`journal_bytes` says how much of the journal the rows hold. So the rows
never hold what the durable journal does not; a crash of the machine itself
can lose at most the last ROWS_S of finished tasks, which the rerun redoes;
and every reader overlays the journal past the rows. On opening, a record a kill cut is trimmed, the
rest of the journal is replayed into the file (idempotent), rows left
`running` become `pending` again, and a file a kill left unreadable is set
aside and rebuilt from the campaign and the journal. So a rerun finishes the
remaining tasks and ends with the same rows as an uninterrupted run. A lock
file refuses a second run on the same store. A new store is not made beside
a journal that holds records (another store's, which it would take as its
own results), and an existing one is refused beside another store's journal:
its first record does not carry the store's mark (`journal_mark`, which the
store writes into the first record of its journal), or it is shorter than
`journal_bytes` (`campaign.store.files`).

Only a file that is ours is ever opened for writing, set aside or rebuilt
(`campaign.store.files`). A full disk never reaches HDF5 while it grows the
file (HDF5 then crashes): a new file is written in place through a file
object that keeps every failed write from HDF5 (`write_hdf5`; the half-made
file is then removed), growth waits for `ensure_room`, rows are written in place
(`outputs.writing`); a failed journal write is a WriteError naming the
journal, and `abort` closes without writing more.

On the mpio path (`campaign.store.mpio_writer`) rank 0's rows are its own tasks';
the workers write theirs once told the journal holds them; `journal_bytes`
is set when the run closes. What analysis and `campaign status` read is in
`campaign.store.reader`.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import math
import os
import time
import uuid

import numpy as np
import numpy.typing as npt

from collections.abc import Callable, Iterable, Sequence
from typing import TYPE_CHECKING, cast

from campaign.entry_batch import CompressionBatch, is_batch
from campaign.store import journal, provenance, schema, verify
from campaign.store.rows import put, write_entries
from campaign.store.schema import PENDING, RUNNING, StoredCampaign, trial_rows
from campaign.store.files import (check_no_stale_journal, check_own_journal, check_store_path, keep_aside,
                                  open_read, set_aside)
from campaign.task_key import COMPRESSION, TRIAL, Entry, TaskKey, entry_key
from outputs.writing import ensure_room, hdf5_image, named_failures, write_hdf5
from common.errors import InputError

if TYPE_CHECKING:
    import h5py

ROWS_S = 1.0    # s: on the rank0 path the journal is fsync'd and rows written at most this often (an
                # HDF5 write per column costs ~0.3 ms, an fsync ~1 ms: per batch of a few tasks that was
                # most of rank 0's cost per message)


class Store:
    """Rank 0's view of a store: the journal, and the rows (all of them on the
    rank0 path; on the mpio path rank 0's own, through `attach`).
    `on_record(store, entry)`, if given, is called after each `record`
    (the test suite's fault injection, `tests/faults.py`, uses it)."""

    def __init__(self, path: str | os.PathLike[str], campaign: StoredCampaign, new: bool = False, ranks: int = 1,
                 parallel: bool = False, on_record: Callable[[Store, Entry], None] | None = None):
        self.path, self.journal_path = str(path), str(path) + ".journal"
        self.parallel, self.on_record = parallel, on_record
        check_store_path(self.path)               # before anything is created beside it
        if not new:
            check_no_stale_journal(self.path)     # a new store takes no other store's records
        self.lock = hold_lock(self.path)
        try:
            self.file = self._open(campaign, new, ranks)
        except BaseException:
            self._unlock()
            raise
        try:
            self._prepare(campaign, ranks)
        except BaseException:
            self.file.close()                     # a refusal or a full disk: nothing more is written
            self._unlock()
            raise

    # -- opening -----------------------------------------------------------
    def _open(self, campaign, new, ranks):
        """The file, checked against the campaign, set aside (--new), created, or rebuilt."""
        if os.path.exists(self.path) and not new:
            self._check_same(campaign)
        if new:
            self._backup()
        if not os.path.exists(self.path):
            self._create(campaign, ranks)
        return self._open_or_rebuild(campaign, ranks)

    def _prepare(self, campaign, ranks):
        """Trials added, journal trimmed and replayed, rows left running pending again, this run logged."""
        self._add_trials(campaign)
        self.cells = int(self.file["trials"].attrs["cells_per_study"]) if "trials" in self.file else 0
        journal.trim_cut(self.journal_path)
        self.mark = str(self.file.attrs.get("journal_mark", ""))    # its journal's first record carries it
        write_entries(self.file, journal.read(self.journal_path, self.file.attrs.get("journal_bytes", 0)),
                      self.cells, contiguous=self.parallel)
        self._pending_again()
        self._damaged_pending()
        self.journal = open(self.journal_path, "ab")
        self._log_run(ranks)
        self.unjournalled, self.unjournalled_bytes, self.unwritten = [], 0, []
        self.unsynced, self.running, self.shown_running = False, set(), set()
        self.rows_at = time.monotonic()           # when rows were last written (rank0 path)
        self.file.flush()

    def _check_same(self, campaign):
        try:
            with open_read(self.path) as f:
                fingerprint, trials = f.attrs.get("fingerprint"), f.attrs.get("trials_fingerprint", "")
                kind, version = f.attrs.get("task_kind"), f.attrs.get("task_version")
                journal_bytes, mark = int(f.attrs.get("journal_bytes", 0)), str(f.attrs.get("journal_mark", ""))
        except InputError:
            return            # unreadable: rebuilt from the journal
        _check_kind(self.path, kind, version, campaign.kind)
        check_own_journal(self.path, journal_bytes, mark)
        if fingerprint != campaign.fingerprint:
            raise InputError(f"{self.path} was made from a different campaign file; "
                             "use --new to start over (the old store is kept as a backup)")
        if trials not in ("", campaign.trials_fingerprint):
            raise InputError(f"{self.path} holds Monte-Carlo trials of a different [montecarlo] section; "
                             "use --new to start over (the old store is kept as a backup)")

    def _backup(self):
        stamp = time.strftime("%Y%m%d-%H%M%S")
        for p in (self.path, self.journal_path):
            if os.path.exists(p):
                set_aside(p, f"{p}.bak-{stamp}")

    def _create(self, campaign, ranks, mark=None):
        """The new file, written in place with every write failure kept from HDF5 (`outputs.writing`);
        its journal's mark `mark` (None: a new one)."""
        attrs = {**provenance.store_attrs(campaign, ranks), "journal_mark": new_mark() if mark is None else mark}
        write_hdf5(self.path, lambda f: schema.fill(f, campaign, attrs))

    def _open_or_rebuild(self, campaign, ranks):
        import h5py
        try:
            f = h5py.File(self.path, "r+")
            f["state"][:1]
            return f
        except (OSError, KeyError):
            self._rebuild(campaign, ranks)
            return h5py.File(self.path, "r+")

    def _rebuild(self, campaign, ranks):
        """The unreadable file kept as STORE.unreadable-<time> and replaced by a new one (the journal
        replays into it). The path is never without a store: a new store does not take a journal it
        finds alone (`check_no_stale_journal`); a failed rebuild (a full disk) leaves it as it was."""
        aside, linked = keep_aside(self.path, f"{self.path}.unreadable-{time.strftime('%Y%m%d-%H%M%S')}")
        print(f"campaign: {self.path} was left unreadable (kept as {aside}); "
              "rebuilding it from the journal", flush=True)
        found = journal.mark(self.journal_path)      # the journal's mark (None: not told, or nothing in it)
        empty = not os.path.isfile(self.journal_path) or os.path.getsize(self.journal_path) == 0
        try:
            self._create(campaign, ranks, None if empty else found or "")   # '': unmarked, never checked
        except BaseException:
            if linked:
                os.remove(aside)                      # our second name of the file still at the path
            else:
                set_aside(aside, self.path)           # back where it was (nothing is there)
            raise

    def _add_trials(self, campaign):
        """A store made without trials gains the campaign's (its compressions are kept).
        The fingerprint is set last: a group a kill left half made is made again."""
        f = self.file
        if not campaign.studies or f.attrs.get("trials_fingerprint", "") == campaign.trials_fingerprint:
            return
        image = hdf5_image(lambda g: schema.fill_trials(g.create_group("trials"), campaign))
        ensure_room(self.path, len(image))            # HDF5 grows the file: never into a full disk
        if "trials" in f:
            del f["trials"]
        schema.fill_trials(f.create_group("trials"), campaign)
        f.flush()
        f.attrs.update(config_text=campaign.text, trials_fingerprint=campaign.trials_fingerprint)
        f.flush()

    def _pending_again(self):
        """Rows a kill left `running` are pending again."""
        for name in ("state", "trials/state"):
            if name in self.file:
                state = self.file[name][:]
                if (state == RUNNING).any():
                    state[state == RUNNING] = PENDING
                    self.file[name][:] = state

    def _damaged_pending(self):
        """Rows whose checksum fails (`campaign.store.verify`) are pending again: this run computes
        them; said in one line."""
        bad = verify.pending_again(self.file)
        if len(bad["rows"]) or len(bad["trials"]):
            print(f"campaign: {self.path}: {len(bad['rows'])} damaged rows and {len(bad['trials'])} damaged "
                  "trial rows (checksum fails) set pending, computed again by this run", flush=True)

    def _log_run(self, ranks):
        """Provenance of this run (appended to the JSON list `runs`); the rows
        hold the whole journal now (replayed)."""
        ensure_room(self.path, 0)                     # the attribute may grow the file
        runs = json.loads(self.file.attrs.get("runs", "[]"))
        runs.append(provenance.run_record(ranks, "mpio" if self.parallel else "rank0"))
        self.file.attrs.update(runs=json.dumps(runs), journal_bytes=self.journal.tell())

    def attach(self, parallel_file: h5py.File) -> None:
        """mpio path: swap the file rank 0 prepared alone for the one all ranks opened."""
        self.file.close()
        self.file = parallel_file

    # -- what the scheduler reads -----------------------------------------
    def state(self) -> npt.NDArray[np.int8]:
        return self.file["state"][:]

    def trial_state(self) -> np.ndarray:
        """Per trial task (study): the states of its N trials, shape (tasks, N)."""
        return self.file["trials/state"][:].reshape(-1, self.cells) if self.cells else np.zeros((0, 0))

    def trial_attempts(self) -> npt.NDArray[np.int32]:
        """Per trial task: its attempts so far."""
        return self.file["trials/attempts"][::self.cells] if self.cells else np.zeros(0, np.int32)

    def compressions(self) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.int8], list[str]]:
        """(force_nN, state, error) of every compression, for the trials."""
        return self.file["force_nN"][:], self.file["state"][:], list(self.file["error"].asstr()[:])

    def attempts(self) -> npt.NDArray[np.int32]:
        return self.file["attempts"][:]

    # -- writing -----------------------------------------------------------
    def mark_running(self, tasks: Iterable[TaskKey]) -> None:
        """Shown as running from the next flush on (the journal never holds `running`)."""
        self.running.update(tasks)

    def record(self, entry: Entry) -> None:
        """Keep a finished task's entry for the next `flush`; once the entries
        kept reach `journal.RECORD_BYTES` they are appended to the journal as
        one record (not fsync'd, no rows written: that waits for the flush)."""
        self.unjournalled.append(entry)
        self.unjournalled_bytes += journal.approx_bytes(entry)
        if not self.parallel or entry["rank"] == 0:
            self.unwritten.append(entry)
        self.running.discard(entry_key(entry))
        if self.unjournalled_bytes >= journal.RECORD_BYTES:
            self._append_record()
        if self.on_record is not None:
            self.on_record(self, entry)

    def record_all(self, entries: Sequence[Entry] | CompressionBatch) -> None:
        """`record` of each of `entries`; a `CompressionBatch` is kept whole (no
        entry made per task), split where `record` would have appended a
        journal record, so the journal is the same as from its entries."""
        if not is_batch(entries) or self.on_record is not None:
            for e in entries:
                self.record(e)
            return
        batch, at = cast(CompressionBatch, entries), 0
        size = journal.compression_bytes(len(batch.names))
        mine = not self.parallel or bool((batch.rank == 0).all())
        self.running.difference_update(batch.keys())
        while at < len(batch):         # the entries `record` would take to reach RECORD_BYTES, at least one
            room = math.ceil((journal.RECORD_BYTES - self.unjournalled_bytes) / size)
            take = min(len(batch) - at, max(1, room))
            part = batch.part(at, at + take)
            self.unjournalled.append(part)
            self.unjournalled_bytes += take * size
            if mine:
                self.unwritten.append(part)
            if self.unjournalled_bytes >= journal.RECORD_BYTES:
                self._append_record()
            at += take

    def _append_record(self):
        if self.unjournalled:
            with named_failures(self.journal_path):
                journal.append(self.journal, self.unjournalled, self.mark if self.journal.tell() == 0 else "")
            self.unjournalled, self.unjournalled_bytes, self.unsynced = [], 0, True

    def flush(self, rows: bool = False) -> None:
        """The entries kept since the last record appended to the journal as
        one record (written through to the operating system: a killed process
        loses none of it); then, when due, the journal fsync'd and only then
        the rows of the entries recorded since the last row write and the new
        running marks into HDF5 (a row shown running and no longer has been
        finished: its entry is written). Due on the rank0 path when ROWS_S has
        passed since the last row write or `rows` is true; on the mpio path
        (rank 0's own entries only; nothing collective happens) at every flush."""
        self._append_record()
        if not (self.parallel or rows or time.monotonic() - self.rows_at >= ROWS_S):
            return
        if self.unsynced:
            with named_failures(self.journal_path):
                journal.sync(self.journal)
            self.unsynced = False
        if self.unwritten:
            write_entries(self.file, self.unwritten, self.cells, contiguous=self.parallel)
            self.unwritten = []
            if not self.parallel:
                self.file.flush()             # the rows first, then the mark that they are in
                self.file.attrs["journal_bytes"] = self.journal.tell()
        self._show_running()
        if not self.parallel:
            self.file.flush()
        self.rows_at = time.monotonic()

    def _show_running(self):
        new = self.running - self.shown_running
        rows = sorted(i for kind, i in new if kind == COMPRESSION)
        trials = sorted(r for kind, j in new if kind == TRIAL
                        for r in trial_rows(j, self.cells))
        for name, marks in (("state", rows), ("trials/state", trials)):
            if marks:
                put(self.file[name], np.array(marks), np.full(len(marks), RUNNING, np.int8), self.parallel)
        self.shown_running = set(self.running)

    def close(self) -> None:
        """Write what is left and close; on the mpio path every rank closes the
        file together, then rank 0 notes that the rows hold the whole journal."""
        self.flush(rows=True)
        self.file.close()
        if self.parallel:
            import h5py
            with h5py.File(self.path, "r+") as f:
                f.attrs["journal_bytes"] = self.journal.tell()
        self.journal.close()
        self._unlock()

    def abort(self) -> None:
        """After a failed write: close without writing anything more. The rows
        hold what the journal held at the last flush, the journal what was
        fsync'd (a record a full disk cut is trimmed on the next open), so the
        rerun replays it and resumes. On the mpio path every rank closes the
        file together, as in `close`."""
        self.file.close()
        with contextlib.suppress(OSError):
            self.journal.close()                   # what it still buffers may not fit
        self._unlock()

    def _unlock(self):
        fcntl.flock(self.lock, fcntl.LOCK_UN)
        self.lock.close()


def _check_kind(path, kind, version, want):
    """InputError (one line) unless the store at `path` was made by task kind `want` at its version
    (a store made before kinds had versions has neither attribute: refused too)."""
    if kind is None:
        raise InputError(f"{path} was made by an older cortex (no task kind version, no row checksums); "
                         "use --new to start over (the old store is kept as a backup)")
    if (str(kind), int(version)) != (want.name, want.version):
        raise InputError(f"{path} was made by task kind {kind} version {version}, not {want.name} version "
                         f"{want.version}: its rows would mix two codes; use --new to start over "
                         "(the old store is kept as a backup)")


def new_mark() -> str:
    """A new store's mark, which the first record of its journal carries (`journal.mark`)."""
    return uuid.uuid4().hex


def hold_lock(path: str):
    """The store's lock file, held exclusively; InputError if another run holds it."""
    lock = open(path + ".lock", "a")
    try:
        fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        lock.close()
        raise InputError(f"{path} is in use by another campaign run (lock {path}.lock)") from None
    return lock
