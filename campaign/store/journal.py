"""The journal codec: finished tasks' entries, one binary record per flush.

A record holds every entry of one flush (`encode`):

    MAGIC | header length, data length (two little-endian u64) | header | data | CRC-32 of header and data

The header is JSON: per array of the data its name, dtype and shape, the
messages of failed tasks by position, per trial task its scalars, and in a
journal's first record the mark of its store (`store`: the store's attribute
`journal_mark`, `mark`), which tells a store its own journal. The
data are the arrays' raw bytes: a compression's columns (row, state,
attempts, rank, started, converged and each result present), and per
trial task its cells' states and float64 arrays (CELL_KEYS, HEIGHT_KEYS), so
values come back bit for bit. Entries are those of `campaign.task_key`
(`CompressionEntry`, `TrialEntry`), as `campaign.tasks.entry` makes them.

The store (`campaign.store.Store`) appends a record at each flush, and
whenever the entries it keeps reach RECORD_BYTES (without an fsync: that,
and the rows, wait for the flush): the journal then grows steadily (a full
disk stops a run part way, not at its end) and rank 0 holds a bounded
number of entries not yet journalled.

A record is complete when all its bytes and its CRC are there: a kill or a
full disk can only cut the last one, which `trim_cut` removes before a run
appends (no row holds it: rows follow the journal's fsync). A record damaged
later (its CRC fails: a flipped bit, a bad sector) is skipped by the readers,
which find the next record by its MAGIC and check it: the records after it
are read, and its tasks are pending again unless their rows hold them.
"""

import contextlib
import json
import mmap
import os
import struct
import zlib
from collections.abc import Sequence
from typing import Any, BinaryIO

import numpy as np

from campaign.entry_batch import COLUMNS, CompressionBatch, compression_columns
from campaign.entry_batch import split as split_chunks
from campaign.store.schema import STATES
from campaign.task_key import Entry, compression_entry, is_compression, trial_entry

MAGIC = b"\x00cxj"
_SIZES = struct.Struct("<QQ")
_CRC = struct.Struct("<I")
_HEAD = len(MAGIC) + _SIZES.size
RECORD_BYTES = 64 * 1024    # a record holds at most about this much


def compression_bytes(results: int) -> int:
    """About how many bytes a compression's entry with `results` values takes in a record."""
    return 64 + 8 * results


def approx_bytes(entry: Entry) -> int:
    """About how many bytes `entry` takes in a record."""
    if is_compression(entry):
        return compression_bytes(len(entry["results"] or ()))
    cells = entry["cells"]
    return 64 + sum(getattr(v, "nbytes", 8 * len(v)) for v in cells.values()) if cells else 64


def encode(entries: Sequence[Entry | CompressionBatch], store: str = "") -> bytes:
    """One record (bytes) holding `entries` (a `CompressionBatch` among them
    stands for its entries: the record is the same), marked as `store`'s if given."""
    arrays: dict[str, np.ndarray] = {}
    header: dict[str, Any] = {"errors": {}, "tasks": []}
    if store:
        header["store"] = store
    compressions, trials = split_chunks(entries)
    if compressions:
        _compression_arrays(compressions, arrays, header["errors"])
    for k, e in enumerate(trials):
        header["tasks"].append(_trial_arrays(k, e, arrays))
    data = [np.ascontiguousarray(a) for a in arrays.values()]
    header["arrays"] = [[name, a.dtype.str, list(a.shape)] for name, a in zip(arrays, data)]
    head = json.dumps(header, separators=(",", ":")).encode()
    body = head + b"".join(a.tobytes() for a in data)
    return MAGIC + _SIZES.pack(len(head), len(body) - len(head)) + body + _CRC.pack(zlib.crc32(body))


def _compression_arrays(chunks, arrays, errors):
    """The compressions' arrays (entries and `CompressionBatch`es, in order): `COLUMNS`,
    then each result some task has; their messages by position."""
    columns = compression_columns(chunks)
    for key in COLUMNS:
        arrays[f"c.{key}"] = columns[key]
    for key, column in columns["results"].items():
        arrays[f"r.{key}"] = column
    errors.update({str(i): m for i, m in columns["errors"].items()})


def _trial_arrays(k, e, arrays):
    """Trial task `e`'s arrays under `t{k}.`; returns its header part."""
    cells = e.get("cells") or {}
    for key, value in cells.items():
        if key == "state":
            arrays[f"t{k}.state"] = np.array([STATES.index(s) for s in value], np.int8)
        elif key != "error":
            arrays[f"t{k}.{key}"] = np.asarray(value, np.float64)
    cell_errors = {str(i): m for i, m in enumerate(cells.get("error", ())) if m}
    return {"task": int(e["task"]), "state": e["state"], "error": e.get("error", ""),
            "attempts": int(e["attempts"]), "rank": int(e["rank"]), "started": e.get("started"),
            "cells": sorted(cells), "cell_errors": cell_errors}


def decode(header: dict[str, Any], data: bytes) -> list[Entry]:
    """The entries of one record (its JSON header and data bytes), in the
    order: compressions, then trial tasks."""
    arrays, offset = {}, 0
    for name, dtype, shape in header["arrays"]:
        a = np.frombuffer(data, dtype, int(np.prod(shape)), offset).reshape(shape)
        arrays[name], offset = a, offset + a.nbytes
    return _compression_entries(arrays, header["errors"]) + [_trial_entry(k, t, arrays)
                                                             for k, t in enumerate(header["tasks"])]


def _compression_entries(arrays, errors):
    if "c.row" not in arrays:
        return []
    c = {key: arrays[f"c.{key}"].tolist() for key in COLUMNS}
    r = {name[2:]: a.tolist() for name, a in arrays.items() if name.startswith("r.")}
    out = []
    for i in range(len(c["row"])):
        results = {key: values[i] for key, values in r.items()}
        results["converged"] = bool(c["converged"][i])
        out.append(compression_entry(c["row"][i], results, STATES[c["state"][i]], errors.get(str(i), ""),
                                     c["attempts"][i], c["rank"][i], c["started"][i]))
    return out


def _trial_entry(k, t, arrays):
    """Trial task `t` (the k-th of its record) as the entry it was."""
    cells = {}
    for key in t["cells"]:
        if key == "state":
            cells[key] = [STATES[s] for s in arrays[f"t{k}.state"].tolist()]
        elif key == "error":
            n = len(arrays[f"t{k}.state"]) if f"t{k}.state" in arrays else 0
            cells[key] = [t["cell_errors"].get(str(i), "") for i in range(n)]
        else:
            cells[key] = arrays[f"t{k}.{key}"].copy()
    return trial_entry(t["task"], cells, t["state"], t["error"], t["attempts"], t["rank"], t["started"])


def _record(buf, at, decoded=True):
    """(end, entries) of the record at byte `at` of `buf`, or None if no whole record that checks is there
    (`decoded` False: entries [] unless its header is not JSON, only its CRC checked)."""
    got = _header(buf, at)
    if got is None:
        return None
    end, header, data = got
    try:
        return end, (decode(header, data) if decoded else [])
    except (ValueError, KeyError, TypeError):       # a header that checks but is not ours
        return None


def _header(buf, at):
    """(end, header, data bytes) of the record at byte `at` of `buf`, or None if no whole record that
    checks, with a JSON header, is there."""
    lead = buf[at:at + _HEAD]
    if len(lead) < _HEAD or lead[:len(MAGIC)] != MAGIC:
        return None
    n_head, n_data = _SIZES.unpack(lead[len(MAGIC):])
    end = at + _HEAD + n_head + n_data + _CRC.size
    if end > len(buf):
        return None
    body = buf[at + _HEAD:end - _CRC.size]
    if _CRC.unpack(buf[end - _CRC.size:end])[0] != zlib.crc32(body):
        return None
    try:
        header = json.loads(body[:n_head])
    except ValueError:
        return None
    return (end, header, body[n_head:]) if isinstance(header, dict) else None


def _frames(buf, at=0, decoded=True):
    """(start, end, entries) of each stretch of `buf` from byte `at` on: a record that checks, or
    (entries None) a damaged stretch up to the next record that does (found by its MAGIC), or to the
    end (a record a kill cut)."""
    while at < len(buf):
        got = _record(buf, at, decoded)
        if got is not None:
            yield at, got[0], got[1]
            at = got[0]
            continue
        start = at
        while got is None:
            at = buf.find(MAGIC, at + 1)
            if at < 0:
                yield start, len(buf), None
                return
            got = _record(buf, at, decoded)
        yield start, at, None


@contextlib.contextmanager
def _mapped(path):
    """The journal's bytes (memory-mapped; b'' for an empty or missing one)."""
    if not os.path.exists(path) or os.path.getsize(path) == 0:
        yield b""
        return
    with open(path, "rb") as fh, mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ) as buf:
        yield buf


def read(path: str | os.PathLike[str], start: int = 0) -> list[Entry]:
    """Entries of a journal from byte `start` on (a store's `journal_bytes`:
    everything before is in its rows); a damaged record (its CRC fails) is skipped, the records
    after it read; a record cut by a kill is ignored."""
    entries: list[Entry] = []
    with _mapped(path) as buf:
        for _, _, batch in _frames(buf, int(start)):
            entries.extend(batch or ())
    return entries


def read_all(path: str | os.PathLike[str], decoded: bool = True) -> list[tuple[int, int, list[Entry] | None]]:
    """(start, end, entries) of every stretch of the journal: its records, and (entries None) its
    damaged stretches (`_frames`); `decoded` False: each record's entries [] (its CRC checked only)."""
    with _mapped(path) as buf:
        return list(_frames(buf, 0, decoded))


def complete_bytes(path: str | os.PathLike[str]) -> int:
    """How many leading bytes of the journal end with a complete record (damaged records before
    it included: they stay, and are skipped when read)."""
    end = 0
    with _mapped(path) as buf:
        for _, stop, batch in _frames(buf, 0, False):
            if batch is not None:
                end = stop
    return end


def trim_cut(path: str | os.PathLike[str]) -> None:
    """Cut the journal after its last complete record: a kill or a full disk
    may have left the last one unfinished; it was never fsync'd whole, so no
    row holds it, and records appended after it must stay readable. A damaged
    record with complete ones after it is kept (skipped when read)."""
    if os.path.exists(path) and os.path.getsize(path) > 0:
        end = complete_bytes(path)
        if end < os.path.getsize(path):
            with open(path, "rb+") as fh:
                fh.truncate(end)


def append(fh: BinaryIO, entries: Sequence[Entry], store: str = "") -> None:
    """Write one record of `entries` to the open journal `fh` (binary, append),
    as far as the operating system (a kill cannot lose it; `sync` makes it durable);
    marked as `store`'s if given (a journal's first record)."""
    fh.write(encode(entries, store))
    fh.flush()


def mark(path: str | os.PathLike[str]) -> str | None:
    """The mark of the store whose journal this is: its first record's ('' if that record has none:
    written by another store, or before records were marked); None when that cannot be told (an
    empty or missing journal, a first record cut or damaged)."""
    with _mapped(path) as buf:
        got = _header(buf, 0)
    if got is None:
        return None
    value = got[1].get("store", "")
    return value if isinstance(value, str) else ""


def sync(fh: BinaryIO) -> None:
    """Make everything appended to `fh` durable (fsync)."""
    fh.flush()
    os.fsync(fh.fileno())


def is_ours(path: str | os.PathLike[str]) -> bool:
    """A journal: empty, or beginning with one of our records."""
    with open(path, "rb") as fh:
        lead = fh.read(len(MAGIC))
    return not lead or lead == MAGIC
