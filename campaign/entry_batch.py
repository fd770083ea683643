"""Finished compressions as columns: how a task process sends a batch of
them, and the one place their columns are taken from entries.

A task process's answer is a list of entries (`campaign.task_key`), one
dict per task. A compression's entry holds a dict of results, so a batch of
b no-op compressions is b + b dicts to pickle, to unpickle on rank 0 and to
take apart again into the journal's and the rows' columns: about 10 us a
task on rank 0, which for tasks of a few microseconds is more than the
computing. When every task of a batch is a compression whose results have
the same names (all of a batch that finished: a failed compression has no
results), the task process sends a `CompressionBatch` instead: the columns

    row (int64), state (int8, into STATES), attempts, rank (int32),
    started (float64, Unix s), values (float64, tasks x result names),

the result names once, and the messages by position. Rank 0 records it
whole (`campaign.store.Store.record_all`); the journal and the rows take its
columns as they are (`compression_columns`), so what they write is the same,
bit for bit, as from the entries it stands for. Anything else that iterates
it gets those entries, made on demand (`entries`): a result that was an int
or a bool comes back as a float, which is how the journal and the rows
store it anyway.
"""

from __future__ import annotations

import operator
from collections.abc import Iterable, Iterator, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from campaign.store.schema import STATES, results_table
from campaign.task_key import (COMPRESSION, CompressionEntry, Entry, TaskKey, TrialEntry, compression_entry,
                               is_compression)

if TYPE_CHECKING:
    from typing_extensions import TypeIs

_CODE = {s: i for i, s in enumerate(STATES)}
_META = operator.itemgetter("row", "state", "attempts", "rank", "started", "error")
COLUMNS = {"row": np.int64, "state": np.int8, "attempts": np.int32, "rank": np.int32, "started": np.float64,
           "converged": np.int8}      # `compression_columns`' bookkeeping columns and their dtypes


class CompressionBatch:
    """Finished compressions as columns (module docstring); a sequence of their entries."""

    __slots__ = ("row", "state", "attempts", "rank", "started", "names", "values", "errors")

    def __init__(self, row: npt.NDArray[np.int64], state: npt.NDArray[np.int8], attempts: npt.NDArray[np.int32],
                 rank: npt.NDArray[np.int32], started: npt.NDArray[np.float64], names: tuple[str, ...],
                 values: npt.NDArray[np.float64], errors: dict[int, str]):
        self.row, self.state, self.attempts, self.rank, self.started = row, state, attempts, rank, started
        self.names, self.values, self.errors = names, values, errors

    @classmethod
    def of(cls, entries: Sequence[Entry]) -> CompressionBatch | None:
        """`entries` as columns, or None unless all are compressions whose results have the same names."""
        compressions = [e for e in entries if is_compression(e)]
        if not entries or len(compressions) != len(entries):
            return None
        results = [e["results"] for e in compressions]
        names = tuple(results[0])
        if not names or set(map(len, results)) != {len(names)}:
            return None
        try:                # each has every name and no other (as many), each value a number
            values = np.array(list(map(operator.itemgetter(*names), results)), np.float64)
        except (KeyError, TypeError, ValueError):
            return None
        values = values.reshape(len(results), len(names))
        row, state, attempts, rank, started, error = zip(*map(_META, compressions))
        return cls(np.array(row, np.int64), np.array([_CODE[s] for s in state], np.int8),
                   np.array(attempts, np.int32), np.array(rank, np.int32), np.array(started, np.float64),
                   names, values, {i: m for i, m in enumerate(error) if m})

    def __len__(self) -> int:
        return len(self.row)

    def entries(self) -> list[CompressionEntry]:
        """The entries this batch stands for, in order."""
        values = self.values.tolist()
        return [compression_entry(r, dict(zip(self.names, v)), STATES[s], self.errors.get(i, ""), a, k, t)
                for i, (r, s, a, k, t, v) in enumerate(zip(self.row.tolist(), self.state.tolist(),
                                                           self.attempts.tolist(), self.rank.tolist(),
                                                           self.started.tolist(), values))]

    def __iter__(self) -> Iterator[CompressionEntry]:
        return iter(self.entries())

    def part(self, start: int, stop: int) -> CompressionBatch:
        """Tasks start .. stop - 1 of this batch, as a batch."""
        cut = slice(start, stop)
        return CompressionBatch(self.row[cut], self.state[cut], self.attempts[cut], self.rank[cut],
                                self.started[cut], self.names, self.values[cut],
                                {i - start: m for i, m in self.errors.items() if start <= i < stop})

    def keys(self) -> set[TaskKey]:
        """The tasks of this batch."""
        return {TaskKey(COMPRESSION, r) for r in self.row.tolist()}

    def failed(self) -> int:
        """How many of its tasks failed."""
        return int(np.count_nonzero(self.state == _CODE["failed"]))


Chunk = CompressionEntry | CompressionBatch


def is_batch(entries: object) -> TypeIs[CompressionBatch]:
    """Whether `entries` is a `CompressionBatch` (else entries)."""
    return isinstance(entries, CompressionBatch)


def split(items: Iterable[Entry | CompressionBatch]) -> tuple[list[Chunk], list[TrialEntry]]:
    """(the compressions: entries and batches, the trial tasks' entries) of `items`, each in their order."""
    compressions: list[Chunk] = []
    trials: list[TrialEntry] = []
    for x in items:
        if is_batch(x) or is_compression(x):
            compressions.append(x)
        else:
            trials.append(x)
    return compressions, trials


def compression_columns(chunks: Sequence[Chunk], names: Sequence[str] | None = None) -> dict[str, Any]:
    """The columns of compression entries and batches `chunks`, in order:
    row, state, attempts, rank, started, converged (arrays), `results`
    ({name: float64 array, NaN where a task lacks it} for `names`, by default
    every result some task has, in the order first met) and `errors` ({position: message}). A run of
    entries is taken apart as one (a pass per column), a batch as it is."""
    pieces: list[dict[str, Any]] = []
    run: list[CompressionEntry] = []
    for chunk in chunks:
        if is_batch(chunk):
            if run:
                pieces.append(_entry_columns(run))
                run = []
            pieces.append(_batch_columns(chunk))
        else:
            run.append(chunk)
    if run:
        pieces.append(_entry_columns(run))
    if names is None:
        names = list(dict.fromkeys(k for p in pieces for k in p["names"]() if k != "converged"))
    out: dict[str, Any] = {"errors": {}}
    at = 0
    for p in pieces:
        out["errors"].update({at + i: m for i, m in p["errors"].items()})
        at += len(p["row"])
    for key, dtype in COLUMNS.items():
        out[key] = np.concatenate([p[key] for p in pieces]) if pieces else np.zeros(0, dtype)
    table = (np.concatenate([p["table"](names) for p in pieces]) if pieces
             else np.zeros((0, len(names))))
    out["results"] = dict(zip(names, table.T))
    return out



def _batch_columns(batch: CompressionBatch) -> dict[str, Any]:
    n, where = len(batch), {k: i for i, k in enumerate(batch.names)}

    def table(names):
        out = np.full((n, len(names)), np.nan)
        for j, k in enumerate(names):
            if k in where:
                out[:, j] = batch.values[:, where[k]]
        return out
    converged = batch.values[:, where["converged"]] != 0 if "converged" in where else np.zeros(n, bool)
    return {"row": batch.row, "state": batch.state, "attempts": batch.attempts, "rank": batch.rank,
            "started": batch.started, "converged": converged.astype(np.int8), "errors": batch.errors,
            "names": lambda: batch.names, "table": table}


def _entry_columns(entries: list[CompressionEntry]) -> dict[str, Any]:
    results = [e.get("results") or {} for e in entries]
    columns = {"row": [e["row"] for e in entries], "state": [_CODE[e["state"]] for e in entries],
               "attempts": [e["attempts"] for e in entries], "rank": [e["rank"] for e in entries],
               "started": [e.get("started", np.nan) for e in entries],
               "converged": [bool(r.get("converged", False)) for r in results]}
    out: dict[str, Any] = {key: np.array(columns[key], dtype) for key, dtype in COLUMNS.items()}
    out.update(errors={i: e["error"] for i, e in enumerate(entries) if e.get("error")},
               names=lambda: [k for r in results for k in r], table=lambda names: results_table(results, names))
    return out
