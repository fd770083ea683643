"""Journal entries into HDF5 rows: the one place a store's rows are written.

A compression's entry (`row`) fills its task row (state, attempts, rank,
error, converged, started, RESULTS and, in a table campaign's store,
its task's own: `schema.stored_results`); a trial task's entry (`task` j) fills
its study's N trial rows j N .. j N + N - 1 (`trial_columns`). Rows are
written one HDF5 write per column and run of consecutive rows (on the rank0
path one scattered write per column where the runs are many; `put`); the
last entry of a row wins. Each row written gets its checksum (`campaign.store.checksum`), from
the values written.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from campaign.entry_batch import CompressionBatch, compression_columns, split
from campaign.store.checksum import TRIAL_COVERED, row_checksums, task_names
from campaign.store.schema import CELL_KEYS, CHECKSUM, HEIGHT_KEYS, STATES, clip, stored_results, trial_rows
from campaign.task_key import Entry, TrialEntry

if TYPE_CHECKING:
    import h5py

RUNS_MAX = 16       # rank0 path: more runs of consecutive rows than this are written as one scattered write


def write_entries(f: h5py.File, entries: Sequence[Entry | CompressionBatch], cells: int,
                  contiguous: bool = False) -> None:
    """Write journal entries (and `CompressionBatch`es, which stand for theirs)
    into their rows of the open file `f`; `cells`: trials per study (N)."""
    compressions, trials = split(entries)
    _write_trials(f, {e["task"]: e for e in trials}, cells)
    if not compressions:
        return
    c = compression_columns(compressions, stored_results(f))
    rows, last = np.unique(c["row"][::-1], return_index=True)
    last = len(c["row"]) - 1 - last                # each row's last entry, rows in order
    errors = np.full(len(c["row"]), "", object)
    for i, message in c["errors"].items():
        errors[i] = message
    columns: dict[str, np.ndarray] = {
        "state": c["state"][last], "attempts": c["attempts"][last], "rank": c["rank"][last],
        "error": errors[last], "converged": c["converged"][last], "started_unix_s": c["started"][last]}
    columns.update((key, values[last]) for key, values in c["results"].items())
    if CHECKSUM in f:               # (a store made before rows had checksums has none)
        columns[CHECKSUM] = row_checksums([columns[k] for k in task_names(c["results"])])
    for key, values in columns.items():
        put(f[key], rows, values, contiguous)


def runs(rows: npt.NDArray[np.int64]) -> list[tuple[int, int, slice]]:
    """Sorted row numbers as (start, stop, index range) of consecutive runs."""
    cuts = np.flatnonzero(np.diff(rows) != 1) + 1
    starts, stops = np.r_[0, cuts], np.r_[cuts, len(rows)]
    return [(int(rows[a]), int(rows[b - 1]) + 1, slice(a, b)) for a, b in zip(starts, stops)]


def _fit(dset, values):
    """`values` as `dset` stores them (error messages clipped to fixed length)."""
    return np.array([clip(v) if v else b"" for v in values], dset.dtype) if dset.dtype.kind == "S" else values


def put(dset: h5py.Dataset, rows: npt.NDArray[np.int64], values: np.ndarray, contiguous: bool) -> None:
    """dset[rows] = values, by runs of consecutive rows if `contiguous` (parallel
    HDF5 writes no scattered selection) or if there are at most RUNS_MAX of
    them: h5py builds a scattered selection point by point (~9 ms for 512
    rows), a slice is one hyperslab (~0.1 ms), and rows are handed out in
    order, so a flush's rows are mostly a few runs."""
    values = _fit(dset, values)
    parts = runs(rows)
    if not contiguous and len(parts) > RUNS_MAX:
        dset[rows] = values
        return
    for start, stop, part in parts:
        dset[start:stop] = values[part]


def _write_trials(f, by_task, N):
    """Trial tasks' entries (`trial_columns`), one slice write per column
    for each run of consecutive tasks."""
    if not by_task:
        return
    g = f["trials"]
    tasks = np.array(sorted(by_task))
    for start, stop, _ in runs(tasks):
        parts = [trial_columns(by_task[t], N, g["h0_true_um"].shape[1]) for t in range(start, stop)]
        rows = trial_rows(start, N, stop - start)
        columns = {key: np.concatenate([p[key] for p in parts]) for key in parts[0]}
        if CHECKSUM in g:
            columns[CHECKSUM] = row_checksums([columns[k] for k in TRIAL_COVERED])
        for key, values in columns.items():
            g[key][rows.start:rows.stop] = _fit(g[key], values)


def trial_columns(entry: TrialEntry, N: int, m: int) -> dict[str, np.ndarray]:
    """A trial task's journal entry as the columns of its N rows. `cells` holds
    per-cell lists (`state`, `error`, CELL_KEYS) and per-cell lists of
    per-height values (HEIGHT_KEYS); a task that failed as a whole has no
    `cells`: all its trials are failed with its error, their values NaN.
    m: heights per trial."""
    cells = entry.get("cells") or {}
    out = {"state": np.array([STATES.index(x) for x in cells.get("state", [entry["state"]] * N)], np.int8),
           "error": np.array(cells.get("error", [entry.get("error", "")] * N), object),
           "attempts": np.full(N, entry["attempts"], np.int32), "rank": np.full(N, entry["rank"], np.int32),
           "started_unix_s": np.full(N, entry.get("started", np.nan), float)}
    for key in CELL_KEYS + HEIGHT_KEYS:
        shape = (N,) if key in CELL_KEYS else (N, m)
        out[key] = np.asarray(cells[key], float) if key in cells else np.full(shape, np.nan)
    return out

