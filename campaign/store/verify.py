"""Damaged rows found and rewritten: what `cortex campaign verify` and `cortex campaign repair` do,
and what a run does on opening a store.

A row is damaged when it is done or failed and its checksum fails (`campaign.store.checksum`); a
journal record is damaged when its CRC fails (`campaign.store.journal`; a record a kill cut at
the journal's end is not damage, the next run trims it).

- `verify(path)`: one line per damaged row, trial row and journal stretch (read-only, no lock:
  also while a campaign runs; a row the journal holds past the file's `journal_bytes`, which a
  run may be writing, is not checked: the readers take it from the journal);
- `repair(path)`: under the store's lock, each damaged row rewritten from its task's last entry in
  the journal (`campaign.store.rows.write_entries`, which writes the values and the checksum the
  run wrote), a damaged row the journal does not hold set pending (the next run computes it);
  nothing but the store's damaged rows is written;
- `pending_again(f)`: on opening for a run (`campaign.store.Store`), damaged rows set pending, to
  be computed again by that run.
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from campaign.store import checksum, journal
from campaign.store.rows import write_entries
from campaign.store.schema import CHECKSUM, PENDING, stored_results, trial_rows
from campaign.task_key import is_compression

if TYPE_CHECKING:
    import h5py


CHUNK = 1 << 16      # rows checked at a time: rank 0 holds CHUNK rows' columns (12 MB), not the store's


def damaged_rows(f: h5py.File) -> dict[str, npt.NDArray[np.int64]]:
    """{'rows': damaged task rows, 'trials': damaged trial rows} of the open store `f` (empty arrays
    for a store without checksums), checked CHUNK rows at a time."""
    out = {"rows": np.zeros(0, np.int64), "trials": np.zeros(0, np.int64)}
    if CHECKSUM in f:
        out["rows"] = _by_chunks(f, checksum.task_names(stored_results(f)))
    if "trials" in f and CHECKSUM in f["trials"]:
        out["trials"] = _by_chunks(f["trials"], checksum.TRIAL_COVERED)
    return out


def _by_chunks(g, names):
    n = len(g["state"])
    parts = [start + checksum.damaged(lambda k: g[k][start:start + CHUNK], names) for start in range(0, n, CHUNK)]
    return np.concatenate(parts) if parts else np.zeros(0, np.int64)


def pending_again(f: h5py.File) -> dict[str, npt.NDArray[np.int64]]:
    """Set the damaged rows of the open store `f` pending (a run computes them again); returns them."""
    bad = damaged_rows(f)
    for name, rows in (("state", bad["rows"]), ("trials/state", bad["trials"])):
        if len(rows):
            state = f[name][:]
            state[rows] = PENDING
            f[name][:] = state
    return bad


def journal_damage(path: str | os.PathLike[str]) -> list[tuple[int, int]]:
    """The damaged stretches (start, end bytes) of the journal of store `path` (a cut last record
    not among them)."""
    stretches = journal.read_all(str(path) + ".journal", decoded=False)
    last = max((i for i, (_, _, e) in enumerate(stretches) if e is not None), default=-1)
    return [(a, b) for i, (a, b, e) in enumerate(stretches) if e is None and i < last]


def _open_store(path):
    """Store `path` opened read-only; InputError (one line) for a file that is not one."""
    from campaign.store.files import open_read
    from common.errors import InputError
    f = open_read(path)
    if "fingerprint" not in f.attrs or "state" not in f:
        f.close()
        raise InputError(f"{path}: not a campaign store")
    return f


def findings(path: str | os.PathLike[str]) -> dict[str, list]:
    """What is damaged in store `path`: {'rows': [[row, task id]], 'trial_rows': [[row, trial task,
    cell]], 'journal': [[start, end]] (damaged stretches, bytes)}."""
    with _open_store(path) as f:
        bad = damaged_rows(f)
        cells = int(f["trials"].attrs["cells_per_study"]) if "trials" in f else 1
        _drop_newer(bad, journal.read(str(path) + ".journal", f.attrs.get("journal_bytes", 0)), cells)
        ids = f["task_id"][bad["rows"]] if len(bad["rows"]) else []
    return {"rows": [[int(r), t.decode()] for r, t in zip(bad["rows"], ids)],
            "trial_rows": [[r, r // cells, r % cells] for r in bad["trials"].tolist()],
            "journal": [[a, b] for a, b in journal_damage(path)]}


def _drop_newer(bad, entries, cells):
    """Leave out of `bad` the rows the journal holds past the rows (a running campaign's rows being
    written: the readers take them from the journal)."""
    rows = {e["row"] for e in entries if is_compression(e)}
    tasks = {e["task"] for e in entries if not is_compression(e)}
    bad["rows"] = np.array([r for r in bad["rows"].tolist() if r not in rows], np.int64)
    bad["trials"] = np.array([r for r in bad["trials"].tolist() if r // cells not in tasks], np.int64)


def verify(path: str | os.PathLike[str], found: dict[str, list] | None = None) -> list[str]:
    """One line per damaged row, trial row and journal stretch of store `path` ([] if none);
    `found`: its `findings`, if made already."""
    found = findings(path) if found is None else found
    return ([f"{path}: row {r} (task {t}): damaged, its checksum fails" for r, t in found["rows"]]
            + [f"{path}: trial row {r} (trial task {j}, cell {c}): damaged, its checksum fails"
               for r, j, c in found["trial_rows"]]
            + [f"{path}.journal: bytes {a}-{b} damaged (no record there checks); its tasks are pending "
               "unless their rows hold them" for a, b in found["journal"]])


def repair(path: str | os.PathLike[str]) -> list[str]:
    """Rewrite the damaged rows of store `path` from the journal (module docstring), under its lock;
    one line per row rewritten or set pending."""
    import h5py

    from campaign.store.files import check_store_path
    from campaign.store.store import hold_lock
    verify(path)                                    # InputError for what is not a store
    check_store_path(str(path))
    lock = hold_lock(str(path))
    try:
        with h5py.File(path, "r+") as f:
            return _rewrite(f, str(path))
    finally:
        lock.close()


def _rewrite(f, path):
    bad = damaged_rows(f)
    rows, trial = set(bad["rows"].tolist()), set(bad["trials"].tolist())
    cells = int(f["trials"].attrs["cells_per_study"]) if "trials" in f else 1
    tasks = {r // cells for r in trial}
    entries = [e for e in journal.read(path + ".journal")
               if (e["row"] in rows if is_compression(e) else e["task"] in tasks)]
    write_entries(f, entries, cells)
    held = {e["row"] if is_compression(e) else -1 - e["task"] for e in entries}
    lines = []
    for r in sorted(rows):
        lines.append(f"{path}: row {r} " + ("rewritten from the journal" if r in held else
                                           "is not in the journal: pending again (a rerun computes it)"))
    for r in sorted(trial):
        lines.append(f"{path}: trial row {r} " + ("rewritten from the journal" if -1 - r // cells in held else
                                                 "is not in the journal: pending again (a rerun computes it)"))
    missing = {"state": [r for r in rows if r not in held],
               "trials/state": [r for t in tasks if -1 - t not in held for r in trial_rows(t, cells)]}
    for name, marks in missing.items():
        if marks:
            state = f[name][:]
            state[np.array(sorted(marks))] = PENDING
            f[name][:] = state
    f.flush()
    return lines
