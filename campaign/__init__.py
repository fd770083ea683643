"""The campaign engine: campaign files, the task grid, the MPI master/worker
scheduler and the resumable HDF5 store.

Public API (imported on first use):

- `load(path)` -> `Campaign`: a campaign file, checked (its shells,
  studies, solver method).
- `run(campaign, store_path, ...)`: run or resume it under MPI (every rank
  calls it; the exit status is returned).
- `read_results(store)`, `read_trials(store)`: the store's compressions and
  Monte-Carlo trials as pandas DataFrames; `summary(store)`: counts, failures,
  throughput (what `cortex campaign status --json` prints);
  `read_provenance(store)`: what made it.
- `Kind`, `register(kind)`: a task kind, registered by the module that owns its
  compute function (`campaign.kinds`; a campaign file names it `task = "MODULE:NAME"`).

The store is a subpackage with a face of its own (`campaign.store`); what a
task is (a compression or a trial task, its key, number and entry) lives in
`campaign.task_key`.
"""

from typing import TYPE_CHECKING

from common.lazy_exports import lazy_exports

if TYPE_CHECKING:
    from campaign.config import Campaign, load
    from campaign.kinds import Kind, register
    from campaign.scheduler import run
    from campaign.store.reader import read_provenance, read_results, read_trials, summary

__all__, __getattr__, __dir__ = lazy_exports(__name__, {
    "load": "campaign.config", "Campaign": "campaign.config",
    "run": "campaign.scheduler", "Kind": "campaign.kinds", "register": "campaign.kinds",
    "read_results": "campaign.store.reader", "read_trials": "campaign.store.reader",
    "summary": "campaign.store.reader", "read_provenance": "campaign.store.reader",
})
