"""A reading's finished replays, kept in its output folder so that a stopped reading resumes
(docs/viscoelastic.md).

The protocol-aware reading (`analysis.afm.protocol_reading`) replays each cell in rounds, and the
laws of a round follow from the replays before it, deterministically: the same recordings read
again with the same options ask for the same replays in the same order. Each finished replay of
a cell (`analysis.afm.replayed.cell_replays`: one set of laws, at its memories, linearised or
full) is written to DIR/`replays`/KEY.npz as soon as it is back (`outputs.writing.write_atomically`:
a kill or a full disk leaves whole files or none), KEY the SHA-256 of all that determines it:

    the replay's code (the source of the `solver` and `analysis` packages), the cell's recording
    (id, volume, samples, segments, what the file recorded), its laws (their float bits),
    bending, wait, linearised or full, and the memories

A reading run again into the same DIR reads back what it finds instead of replaying it (`get`,
`read_back` counts them; summary.json's `protocol.replays_read_back`), so a reading stopped by a
kill, a job's time limit or a full disk goes on from its last finished replay, and ends with the
same files as one that was never stopped. A file that cannot be read (not ours, or damaged) is
replayed and written again. The folder stays after the reading (a second reading with other
options reuses what still applies); deleting it costs only the time to replay.
"""

from __future__ import annotations

import hashlib
import io
import json
import zipfile
from collections.abc import Sequence
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from analysis.afm.wait_relaxation import Waits
from common.errors import InputError
from outputs.writing import write_atomically

if TYPE_CHECKING:
    from analysis.afm.cell import Cell
    from analysis.afm.memory_fit import Node
    from outputs.ownership import OutputDir

NAME = "replays"          # the folder in the reading's output folder
Job = tuple["Cell", dict[str, float], str, "float | None", bool, Sequence["Node"]]   # `cell_replays`' arguments
Replays = tuple[dict["Node", "np.ndarray | str"], "Waits | None"]                     # ... and its result


@lru_cache(maxsize=1)
def code_digest() -> str:
    """SHA-256 of the source of the `solver` and `analysis` packages: a replay's code."""
    import analysis
    import solver
    h = hashlib.sha256()
    for package in (solver, analysis):
        root = Path(next(iter(package.__path__)))
        for path in sorted(root.rglob("*.py")):
            h.update(str(path.relative_to(root.parent)).encode() + b"\0" + path.read_bytes() + b"\0")
    return h.hexdigest()


def _number(x: object) -> str:
    """A value as text, a number by its float bits."""
    if x is None:
        return "none"
    return float(x).hex() if isinstance(x, (int, float, np.floating, np.integer)) else str(x)


def recording_digest(cell: Cell) -> str:
    """SHA-256 of what a replay reads of `cell`: its id, volume, samples, segments and record."""
    h = hashlib.sha256()
    h.update(json.dumps([cell.cell_id, _number(cell.volume_um3), cell.dish_known, cell.timed,
                         [[s.kind, s.start, s.stop, _number(s.frequency_hz), _number(s.amplitude_um)]
                          for s in cell.segments], cell.recorded], sort_keys=True, default=str).encode())
    for a in (cell.time_s, cell.force_nN, cell.height_um):
        h.update(np.ascontiguousarray(a, np.float64).tobytes())
    return h.hexdigest()


def _memory(m: Node) -> str:
    return m if isinstance(m, str) else _number(m)


def key(job: Job, recording: str) -> str:
    """The file name (no suffix) of `job`'s replays (`analysis.afm.protocol_reading._one`'s
    arguments), `recording` its cell's `recording_digest` (module docstring)."""
    _, law, bending, wait_s, linearised, memories = job
    text = json.dumps([code_digest(), recording, sorted((k, _number(v)) for k, v in law.items()), bending,
                       _number(wait_s), bool(linearised), [_memory(m) for m in memories]])
    return hashlib.sha256(text.encode()).hexdigest()


def encoded(result: Replays, memories: Sequence[Node]) -> bytes:
    """The .npz bytes of one job's result (its memories in `memories`' order)."""
    factors, waits = result
    arrays: dict[str, np.ndarray] = {}
    for i, m in enumerate(memories):
        f = factors[m]
        arrays[f"why{i}" if isinstance(f, str) else f"f{i}"] = np.array(f) if isinstance(f, str) else np.asarray(f, np.float64)
    if waits is not None:
        arrays.update(w_time=waits.time_s, w_force=waits.force_nN, w_wait=np.asarray(waits.wait, np.int64),
                      w_used=np.asarray(waits.used, np.int64))
        arrays.update({f"wm{i}": waits.model[m] for i, m in enumerate(memories) if m in waits.model})
    buf = io.BytesIO()
    np.savez(buf, allow_pickle=False, **arrays)
    return buf.getvalue()


def decoded(data: bytes, memories: Sequence[Node]) -> Replays:
    """One job's result from `encoded`'s bytes; ValueError (or KeyError) if they are not one."""
    with np.load(io.BytesIO(data), allow_pickle=False) as z:
        factors: dict[Node, np.ndarray | str] = {}
        for i, m in enumerate(memories):
            factors[m] = str(z[f"why{i}"]) if f"why{i}" in z.files else np.array(z[f"f{i}"], np.float64)
        if "w_time" not in z.files:
            return factors, None
        model = {m: np.array(z[f"wm{i}"]) for i, m in enumerate(memories) if f"wm{i}" in z.files}
        return factors, Waits(np.array(z["w_time"]), np.array(z["w_force"]), np.array(z["w_wait"]),
                              tuple(int(k) for k in z["w_used"]), model)


class ReplayStore:
    """DIR/`replays`: `get` a job's result if a reading wrote it, `put` one just replayed."""

    def __init__(self, out: OutputDir) -> None:
        self.path = out.claim(NAME)
        if self.path.exists() and (self.path.is_symlink() or not self.path.is_dir()):
            raise InputError(f"{out.what} {out.path}: {NAME} is there and is not the folder of replays "
                             "cortex writes; it is left as it is (choose another folder)")
        self.path.mkdir(exist_ok=True)
        self.read_back = 0
        self._recordings: dict[str, str] = {}

    def _file(self, job: Job) -> Path:
        cell = job[0]
        if cell.cell_id not in self._recordings:
            self._recordings[cell.cell_id] = recording_digest(cell)
        return self.path / f"{key(job, self._recordings[cell.cell_id])}.npz"

    def get(self, job: Job) -> Replays | None:
        """`job`'s result as a reading wrote it, or None (not there, or not readable)."""
        path = self._file(job)
        try:
            got = decoded(path.read_bytes(), job[5])
        except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile):
            return None
        self.read_back += 1
        return got

    def put(self, job: Job, result: Replays) -> None:
        """Write `job`'s result (a full disk: WriteError, the files before it whole)."""
        write_atomically(self._file(job), encoded(result, job[5]))

