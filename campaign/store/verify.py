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
  nothing but the store's damaged rows is written; a row whose parameters are damaged
  (PARAM_CHECKSUM fails) has them rewritten from the campaign's grid (the config text the store
  keeps, `campaign.config`, its grid's columns as `schema.fill` wrote them); refused beside
  another store's journal (`campaign.store.files.check_own_journal`);
- `pending_again(f)`: on opening for a run (`campaign.store.Store`), damaged rows set pending, to
  be computed again by that run.
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from campaign.store import checksum, journal
from campaign.store.files import open_store
from campaign.store.rows import write_entries
from campaign.store.schema import (CHECKSUM, PARAM_CHECKSUM, PENDING, TRIAL_PARAMS, stored_params, stored_results,
                                   trial_rows)
from campaign.store.schema import task_id as schema_task_id
from campaign.task_key import is_compression

if TYPE_CHECKING:
    import h5py


CHUNK = 1 << 16      # rows checked at a time: rank 0 holds CHUNK rows' columns (12 MB), not the store's


def damaged_rows(f: h5py.File) -> dict[str, npt.NDArray[np.int64]]:
    """{'rows': damaged task rows, 'trials': damaged trial rows, 'params' and 'trial_params': the task
    and trial rows whose parameters are damaged} of the open store `f` (empty arrays for a store
    without checksums), checked CHUNK rows at a time."""
    none = np.zeros(0, np.int64)
    out = {"rows": none, "trials": none, "params": none, "trial_params": none}
    if CHECKSUM in f:
        out["rows"] = _by_chunks(f, checksum.task_names(stored_results(f)), checksum.damaged)
    if PARAM_CHECKSUM in f:
        out["params"] = _by_chunks(f, checksum.param_names(stored_params(f)), checksum.bad_params)
    if "trials" in f and CHECKSUM in f["trials"]:
        out["trials"] = _by_chunks(f["trials"], checksum.TRIAL_COVERED, checksum.damaged)
    if "trials" in f and PARAM_CHECKSUM in f["trials"]:
        out["trial_params"] = _by_chunks(f["trials"], checksum.TRIAL_PARAM_COVERED, checksum.bad_params)
    return out


def _by_chunks(g, names, check):
    n = len(g["state"])
    parts = [start + check(lambda k: g[k][start:start + CHUNK], names) for start in range(0, n, CHUNK)]
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


def findings(path: str | os.PathLike[str]) -> dict[str, list]:
    """What is damaged in store `path`: {'rows': [[row, task id]], 'trial_rows': [[row, trial task,
    cell]], 'journal': [[start, end]] (damaged stretches, bytes), 'param_rows': [[row, task id]],
    'trial_param_rows': [[row, trial task, cell]] (rows whose parameters are damaged)}."""
    with open_store(path) as f:
        bad = damaged_rows(f)
        cells = int(f["trials"].attrs["cells_per_study"]) if "trials" in f else 1
        _drop_newer(bad, journal.read(str(path) + ".journal", f.attrs.get("journal_bytes", 0)), cells)
        ids = {int(r): f["task_id"][r].decode(errors="replace") for r in np.r_[bad["rows"], bad["params"]]}
    return {"rows": [[r, ids[r]] for r in bad["rows"].tolist()],
            "trial_rows": [[r, r // cells, r % cells] for r in bad["trials"].tolist()],
            "journal": [[a, b] for a, b in journal_damage(path)],
            "param_rows": [[r, ids[r]] for r in bad["params"].tolist()],
            "trial_param_rows": [[r, r // cells, r % cells] for r in bad["trial_params"].tolist()]}


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
            + [f"{path}: row {r} (task {t}): its parameters are damaged, their checksum fails"
               for r, t in found.get("param_rows", [])]
            + [f"{path}: trial row {r} (trial task {j}, cell {c}): its parameters are damaged, their checksum fails"
               for r, j, c in found.get("trial_param_rows", [])]
            + [f"{path}.journal: bytes {a}-{b} damaged (no record there checks); its tasks are pending "
               "unless their rows hold them" for a, b in found["journal"]])


def repair(path: str | os.PathLike[str]) -> list[str]:
    """Rewrite the damaged rows of store `path` from the journal (module docstring), under its lock;
    one line per row rewritten or set pending."""
    import h5py

    from campaign.store.files import check_own_journal, check_store_path, open_read
    from campaign.store.store import hold_lock
    verify(path)                                    # InputError for what is not a store
    check_store_path(str(path))
    lock = hold_lock(str(path))
    try:
        with open_read(path) as f:
            journal_bytes, mark = int(f.attrs.get("journal_bytes", 0)), str(f.attrs.get("journal_mark", ""))
        check_own_journal(str(path), journal_bytes, mark)      # not another store's journal
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
    lines += _rewrite_params(f, path, bad["params"], bad["trial_params"])
    f.flush()
    return lines


def _rewrite_params(f, path, rows, trial):
    """The parameters of task rows `rows` and trial rows `trial` rewritten from the campaign's grid
    (its columns made for the while: 8 bytes a task and parameter), with their PARAM_CHECKSUM; one
    line per row."""
    if not len(rows) and not len(trial):
        return []
    campaign = _stored_campaign(f)
    if len(rows):
        names, grid = checksum.param_names(stored_params(f)), campaign.shells.columns()   # as `schema.fill`
        columns = {k: grid[k][rows] for k in names[:-1]}
        del grid
        columns["bending"] = columns["bending"].astype(f["bending"].dtype)
        columns["task_id"] = np.array([schema_task_id(campaign.shells[int(r)], campaign.method) for r in rows], "S16")
        columns[PARAM_CHECKSUM] = checksum.row_checksums([columns[k] for k in names])
        for key, values in columns.items():
            f[key][rows] = values
    if len(trial):
        g, cells = f["trials"], int(f["trials"].attrs["cells_per_study"])
        studies = [campaign.studies[int(r) // cells] for r in trial]
        columns = {"task": trial // cells, "study": np.array([s.study for s in studies]), "cell": trial % cells}
        columns.update((k, np.array([getattr(s, a) for s in studies], float)) for k, a in TRIAL_PARAMS.items())
        columns["h0_true_um"] = np.array([s.heights_um for s in studies], float)
        columns[PARAM_CHECKSUM] = checksum.row_checksums([columns[k] for k in checksum.TRIAL_PARAM_COVERED])
        for key, values in columns.items():
            g[key][trial] = np.asarray(values).astype(g[key].dtype)
    return ([f"{path}: row {r} parameters rewritten from the campaign's grid" for r in rows.tolist()]
            + [f"{path}: trial row {r} parameters rewritten from the campaign's grid" for r in trial.tolist()])


def _stored_campaign(f):
    """The campaign of the open store `f`, loaded from the config text it keeps."""
    import tempfile

    from campaign.config import load
    with tempfile.TemporaryDirectory() as tmp:
        config = os.path.join(tmp, "campaign.toml")
        with open(config, "w") as fh:
            fh.write(f.attrs["config_text"])
        return load(config)
