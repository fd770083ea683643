"""One task vocabulary: which task a number, a key or a finished task's entry is.

A campaign's tasks are its compressions (the grid, `campaign.grid`) and its
Monte-Carlo trial tasks (one per study, `campaign.trials.Study`). A task is
named by its `TaskKey` (kind, ordinal): a compression's ordinal i is its
grid index (its row of the store), a trial task's ordinal j its study's place
(its N trial rows, `campaign.store.schema.trial_rows`).

The policy and the scheduler queue, hand out and send tasks as one number
each (`TaskNumbers`): the compressions 0 .. n-1 in grid order, then trial
task j is n + j. A number queues, pickles and hashes at C speed (a key sent
per task would cost its pickling, about ten times an int's, on the engine's
busiest path). Only this module turns numbers into keys and back.

A finished task is an entry (what the journal records, `campaign.store.journal`):
a `CompressionEntry` (`row`, `results`) or a `TrialEntry` (`task`, per-cell
`cells`), both with `state`, `error`, `attempts`, `rank` and `started`
(Unix s). They are plain dicts (typed for the checker, free at run time);
`entry_key`, `is_compression` and `split` say which is which.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Final, Literal, NamedTuple, TypedDict, final

if TYPE_CHECKING:
    from typing_extensions import TypeIs

Kind = Literal["compression", "trial"]
COMPRESSION: Final = "compression"
TRIAL: Final = "trial"


class TaskKey(NamedTuple):
    """A task: a compression by its grid index, or a trial task by its study's place."""
    kind: Kind
    ordinal: int        # (`index` would hide the tuple's method)


_new = tuple.__new__    # TaskKey made as `_new(TaskKey, (kind, ordinal))`: a third of the time of
                        # TaskKey(kind, ordinal), whose __new__ is Python; the engine makes one per task


@dataclass(frozen=True, slots=True)
class TaskNumbers:
    """The numbers of a campaign's `compressions` compressions and `trials` trial tasks."""
    compressions: int
    trials: int = 0

    @property
    def count(self) -> int:
        """Tasks in all."""
        return self.compressions + self.trials

    def key(self, number: int) -> TaskKey:
        """The task numbered `number`."""
        n = self.compressions
        return _new(TaskKey, (COMPRESSION, number) if number < n else (TRIAL, number - n))

    def keys(self, numbers: Iterable[int]) -> list[TaskKey]:
        """The tasks numbered `numbers`, in their order."""
        n = self.compressions
        return [_new(TaskKey, (COMPRESSION, t) if t < n else (TRIAL, t - n)) for t in numbers]

    def number(self, key: TaskKey) -> int:
        """The number of task `key`."""
        return key.ordinal if key.kind == COMPRESSION else self.compressions + key.ordinal

    def of_compressions(self, rows: Iterable[int]) -> list[int]:
        """The numbers of the compressions of grid indices `rows` (the same integers:
        compressions come first, in grid order; no key made per task for a million of them)."""
        return list(rows)

    def of_entry(self, entry: Entry) -> int:
        """The number of the task whose entry `entry` is."""
        return entry["row"] if "row" in entry else self.compressions + entry["task"]


class _Finished(TypedDict):
    state: str          # one of campaign.store.schema.STATES: done or failed
    error: str          # a failed task's message ('' if none)
    attempts: int
    rank: int           # the rank that computed it
    started: float      # Unix s


@final
class CompressionEntry(_Finished):
    """A finished compression: its grid index `row` and the solver's `results`
    (result name -> value, `converged` among them; {} for a failed one)."""
    row: int
    results: dict[str, Any]


@final
class TrialEntry(_Finished):
    """A finished trial task: its study's place `task` and per cell its `cells`
    (`campaign.trials.run_study`'s lists and arrays; {} for a task failed as a whole)."""
    task: int
    cells: dict[str, Any]


Entry = CompressionEntry | TrialEntry


def is_compression(entry: Entry) -> TypeIs[CompressionEntry]:
    """Whether `entry` is a compression's (else a trial task's)."""
    return "row" in entry


def entry_key(entry: Entry) -> TaskKey:
    """The task whose entry `entry` is."""
    return _new(TaskKey, (COMPRESSION, entry["row"]) if "row" in entry else (TRIAL, entry["task"]))


def split(entries: Sequence[Entry]) -> tuple[list[CompressionEntry], list[TrialEntry]]:
    """(the compressions' entries, the trial tasks' entries) of `entries`, each in their order."""
    compressions: list[CompressionEntry] = []
    trials: list[TrialEntry] = []
    for e in entries:
        if "row" in e:
            compressions.append(e)
        else:
            trials.append(e)
    return compressions, trials


def compression_entry(row: int, results: dict[str, Any], state: str, error: str, attempts: int, rank: int,
                      started: float) -> CompressionEntry:
    """Compression `row`'s entry."""
    return {"row": row, "results": results, "state": state, "error": error, "attempts": attempts, "rank": rank,
            "started": started}


def trial_entry(task: int, cells: dict[str, Any], state: str, error: str, attempts: int, rank: int,
                started: float) -> TrialEntry:
    """Trial task `task`'s entry."""
    return {"task": task, "cells": cells, "state": state, "error": error, "attempts": attempts, "rank": rank,
            "started": started}
