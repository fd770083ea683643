"""The store's schema, written once: its datasets, their dtypes, and how a new file is laid out.

One row per compression task (the grid, `campaign.config`): its parameters
(PARAMS, and its task kind's own: `campaign.kinds`), its results (RESULTS,
NaN until done, and its kind's own), `converged`, `state` (an
index into STATES), `attempts`, worker `rank`, `started_unix_s` and `error`
(fixed-length UTF-8 of ERROR_BYTES: parallel HDF5 cannot write
variable-length strings; the journal keeps a message whole); `task_id` and
`bending` are fixed-length ASCII.

The group `trials` holds the Monte-Carlo trials (`campaign.trials`): one
row per trial (cell), study j's N cells at rows j N .. j N + N - 1, with
the per-trial columns TRIAL_PER_CELL and (trial, height) arrays
TRIAL_PER_HEIGHT; their union, in that order, is TRIAL_COLUMNS, the long
table `campaign.store.reader.read_trials` returns. The schema imports no physics,
so the readers (and `cortex campaign status`) load neither numba nor the solver.
"""

from __future__ import annotations

import hashlib
import json
import math
import operator

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
import numpy.typing as npt

if TYPE_CHECKING:
    import h5py

    from campaign.grid import Grid
    from campaign.kinds import Kind
    from campaign.trials import Study
    from solver.model import Shell

FORMAT = "cortex-campaign-store"    # the file's `format` attribute: what says a file is ours
PARAMS = ("volume_um3", "h0_um", "dh_um", "bulk_mN_per_m", "shear_mN_per_m",
          "tension_mN_per_m", "thickness_um", "viscosity_Pa_s", "frequency_hz")   # NaN: elastic
RESULTS = ("force_nN", "active_force_nN", "gamma_eff_mN_per_m", "delta_gamma_mN_per_m",
           "area_strain", "area_strain_shell", "modulus_mN_per_m", "h_mean_um", "h_tilde",
           "volume_error", "equator_shear_ratio", "iterations", "wall_s",
           # a viscous cell's (solver.viscous; NaN for an elastic one)
           "compression_modulus_mN_per_m", "storage_modulus_mN_per_m", "loss_modulus_mN_per_m",
           "loss_angle_rad", "elastic_modulus_mN_per_m", "viscous_wall_s")
# a kind's own columns (`campaign.kinds`: the tables' in analysis) are the store's attributes
# `task_params` and `task_results` (JSON {column: unit}); a store made before kinds had them holds
# the protocol's parameter columns OLD_PARAMS and result columns of no other name (`_extra`)
OLD_PARAMS = ("bulk_exponent", "shear_exponent", "wait_s", "protocol_frequency_hz")
STATES = ("pending", "running", "done", "failed")
PENDING, RUNNING, DONE, FAILED = range(4)
CHECKSUM = "checksum"       # a done or failed row's checksum column (`campaign.store.checksum`)
PARAM_CHECKSUM = "param_checksum"   # every row's parameters' checksum, written with them (`fill`)
ERROR_BYTES = 256           # an error message's room in its row
# a trial task's results per cell (`campaign.trials.run_study`, beside `state` and `error`): one value,
# and one per height
CELL_KEYS = ("tension_mN_per_m", "volume_used_um3")
HEIGHT_KEYS = ("h0_used_um", "h1_used_um", "force_nN", "h_tilde", "modulus_mN_per_m",
               "gamma_eff_mN_per_m", "tension_seen_mN_per_m")
# the bookkeeping columns of a task row (and of a trial row), beside its parameters and results
BOOKKEEPING = {"state": np.int8, "attempts": np.int32, "rank": np.int32, "started_unix_s": float}
# trials: the study's parameters per trial (dataset <- Study attribute), then the columns of the long table
TRIAL_PARAMS = {"nu_true": "nu_true", "bulk_mN_per_m": "bulk_mN_per_m", "shear_mN_per_m": "shear_mN_per_m",
                "volume_true_um3": "volume_um3"}
TRIAL_PER_CELL = ("trial_id", "state", "nu_true", "bending", "height_error_mode", "study", "cell",
                  "bulk_mN_per_m", "shear_mN_per_m", "tension_mN_per_m", "volume_true_um3", "volume_used_um3")
TRIAL_PER_HEIGHT = ("h0_true_um", "h0_used_um", "h1_used_um", "h_tilde", "modulus_mN_per_m",
                    "gamma_eff_mN_per_m", "tension_seen_mN_per_m")
TRIAL_COLUMNS = TRIAL_PER_CELL + TRIAL_PER_HEIGHT


class StoredCampaign(Protocol):
    """What the store reads of a campaign (`campaign.config.Campaign`): its
    grid and trial tasks to lay out, its text and fingerprints to keep."""

    @property
    def name(self) -> str: ...
    @property
    def text(self) -> str: ...
    @property
    def method(self) -> str: ...
    @property
    def shells(self) -> Grid: ...
    @property
    def studies(self) -> tuple[Study, ...]: ...
    @property
    def trial_cells(self) -> int: ...
    @property
    def fingerprint(self) -> str: ...
    @property
    def trials_fingerprint(self) -> str: ...
    @property
    def kind(self) -> Kind: ...


_SORTED_JSON = json.JSONEncoder(sort_keys=True)    # json.dumps(..., sort_keys=True) without making one per call


def task_id(shell: Shell, method: str) -> str:
    """A task's id: a hash of its parameters (the text of json.dumps(...,
    sort_keys=True)), stable across runs."""
    key = _SORTED_JSON.encode({**shell.to_dict(), "method": method})
    return hashlib.sha256(key.encode()).hexdigest()[:16]


def task_ids(grid: Grid, method: str) -> list[str]:
    """`task_id` of every shell of `grid` (a `campaign.grid.Grid`), the same
    ids: each JSON text made from a template of the sorted keys with the
    values' texts (`Grid.texts`; json prints a float as its repr) instead of
    from a shell's dict: 10,000 ids in about 10 ms."""
    return list(_task_ids(grid, method))


def task_id_column(grid: Grid, method: str) -> np.ndarray:
    """`task_ids` as the store keeps them (16 ASCII bytes each), made one at a
    time: no list of a million strings (73 bytes a task) on the way."""
    return np.fromiter(_task_ids(grid, method), "S16", count=len(grid))


def _task_ids(grid, method):
    keys = sorted({**grid[0].to_dict(), "method": method})
    fields = [k for k in keys if k != "method"]
    own = json.dumps(method).replace("%", "%%")
    body = "{" + ", ".join(f"{json.dumps(k)}: {own if k == 'method' else '%s'}" for k in keys) + "}"
    return (hashlib.sha256(text.encode()).hexdigest()[:16] for text in grid.texts(body, fields, _json_value))


def _json_value(value):
    """`value` as json.dumps prints it: a finite float is its repr (the fast way)."""
    return repr(value) if type(value) is float and math.isfinite(value) else json.dumps(value)


def results_table(results: Sequence[Mapping[str, Any]], keys: Sequence[str]) -> npt.NDArray[np.float64]:
    """The values of `keys` in each of the dicts `results` as a float64 array
    (len(results), len(keys)), NaN where a dict lacks a key: what the journal
    and the rows take a batch's result columns from (one C-level pass when
    every dict has every key, as a solver's or a no-op's results do)."""
    get = operator.itemgetter(*keys) if keys else (lambda r: ())
    try:
        table = list(map(get, results))
    except KeyError:
        table = [[r.get(k, np.nan) for k in keys] for r in results]
    return np.array(table, np.float64).reshape(len(results), len(keys))


def trial_rows(task: int, cells: int, tasks: int = 1) -> range:
    """The rows of trial tasks `task` .. `task + tasks - 1`: study j's N = `cells`
    cells are rows j N .. j N + N - 1."""
    return range(task * cells, (task + tasks) * cells)


def error_dtype() -> np.dtype:
    """Error messages: fixed-length UTF-8 of ERROR_BYTES."""
    import h5py
    return h5py.string_dtype("utf-8", ERROR_BYTES)


def fixed_strings(values: Sequence[str]) -> np.ndarray:
    """Short ASCII names (task ids, bending variants) as a fixed-length byte
    array: read back a hundred times faster than variable-length strings."""
    return np.array(values, f"S{max(map(len, values), default=1)}")   # (ASCII: numpy refuses other text)


def clip(text: str) -> bytes:
    """`text` as at most ERROR_BYTES bytes of UTF-8, cut between characters."""
    return text.encode()[:ERROR_BYTES].decode(errors="ignore").encode()


def _bookkeeping(g, n):
    """The bookkeeping columns of `n` rows, each pending, never attempted."""
    for key, dtype in BOOKKEEPING.items():
        g[key] = np.full(n, {"rank": -1, "started_unix_s": np.nan}.get(key, 0), dtype)
    g.create_dataset("error", (n,), error_dtype(), dcpl=_allocated(), fill_time="alloc")   # HDF5 writes the
    # empty messages itself, a buffer at a time: no n x ERROR_BYTES array (256 MB at a million rows)
    g.create_dataset(CHECKSUM, (n,), np.uint64, dcpl=_allocated(), fill_time="alloc")   # zeros; set where
    # a row is written (`campaign.store.checksum`)


def _allocated():
    """A dataset-creation property list whose storage is allocated when the dataset is made (and its fill
    value written then): rows are later written in place, never growing the file."""
    import h5py
    dcpl = h5py.h5p.create(h5py.h5p.DATASET_CREATE)
    dcpl.set_alloc_time(h5py.h5d.ALLOC_TIME_EARLY)
    return dcpl


def fill(f: h5py.File, campaign: StoredCampaign, attrs: Mapping[str, Any]) -> None:
    """Lay out a new store in the open file `f`: every dataset at its final
    size, every row pending; `attrs` (provenance) and FORMAT as attributes."""
    from campaign.store.checksum import row_checksums
    n, params = len(campaign.shells), PARAMS + tuple(campaign.kind.params)
    columns = campaign.shells.columns()             # no shell made
    for key in params:
        f[key] = columns[key]
    sums = row_checksums([columns[key] for key in params])     # the parameters' part (`checksum.param_names`)
    f.create_dataset("bending", data=fixed_strings(columns["bending"]))
    del columns                                     # (at a million tasks 80 MB, not kept while the ids are made)
    f.create_dataset("task_id", data=task_id_column(campaign.shells, campaign.method))
    with np.errstate(over="ignore"):
        sums += row_checksums([f["bending"][:], f["task_id"][:]], first=len(params))
    f[PARAM_CHECKSUM] = sums
    for key in result_names(campaign):
        f.create_dataset(key, data=np.full(n, np.nan))
    f["converged"] = np.zeros(n, np.int8)
    _bookkeeping(f, n)
    if campaign.studies:
        fill_trials(f.create_group("trials"), campaign)
    kind = campaign.kind
    f.attrs.update(attrs, format=FORMAT, task_kind=kind.name, task_version=kind.version,
                   task_params=json.dumps(dict(kind.params)), task_results=json.dumps(dict(kind.results)))


def result_names(campaign: StoredCampaign) -> tuple[str, ...]:
    """The result columns of `campaign`'s rows: RESULTS, and its kind's own (`campaign.kinds.Kind.results`)."""
    return RESULTS + tuple(campaign.kind.results)


def stored_results(f: h5py.File | h5py.Group) -> tuple[str, ...]:
    """The result columns of the open store `f`: RESULTS and its kind's own (attribute `task_results`)."""
    if "task_results" in f.attrs:
        return RESULTS + tuple(json.loads(f.attrs["task_results"]))
    return RESULTS + tuple(k for k in _extra(f) if k not in OLD_PARAMS)


def stored_params(f: h5py.File | h5py.Group) -> tuple[str, ...]:
    """The parameter columns of the open store `f`: PARAMS and its kind's own (attribute `task_params`)."""
    if "task_params" in f.attrs:
        return PARAMS + tuple(json.loads(f.attrs["task_params"]))
    return PARAMS + tuple(k for k in OLD_PARAMS if k in f)


def _extra(f):
    """A store made before kinds: its float row columns that are neither PARAMS nor RESULTS nor bookkeeping."""
    n, known = len(f["state"]), set(PARAMS + RESULTS) | set(BOOKKEEPING) | {"converged", CHECKSUM, PARAM_CHECKSUM}
    return sorted(k for k, d in f.items() if k not in known and getattr(d, "shape", None) == (n,)
                  and d.dtype == np.float64)


def fill_trials(g: h5py.Group, campaign: StoredCampaign) -> None:
    """One row per trial: study j's cells are rows j N .. j N + N - 1."""
    import h5py
    studies, N = campaign.studies, campaign.trial_cells
    n, m = len(studies) * N, len(studies[0].heights_um)
    per = lambda attr: np.repeat([getattr(s, attr) for s in studies], N)  # noqa: E731
    str_t = h5py.string_dtype()
    g.create_dataset("trial_id", data=np.array([t for s in studies for t in s.trial_ids()], object),
                     dtype=str_t)
    g["task"] = np.repeat(np.arange(len(studies), dtype=np.int32), N)
    g["study"] = per("study").astype(np.int32)
    g["cell"] = np.tile(np.arange(N, dtype=np.int32), len(studies))
    for key in ("bending", "height_error_mode"):
        g.create_dataset(key, data=per(key).astype(object), dtype=str_t)
    for key, attr in TRIAL_PARAMS.items():
        g[key] = per(attr).astype(float)
    g["h0_true_um"] = np.repeat(np.array([s.heights_um for s in studies], float), N, axis=0)
    for key in CELL_KEYS:
        g.create_dataset(key, data=np.full(n, np.nan))
    for key in HEIGHT_KEYS:
        g.create_dataset(key, data=np.full((n, m), np.nan))
    _bookkeeping(g, n)
    from campaign.store.checksum import TRIAL_PARAM_COVERED, row_checksums
    g[PARAM_CHECKSUM] = row_checksums([g[key][:] for key in TRIAL_PARAM_COVERED])
    g.attrs["cells_per_study"] = N
