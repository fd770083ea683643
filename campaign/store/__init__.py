"""The campaign store: one HDF5 file of task rows, the journal beside it, and
their readers (docs/store.md).

Public API (imported on first use):

- `Store(path, campaign, ...)`: rank 0's view of a store during a run (lock,
  check, create or rebuild, replay; `record`, `flush`, `close`, `abort`).
- `write_path(requested, ranks)`, `open_parallel(path, comm)`, `Writer`: the
  parallel (mpio) write path.
- `read_results(store)`, `read_trials(store)`, `read_provenance(store)`,
  `summary(store)`: what analysis and `cortex campaign status` read.
- `open_read(path)`, `is_our_store(path)`: a store opened read-only; whether a
  file is one of ours.
- `STATES` and `PENDING, RUNNING, DONE, FAILED`: a row's `state`.

Its modules, one job each: `schema` (the datasets, written once), `journal`
(the binary journal codec), `rows` (journal entries into rows), `store`
(`Store`), `mpio_writer`, `files` (which files are ours), `reader`,
`checksum` (the checksum a row carries), `verify` (damaged rows found and
rewritten from the journal), `provenance`.
"""

from typing import TYPE_CHECKING

from common.lazy_exports import lazy_exports

if TYPE_CHECKING:
    from campaign.store.files import is_our_store, open_read
    from campaign.store.mpio_writer import Writer, open_parallel, write_path
    from campaign.store.reader import read_provenance, read_results, read_trials, summary
    from campaign.store.schema import DONE, FAILED, PENDING, RUNNING, STATES
    from campaign.store.store import Store

__all__, __getattr__, __dir__ = lazy_exports(__name__, {
    "Store": "campaign.store.store",
    "write_path": "campaign.store.mpio_writer", "open_parallel": "campaign.store.mpio_writer",
    "Writer": "campaign.store.mpio_writer",
    "read_results": "campaign.store.reader", "read_trials": "campaign.store.reader",
    "read_provenance": "campaign.store.reader", "summary": "campaign.store.reader",
    "open_read": "campaign.store.files", "is_our_store": "campaign.store.files",
    **dict.fromkeys(("STATES", "PENDING", "RUNNING", "DONE", "FAILED"), "campaign.store.schema"),
})
