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
odds about 2^-64. The error message (text) is not covered.

The parameters, written once when the store is made (`schema.fill`), have their own column
PARAM_CHECKSUM, the same sum over `param_names` (the parameter columns, then `bending` and
`task_id`, a fixed-length string as its 8-byte words, zero-padded) in a task row and over
TRIAL_PARAM_COVERED in a trial row; it is checked in every row, whatever its state
(`bad_params`), and a damaged one is rewritten from the campaign's grid (`campaign.store.verify`).

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

from campaign.store.schema import CELL_KEYS, CHECKSUM, DONE, FAILED, HEIGHT_KEYS, PARAM_CHECKSUM, TRIAL_PARAMS

TASK_COVERED = ("state", "converged", "attempts", "rank", "started_unix_s")
TRIAL_COVERED = ("state", "attempts", "rank", "started_unix_s") + CELL_KEYS + HEIGHT_KEYS
TRIAL_PARAM_COVERED = ("task", "study", "cell") + tuple(TRIAL_PARAMS) + ("h0_true_um",)
_PHI = np.uint64(0x9E3779B97F4A7C15)


def _weights(count: int) -> npt.NDArray[np.uint64]:
    """K_j for j = 0 .. count - 1."""
    with np.errstate(over="ignore"):
        return (np.arange(count, dtype=np.uint64) * np.uint64(2) + np.uint64(1)) * _PHI


def _bits(column: np.ndarray, n: int) -> npt.NDArray[np.uint64]:
    """A column's values (n rows, one value or several a row) as 64-bit patterns, (n, k)."""
    a = np.asarray(column)
    if a.dtype.kind == "S":                         # fixed-length text: its 8-byte words, zero-padded
        words = np.zeros((n, -(-a.dtype.itemsize // 8) * 8), np.uint8)
        words[:, :a.dtype.itemsize] = np.ascontiguousarray(a).view(np.uint8).reshape(n, -1)
        return words.view(np.uint64)
    if a.dtype == np.float64:
        return np.ascontiguousarray(a).view(np.uint64).reshape(n, -1)
    return a.astype(np.int64).view(np.uint64).reshape(n, -1)


def row_checksums(columns: Sequence[np.ndarray], first: int = 0) -> npt.NDArray[np.uint64]:
    """c of each row of `columns` (each n rows, in covered order; module docstring); `first`: the
    index j of their first value (the sum over the values before, added to this one, is the whole)."""
    n = len(columns[0]) if columns else 0
    bits = [_bits(column, n) for column in columns]
    weights = _weights(first + sum(b.shape[1] for b in bits))
    total, j = np.zeros(n, np.uint64), first
    with np.errstate(over="ignore"):
        for b in bits:
            for t in range(b.shape[1]):
                total += b[:, t] * weights[j]
                j += 1
    return total


def task_names(results: Sequence[str]) -> tuple[str, ...]:
    """The covered columns of a task row whose result columns are `results`, in order."""
    return TASK_COVERED + tuple(results)


def param_names(params: Sequence[str]) -> tuple[str, ...]:
    """The columns a task row's PARAM_CHECKSUM covers, its parameter columns `params` first, in order."""
    return tuple(params) + ("bending", "task_id")


def bad_params(get: Callable[[str], np.ndarray], names: Sequence[str]) -> npt.NDArray[np.int64]:
    """The rows (any state) whose PARAM_CHECKSUM fails; `get(name)` gives a column, `names` the covered."""
    sums = row_checksums([np.asarray(get(name)) for name in names])
    return np.flatnonzero(sums != np.asarray(get(PARAM_CHECKSUM)))


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
