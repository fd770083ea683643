"""Rows that check themselves: the checksum a done or failed row carries, and which rows fail it.

Where a row is written (`campaign.store.rows`, the one place), its column `checksum` (uint64) gets

    c = Σ_j K_j · v_j   (mod 2^64)

over the row's covered values v_j, each as its 64-bit pattern (a float64's bits; an integer
widened to 64 bits), K_j = (2 j + 1) · φ mod 2^64 with φ = 0x9E3779B97F4A7C15, every K_j odd and
no two alike. A task row covers TASK_COVERED (state, converged, attempts, rank, started) and its
result columns (`schema.stored_results`); a trial row TRIAL_COVERED (state, attempts, rank,
started), CELL_KEYS and HEIGHT_KEYS (each of the m heights its own v_j). One flipped bit changes
one v_j by ±2^b, hence c by ±K_j 2^b (mod 2^64), which is never 0 (K_j is odd, b < 64): every
single flipped bit in a covered column, or in the checksum itself, is seen; more are missed with
odds about 2^-64. The error message (text) and the parameters (written once, when the store is
made) are not covered.

Only rows whose state is done or failed are checked (`damaged`): a pending or running row holds
no result (its checksum is whatever its last write left). A done row whose state bit turns it
pending is computed again by the next run, never read as a result; a pending row turned done
fails its checksum (0). The check is numpy over whole columns: a few passes over what the
readers read anyway (the figure at a million rows: docs/store.md, `bench/million.py`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import numpy.typing as npt

from campaign.store.schema import CELL_KEYS, CHECKSUM, DONE, FAILED, HEIGHT_KEYS

TASK_COVERED = ("state", "converged", "attempts", "rank", "started_unix_s")
TRIAL_COVERED = ("state", "attempts", "rank", "started_unix_s") + CELL_KEYS + HEIGHT_KEYS
_PHI = np.uint64(0x9E3779B97F4A7C15)


def _weights(count: int) -> npt.NDArray[np.uint64]:
    """K_j for j = 0 .. count - 1."""
    with np.errstate(over="ignore"):
        return (np.arange(count, dtype=np.uint64) * np.uint64(2) + np.uint64(1)) * _PHI


def _bits(column: np.ndarray, n: int) -> npt.NDArray[np.uint64]:
    """A column's values (n rows, one value or several a row) as 64-bit patterns, (n, k)."""
    a = np.asarray(column)
    if a.dtype == np.float64:
        return np.ascontiguousarray(a).view(np.uint64).reshape(n, -1)
    return a.astype(np.int64).view(np.uint64).reshape(n, -1)


def row_checksums(columns: Sequence[np.ndarray]) -> npt.NDArray[np.uint64]:
    """c of each row of `columns` (each n rows, in covered order; module docstring)."""
    n = len(columns[0]) if columns else 0
    bits = [_bits(column, n) for column in columns]
    weights = _weights(sum(b.shape[1] for b in bits))
    total, j = np.zeros(n, np.uint64), 0
    with np.errstate(over="ignore"):
        for b in bits:
            for t in range(b.shape[1]):
                total += b[:, t] * weights[j]
                j += 1
    return total


def task_names(results: Sequence[str]) -> tuple[str, ...]:
    """The covered columns of a task row whose result columns are `results`, in order."""
    return TASK_COVERED + tuple(results)


def damaged(get: Callable[[str], np.ndarray], names: Sequence[str]) -> npt.NDArray[np.int64]:
    """The done or failed rows whose checksum fails, by row number; `get(name)` gives a column
    (`names`: the covered ones, in order; CHECKSUM and `state` among what it gives)."""
    state = np.asarray(get("state"))
    checked = np.flatnonzero((state == DONE) | (state == FAILED))
    if not len(checked):
        return checked
    every = len(checked) == len(state)           # a finished store: no copy of its columns
    pick = (lambda a: a) if every else (lambda a: a[checked])
    sums = row_checksums([pick(np.asarray(get(name))) for name in names])
    return checked[sums != pick(np.asarray(get(CHECKSUM)))]
