"""The parallel write path (h5py built with MPI, more than one rank).

Rank 0 prepares the file alone (`campaign.store.Store`: create, replay,
rebuild), then every rank opens it together with `driver="mpio"` and each
rank writes the rows of the tasks it computed, by independent writes of
contiguous runs into the preallocated datasets (no metadata changes, so
nothing collective happens but open and close). The journal stays the
record: a worker keeps its finished entries until rank 0 says how many of
them its fsync'd journal holds (`Writer.written_upto`), so rows still follow
the journal.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from campaign.store.rows import write_entries
from campaign.task_key import Entry
from common.errors import InputError

if TYPE_CHECKING:
    import h5py
    from mpi4py import MPI


def write_path(requested: str, size: int) -> str:
    """The write path for `size` ranks: 'mpio' or 'rank0' (`requested` 'auto'
    picks mpio where h5py has MPI and there is more than one rank)."""
    import h5py
    mpi = bool(h5py.get_config().mpi)
    if requested == "mpio" and not mpi:
        raise InputError("--write-path mpio: this h5py was built without MPI "
                         "(make setup-parallel builds .venv-mpio, which has it)")
    if requested == "auto":
        return "mpio" if mpi and size > 1 else "rank0"
    return requested


def open_parallel(path: str, comm: MPI.Comm) -> h5py.File:
    """The store opened by every rank of `comm` together (parallel HDF5)."""
    import h5py
    return h5py.File(path, "r+", driver="mpio", comm=comm)


class Writer:
    """A worker's side of the mpio path: its finished entries, written into
    its rows once rank 0's journal holds them (`written_upto`)."""

    def __init__(self, f: h5py.File):
        self.file, self.sent = f, 0
        self.entries: list[Entry] = []
        self.cells = int(f["trials"].attrs["cells_per_study"]) if "trials" in f else 0

    def keep(self, entry: Entry) -> None:
        self.entries.append(entry)
        self.sent += 1

    def written_upto(self, count: int) -> None:
        """Rank 0's journal holds this worker's first `count` entries: write those not yet written."""
        ready = len(self.entries) - (self.sent - count)
        write_entries(self.file, self.entries[:ready], self.cells, contiguous=True)
        del self.entries[:ready]

    def close(self) -> None:
        self.file.close()
