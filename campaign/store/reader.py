"""What analysis and `cortex campaign status` read from a store.

Every reader opens the file without HDF5's file locking and overlays the
journal's entries past the file's `journal_bytes` (what the rows do not hold
yet), so it also works while a campaign is running:

- `read_results`: one row per compression task (parameters, state, results);
- `read_trials`: the Monte-Carlo trial curves, one row per trial and height;
- `read_provenance`: what made the store;
- `summary`: counts by state, failures with their messages, throughput and
  ETA, from the state, start-time and wall-time columns and those the check
  reads (the task table is not built).

Error messages are read only for rows that can hold one (attempted and not
done): a done row's message is always empty.

Every reader checks the rows it reads against their checksums (`campaign.store.checksum`): a
damaged row (and a trial row) is read as pending, its results NaN, and said in one line on
stderr (`cortex campaign verify` lists them, `cortex campaign repair` rewrites them from the
journal); a row the journal overlays is taken from the journal. A row whose parameters fail their
checksum (`read_results` and `read_trials`, which read them) is read as pending, its parameters and
results NaN, said in one line (`repair` rewrites them from the campaign's grid). A store made
before rows had checksums is read unchecked.
"""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from campaign.store import checksum, journal
from campaign.store.rows import runs, trial_columns
from campaign.store.schema import (CHECKSUM, DONE, FAILED, PARAM_CHECKSUM, PARAMS, PENDING, STATES, stored_params, stored_results,
                                   TRIAL_PER_CELL, TRIAL_PER_HEIGHT, trial_rows)
from campaign.store.files import open_read, open_store
from campaign.task_key import split
from common.errors import InputError

if TYPE_CHECKING:
    import pandas as pd

_OVERLAY = {"state": "state", "attempts": "attempts", "rank": "rank", "error": "error",
            "started": "started_unix_s"}
_NOT_FLOAT = ("state", "attempts", "rank", "error", "converged")     # the task rows' other columns
FLOATS = "float columns"                # the key of `_task_columns`'s float block
_TRIAL_RUN = ("error", "attempts")      # after TRIAL_COLUMNS in `read_trials`: how its study's run went


def _task_columns(path, names):
    """The compression rows' columns `names` (any of the parameters, the results,
    started_unix_s, converged, rank, error; state and attempts always), journal
    overlaid. The float columns are rows of one array, `cols[FLOATS]` (so a
    DataFrame takes them without a copy)."""
    floats = [k for k in names if k not in _NOT_FLOAT]
    with open_store(path) as f:
        n = len(f["state"])
        block = np.empty((len(floats), n))
        for i, key in enumerate(floats):
            f[key].read_direct(block[i])
        cols = {k: f[k][:] for k in ("state", "attempts") + names if k not in floats and k != "error"}
        cols.update(zip(floats, block))
        cols[FLOATS] = block
        bad, results, params = _damaged_rows(f, cols), stored_results(f), stored_params(f)
        bad_params = _damaged_params(f, cols, params)
        if "error" in names:
            cols["error"] = _errors(f["error"], (cols["state"] != DONE) & (cols["attempts"] > 0))
        start = f.attrs.get("journal_bytes", 0)
    overlaid = set()
    for entry in split(journal.read(str(path) + ".journal", start))[0]:
        _overlay(cols, entry)
        overlaid.add(entry["row"])
    bad = np.array([i for i in bad.tolist() if i not in overlaid], np.int64)
    if len(bad):
        cols["state"][bad] = PENDING
        for key in results:
            if key in cols:
                cols[key][bad] = np.nan          # a row of the float block: the frame's column too
        if "converged" in cols:
            cols["converged"][bad] = False
        _say_damaged(path, "rows", bad)
    if len(bad_params):
        _as_pending(cols, bad_params, params + results)
        _say_damaged(path, "rows' parameters", bad_params, "the campaign's grid")
    return cols


def _damaged_params(f, cols, params):
    """The rows whose PARAM_CHECKSUM fails, if `cols` holds the parameters (else none checked)."""
    if PARAM_CHECKSUM not in f or not set(params) <= set(cols):
        return np.zeros(0, np.int64)
    return checksum.bad_params(lambda k: cols[k] if k in cols else f[k][:], checksum.param_names(params))


def _as_pending(cols, rows, floats):
    """Rows `rows` read as pending, their columns `floats` NaN."""
    cols["state"][rows] = PENDING
    for key in floats:
        if key in cols:
            cols[key][rows] = np.nan
    if "converged" in cols:
        cols["converged"][rows] = False


def _damaged_rows(f, cols):
    """The rows of the open store `f` whose checksum fails (none checked in a store without checksums);
    `cols`: the columns read already (the others are read here)."""
    if CHECKSUM not in f:
        return np.zeros(0, np.int64)
    names = checksum.task_names(stored_results(f))
    return checksum.damaged(lambda k: cols[k] if k in cols else f[k][:], names)


def _say_damaged(path, what, rows, source="the journal"):
    """One line on stderr: the damaged rows read as pending."""
    shown = ", ".join(map(str, rows[:5].tolist())) + (", ..." if len(rows) > 5 else "")
    print(f"{path}: {len(rows)} damaged {what} (checksum fails: {shown}) read as pending; "
          f"cortex campaign repair {path} rewrites them from {source}", file=sys.stderr, flush=True)


def _overlay(cols, entry):
    """One compression entry of the journal over the columns read from the rows."""
    i = entry["row"]
    for key, name in _OVERLAY.items():
        if name in cols:
            value = entry.get(key, "" if key == "error" else np.nan)
            cols[name][i] = STATES.index(value) if key == "state" else value
    results = entry.get("results") or {}
    for key, value in results.items():
        if key in cols and key not in _NOT_FLOAT:
            cols[key][i] = value
    if "converged" in cols:
        cols["converged"][i] = bool(results.get("converged", False))


def _errors(dset, wanted):
    """The messages of the rows `wanted` (bool mask), '' elsewhere, as an object array."""
    out = np.full(len(wanted), "", object)
    rows = np.flatnonzero(wanted)
    if len(rows) > len(wanted) // 8:              # many: one read of the whole column
        out[rows] = dset.asstr()[:][rows]
        return out
    for start, stop, part in (runs(rows) if len(rows) else []):
        out[rows[part]] = dset.asstr()[start:stop]
    return out


def _strings(dset, few=False):
    """A fixed-length ASCII string column as an object array of str. `few`: a
    column of a few distinct values (bending), decoded once each."""
    raw = dset[:]
    if few:
        names, index = np.unique(raw, return_inverse=True)
        return np.array([name.decode() for name in names], object)[index]
    return np.array(raw.astype(f"U{raw.dtype.itemsize}").tolist(), object)


def read_results(path: str | os.PathLike[str]) -> pd.DataFrame:
    """One row per compression task: parameters, state and results (NaN where
    not done; a table campaign's store also its task's, `stored_results`), with the
    journal of a running campaign overlaid."""
    import pandas as pd           # here: a campaign run need not load it
    with open_store(path) as f:
        ids, bending = _strings(f["task_id"]), _strings(f["bending"], few=True)
        results, params = stored_results(f), stored_params(f)
    cols = _task_columns(path, params + results + ("converged", "rank", "error"))
    frame = pd.DataFrame(cols[FLOATS].T, columns=list(params + results), copy=False)
    for i, (key, values) in enumerate((("task_id", ids), ("state", np.array(STATES, object)[cols["state"]]),
                                       ("bending", bending))):
        frame.insert(i, key, values)
    frame["converged"] = cols["converged"].astype(bool)
    frame["attempts"], frame["rank"], frame["error"] = cols["attempts"], cols["rank"], cols["error"]
    return frame


def _trial_arrays(path):
    """The trials group as a dict of arrays (None without one), journal overlaid."""
    import h5py
    with open_read(path) as f:
        if "trials" not in f:
            return None
        g = f["trials"]
        a = {key: (g[key].asstr()[:] if h5py.check_string_dtype(g[key].dtype) else g[key][:]) for key in g}
        N = int(g.attrs["cells_per_study"])
        start = f.attrs.get("journal_bytes", 0)
    bad = checksum.damaged(a.__getitem__, checksum.TRIAL_COVERED) if CHECKSUM in a else np.zeros(0, np.int64)
    bad_params = (checksum.bad_params(a.__getitem__, checksum.TRIAL_PARAM_COVERED) if PARAM_CHECKSUM in a
                  else np.zeros(0, np.int64))
    a["error"] = a["error"].astype(object)
    for e in split(journal.read(str(path) + ".journal", start))[1]:
        rows = trial_rows(e["task"], N)
        for key, values in trial_columns(e, N, a["h0_true_um"].shape[1]).items():
            a[key][rows.start:rows.stop] = values
        bad = bad[(bad < rows.start) | (bad >= rows.stop)]
    if len(bad):
        a["state"][bad] = PENDING
        for key in checksum.TRIAL_COVERED[4:]:
            a[key][bad] = np.nan
        _say_damaged(path, "trial rows", bad)
    if len(bad_params):
        _as_pending(a, bad_params, checksum.TRIAL_PARAM_COVERED[3:] + checksum.TRIAL_COVERED[4:])
        _say_damaged(path, "trial rows' parameters", bad_params, "the campaign's grid")
    return a


def read_trials(path: str | os.PathLike[str]) -> pd.DataFrame:
    """Monte-Carlo trial curves, long format: one row per trial and height with
    the columns TRIAL_COLUMNS (`campaign.store.schema`), then `error` and `attempts`
    (how often its study ran); empty, with those columns, for a store without
    trials. Values of trials not done are NaN."""
    import pandas as pd
    a = _trial_arrays(path)
    if a is None:
        return pd.DataFrame({c: [] for c in TRIAL_PER_CELL + TRIAL_PER_HEIGHT + _TRIAL_RUN})
    m = a["h0_true_um"].shape[1]
    a["state"] = np.array(STATES, object)[a["state"]]
    columns = {key: np.repeat(a[key], m) for key in TRIAL_PER_CELL}
    columns.update({key: a[key].ravel() for key in TRIAL_PER_HEIGHT})
    columns.update({key: np.repeat(a[key], m) for key in _TRIAL_RUN})
    return pd.DataFrame(columns)


def summary(path: str | os.PathLike[str], now: Callable[[], float] = time.time) -> dict[str, Any]:
    """Counts by state, failures with their messages, throughput and ETA;
    `now()` is the clock (Unix s) a running campaign's rate is taken up to."""
    cols = _task_columns(path, ("started_unix_s", "wall_s", "error", "rank"))
    state, started = cols["state"], cols["started_unix_s"]
    counts = np.bincount(state, minlength=len(STATES))
    left = int(len(state) - counts[DONE] - counts[FAILED])
    rate = None
    if counts[DONE] and np.isfinite(started).any():
        # a finished campaign's rate over its own span, a running one's up to now
        span = (now() if left else np.nanmax(started + np.nan_to_num(cols["wall_s"]))) - np.nanmin(started)
        rate = int(counts[DONE]) / span if span > 0 else None
    info = {"tasks": int(len(state)), **{s: int(counts[i]) for i, s in enumerate(STATES)},
            "failures": _failures(path, state, cols["error"]),
            "failed_tasks": failed_tasks(path, state, cols["rank"], cols["error"]), "tasks_per_s": rate,
            "eta_s": (left / rate) if rate else None}
    trials = _trial_states(path)
    if trials is not None:
        t_state, t_error = trials
        info["trials"] = {"trials": int(t_state.size),
                          **{s: int(np.sum(t_state == i)) for i, s in enumerate(STATES)},
                          "failures": sorted({e for e in t_error[t_state == FAILED]})[:10]}
    return info


def _failures(path, state, error):
    """[task_id, error] of every failed compression."""
    failed = np.flatnonzero(state == FAILED)
    if not len(failed):
        return []
    with open_store(path) as f:
        ids = _strings(f["task_id"])[failed]
    return [[str(t), str(error[i])] for t, i in zip(ids, failed)]


def failed_tasks(path: str | os.PathLike[str], state: np.ndarray, rank: np.ndarray, error: np.ndarray) -> list[dict[str, Any]]:
    """One dict per failed compression: task_id, row, its parameters (those
    not NaN, and bending), the rank that ran it, the host (from the message's
    '(rank R on HOST)' tail, None without one) and the error."""
    import re
    failed = np.flatnonzero(state == FAILED)
    if not len(failed):
        return []
    with open_store(path) as f:
        ids = _strings(f["task_id"])[failed]
        bending = _strings(f["bending"], few=True)[failed]
        params = {k: f[k][failed] for k in PARAMS if k in f}
    out = []
    for j, i in enumerate(failed):
        host = re.search(r"\(rank -?\d+ on ([^)]+)\)$", str(error[i]))
        out.append({"task_id": str(ids[j]), "row": int(i),
                    **{k: float(v[j]) for k, v in params.items() if np.isfinite(v[j])},
                    "bending": str(bending[j]), "rank": int(rank[i]), "host": host and host.group(1),
                    "error": str(error[i])})
    return out


def _trial_states(path):
    """(state, error) of every trial, journal overlaid; None for a store without trials."""
    with open_read(path) as f:
        if "trials" not in f:
            return None
    a = _trial_arrays(path)
    return a["state"], a["error"]


def read_provenance(path: str | os.PathLike[str]) -> dict[str, Any]:
    """What made a store: its campaign file's text, fingerprint, code and library
    versions, host and creation time (the attributes written when it was created)."""
    keys = ("name", "config_text", "fingerprint", "code_version", "versions", "host", "created")
    with open_read(path) as f:
        if "fingerprint" not in f.attrs:
            raise InputError(f"{path}: not a campaign store")
        out = {k: f.attrs[k] for k in keys if k in f.attrs}
    return {k: (v.decode() if isinstance(v, bytes) else v.item() if hasattr(v, "item") else v)
            for k, v in out.items()}
