"""The store's schema, written once: its datasets, their dtypes, and how a new file is laid out.

One row per compression task (the grid, `campaign.config`): its parameters
(PARAMS), its results (RESULTS, NaN until done; a viscoelastic-table
campaign's rows also TABLE_RESULTS, the node's coefficients, a ramp-table
campaign's RAMP_RESULTS, the node's forces), `converged`, `state` (an
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
# a viscoelastic-table node's results instead (`[campaign] task = "viscoelastic_table"`,
# `analysis.calibration.viscoelastic_table`; their datasets only in such a store): the complex coefficients
# of ln C's polynomial in the loss angles, the real and the imaginary part of the term
# δ_B^i δ_S^j (0 < i + j <= TABLE_DEGREE) as ln_c_re_b{i}_s{j} and ln_c_im_b{i}_s{j} (dimensionless)
TABLE_DEGREE = 4
TABLE_TERMS = tuple((i, j) for i in range(TABLE_DEGREE + 1) for j in range(TABLE_DEGREE + 1 - i) if i + j > 0)
TABLE_RESULTS = tuple(f"ln_c_{part}_b{i}_s{j}" for part in ("re", "im") for i, j in TABLE_TERMS)
# a shell-ramp-table node's results instead (`[campaign] task = "ramp_table"`,
# `analysis.afm.tension.shell_table`; their datasets only in such a store): F/(K_B R) at each of the
# table's RAMP_DEPTHS depths δ/R as force_over_kb_r_d{i:02d} (dimensionless, a stalled depth filled
# along depth), and `filled_depths`, how many were filled
RAMP_DEPTHS = 48
RAMP_RESULTS = tuple(f"force_over_kb_r_d{i:02d}" for i in range(RAMP_DEPTHS)) + ("filled_depths",)
# a protocol-bias node's (`[campaign] task = "protocol_bias"`, `campaign.protocol_grid`,
# `analysis.afm.synth.protocol_bias`; their datasets only in such a store): its protocol as parameters
# PROTOCOL_PARAMS, and beside RESULTS' modulus_mN_per_m, loss_angle_rad (the segment fit's),
# gamma_eff_mN_per_m (its mean γ_eff), h_tilde, h_mean_um and wall_s the results PROTOCOL_RESULTS
PROTOCOL_PARAMS = ("bulk_exponent", "shear_exponent", "wait_s", "protocol_frequency_hz")
PROTOCOL_RESULTS = ("model_modulus_mN_per_m", "model_loss_angle_rad", "bulk_loss_angle_rad",
                    "shear_loss_angle_rad", "modulus_ratio", "loss_angle_error_rad", "solves")
TASK_RESULTS = {"compression": (), "viscoelastic_table": TABLE_RESULTS, "ramp_table": RAMP_RESULTS,
                "protocol_bias": PROTOCOL_RESULTS}
ALL_RESULTS = RESULTS + TABLE_RESULTS + RAMP_RESULTS + PROTOCOL_RESULTS   # what a journal record or a row may hold
STATES = ("pending", "running", "done", "failed")
PENDING, RUNNING, DONE, FAILED = range(4)
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
    n = len(campaign.shells)
    columns = campaign.shells.columns()             # no shell made
    for key in PARAMS + PROTOCOL_PARAMS:
        if key in columns:              # PROTOCOL_PARAMS: a protocol-bias campaign's alone
            f[key] = columns[key]
    f.create_dataset("bending", data=fixed_strings(columns["bending"]))
    del columns                                     # (at a million tasks 80 MB, not kept while the ids are made)
    f.create_dataset("task_id", data=task_id_column(campaign.shells, campaign.method))
    for key in result_names(campaign):
        f.create_dataset(key, data=np.full(n, np.nan))
    f["converged"] = np.zeros(n, np.int8)
    _bookkeeping(f, n)
    if campaign.studies:
        fill_trials(f.create_group("trials"), campaign)
    f.attrs.update(attrs, format=FORMAT)


def result_names(campaign: StoredCampaign) -> tuple[str, ...]:
    """The result columns of `campaign`'s rows: RESULTS, and its task's own
    (TASK_RESULTS: TABLE_RESULTS, RAMP_RESULTS) for a table campaign (`campaign.config.TASKS`)."""
    return RESULTS + TASK_RESULTS[getattr(campaign, "task", "compression")]


def stored_results(f: h5py.File | h5py.Group) -> tuple[str, ...]:
    """The result columns of the open store `f`: RESULTS and the task's own its rows hold."""
    return RESULTS + next((own for own in TASK_RESULTS.values() if own and own[0] in f), ())


def stored_params(f: h5py.File | h5py.Group) -> tuple[str, ...]:
    """The parameter columns of the open store `f`: PARAMS, and PROTOCOL_PARAMS in a protocol-bias store."""
    return PARAMS + (PROTOCOL_PARAMS if PROTOCOL_PARAMS[0] in f else ())


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
    g.attrs["cells_per_study"] = N
