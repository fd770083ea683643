"""The campaign store: one HDF5 file, one row per task, plus its journal.

Every dataset is created up front at its final size; a task's parameters,
state (pending, running, done, failed), attempts, worker rank, timings, error
message and results live in its own row. Attributes keep the campaign file's
text, its fingerprint, the code and library versions, host and ranks.
Monte-Carlo trials (`campaign.trials`) live in the group `trials`: one row
per trial (cell) with its study's parameters, its own state, attempts, rank,
start time, error and draws, and (trial, height) arrays of its curve; a
study (one trial task) writes its N consecutive rows at once. The attribute
`trials_fingerprint` identifies them: a store made without trials gains them
when the campaign file gets a [montecarlo] section (its compressions kept);
one with other trials is refused.

Kill safety: each finished task is first appended to `STORE.journal` (one
JSON line, fsync'd in batches; a trial task's arrays as base64 of their
float64 bytes, `_encode`) and then written into the HDF5 rows; the HDF5
file is flushed after each batch. On opening, the journal is replayed into
the file (idempotent), rows left `running` become `pending` again, and a file
that a kill left unreadable is set aside and rebuilt from the campaign and the
journal. So a rerun finishes the remaining tasks and ends with the same rows as
an uninterrupted run. A lock file refuses a second run on the same store.

Only a file that is ours is ever opened for writing, set aside or rebuilt
(`check_store_path`, the rule of `outputs.ownership`): our `format`
attribute, or, unreadable, our journal and lock beside it. A full disk never
reaches HDF5 while it grows the file (HDF5 then crashes): new files are built
in memory and written by Python, growth waits for `ensure_room`, rows are
written in place (`outputs.writing`); a failed journal write is a WriteError
naming the journal, and `abort` closes without writing more.

Two write paths, one schema and the same rows (`write_path`):
- rank0: rank 0 alone has the file open and writes every row, as above;
- mpio (h5py built with MPI, more than one rank): rank 0 prepares the file
  alone (create, replay, rebuild), then every rank opens it together with
  `driver="mpio"`, and each rank writes the rows of the tasks it computed,
  by independent writes of contiguous runs into the preallocated datasets
  (no metadata changes, so nothing collective happens but open and close).
  The journal stays the record: a worker keeps its finished entries until
  rank 0 says how many of them its fsync'd journal holds (`Writer`), so rows
  still follow the journal. `journal_bytes` is set when the run closes.
Readers (`read_results`, `read_trials`, `summary`) open the file without
HDF5's file locking and overlay the journal, so they also work while a
campaign is running. The file's attribute `journal_bytes` (set after each
batch's rows are flushed) says how much of the journal the rows already hold:
readers and the replay parse only the rest.
"""

import base64
import contextlib
import fcntl
import json
import os
import platform
import shutil
import socket
import time

import numpy as np

from campaign import faults
from campaign.trials import CELL_KEYS, HEIGHT_KEYS
from outputs.ownership import check_file, hdf5_format
from outputs.writing import ensure_room, hdf5_image, named_failures, write_atomically
from solver.errors import InputError

PARAMS = ("volume_um3", "h0_um", "dh_um", "bulk_mN_per_m", "shear_mN_per_m",
          "tension_mN_per_m", "thickness_um", "viscosity_Pa_s", "frequency_hz")   # NaN: elastic
RESULTS = ("force_nN", "active_force_nN", "gamma_eff_mN_per_m", "delta_gamma_mN_per_m",
           "area_strain", "area_strain_shell", "modulus_mN_per_m", "h_mean_um", "h_tilde",
           "volume_error", "equator_shear_ratio", "iterations", "wall_s",
           # a viscous cell's (solver.viscous; NaN for an elastic one)
           "compression_modulus_mN_per_m", "storage_modulus_mN_per_m", "loss_modulus_mN_per_m",
           "loss_angle_rad", "elastic_modulus_mN_per_m", "viscous_wall_s")
STATES = ("pending", "running", "done", "failed")
PENDING, RUNNING, DONE, FAILED = range(4)
ERROR_BYTES = 256           # an error message's room in its row
TRIAL_COLUMNS = ("trial_id", "state", "nu_true", "bending", "height_error_mode", "study", "cell",
                 "bulk_mN_per_m", "shear_mN_per_m", "tension_mN_per_m", "volume_true_um3",
                 "volume_used_um3", "h0_true_um", "h0_used_um", "h1_used_um", "h_tilde",
                 "modulus_mN_per_m", "gamma_eff_mN_per_m", "tension_seen_mN_per_m")
TRIAL_PARAMS = ("nu_true", "bulk_mN_per_m", "shear_mN_per_m", "volume_true_um3")
FORMAT = "cortex-campaign-store"    # the file's `format` attribute: what says a file is ours


def is_our_store(path):
    """A campaign store: an HDF5 file with our `format` attribute (or, made
    before it had one, our fingerprint and state rows); or a file a kill left
    unreadable with our journal and lock beside it."""
    path = str(path)
    if hdf5_format(path) == FORMAT:
        return True
    try:
        with _open_read(path) as f:
            return "fingerprint" in f.attrs and "config_text" in f.attrs and "state" in f
    except InputError:
        return os.path.isfile(path + ".lock") and os.path.isfile(path + ".journal") \
            and is_our_journal(path + ".journal")


def is_our_journal(path):
    """A journal: empty, or its first line one of our entries (a compression's
    `row` or a trial task's `task`, with its `state`)."""
    with open(path, "rb") as fh:
        first = fh.readline()
    if not first:
        return True
    try:
        entry = json.loads(first)
    except (json.JSONDecodeError, UnicodeDecodeError):
        return False
    return isinstance(entry, dict) and "state" in entry and ("row" in entry or "task" in entry)


def check_store_path(path):
    """Refuse (InputError) a --store that is a folder or a file that is not ours,
    or whose journal is not ours; they are left as they are."""
    check_file(path, is_our_store, "--store")
    check_file(path + ".journal", is_our_journal, "--store's journal")


def task_id(shell, method):
    """A task's id: a hash of its parameters, stable across runs."""
    import hashlib
    key = json.dumps({**shell.to_dict(), "method": method}, sort_keys=True)
    return hashlib.sha256(key.encode()).hexdigest()[:16]


def _h5():
    import h5py
    return h5py


def _open_read(path):
    h5py = _h5()
    if not os.path.exists(path):
        raise InputError(f"{path}: no such store")
    try:
        try:
            return h5py.File(path, "r", locking=False)
        except TypeError:
            return h5py.File(path, "r")
    except OSError as err:
        raise InputError(f"{path}: not a readable HDF5 store ({err})") from None


def write_path(requested, size):
    """The write path for `size` ranks: 'mpio' or 'rank0' (`requested` 'auto'
    picks mpio where h5py has MPI and there is more than one rank)."""
    mpi = bool(_h5().get_config().mpi)
    if requested == "mpio" and not mpi:
        raise InputError("--write-path mpio: this h5py was built without MPI "
                         "(make setup-parallel builds .venv-mpio, which has it)")
    if requested == "auto":
        return "mpio" if mpi and size > 1 else "rank0"
    return requested


def open_parallel(path, comm):
    """The store opened by every rank of `comm` together (parallel HDF5)."""
    return _h5().File(path, "r+", driver="mpio", comm=comm)


class Store:
    """Rank 0's view of a store: the journal, and the rows (all of them on the
    rank0 path; on the mpio path rank 0's own, through `attach`)."""

    def __init__(self, path, campaign, new=False, ranks=1, parallel=False):
        self.path, self.journal_path = str(path), str(path) + ".journal"
        check_store_path(self.path)               # before anything is created beside it
        self.lock = open(str(path) + ".lock", "a")
        try:
            fcntl.flock(self.lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise InputError(f"{path} is in use by another campaign run (lock {path}.lock)") from None
        if os.path.exists(self.path) and not new:
            self._check_same(campaign)
        if new:
            self._backup()
        if not os.path.exists(self.path):
            self._create(campaign, ranks)
        self.file = self._open_or_rebuild(campaign, ranks)
        try:
            self._prepare(campaign, ranks, parallel)
        except BaseException:
            self.file.close()                     # a refusal or a full disk: nothing more is written
            self._unlock()
            raise

    def _prepare(self, campaign, ranks, parallel):
        """Trials added, journal replayed, rows left running pending again, this run logged."""
        path = self.path
        self._add_trials(campaign)
        if parallel and any(name in self.file and self.file[name].dtype.kind == "O"
                            for name in ("error", "trials/error")):
            raise InputError(f"{path} was made by an earlier version (variable-length error strings, which "
                             "parallel HDF5 cannot write): use --write-path rank0, or --new")
        self.parallel = parallel
        self.cells = int(self.file["trials"].attrs["cells_per_study"]) if "trials" in self.file else 0
        _trim_cut_line(self.journal_path)
        self._replay()
        for name in ("state", "trials/state"):
            if name in self.file:
                state = self.file[name][:]
                state[state == RUNNING] = PENDING
                self.file[name][:] = state
        self.journal = open(self.journal_path, "a")
        self._log_run(ranks)
        self.buffer, self.running, self.shown_running, self.unsynced = [], set(), set(), False
        self.file.flush()

    def _log_run(self, ranks):
        """Provenance of this run (appended to the JSON list `runs`); the rows
        hold the whole journal now (replayed)."""
        ensure_room(self.path, 0)                     # the attribute may grow the file
        runs = json.loads(self.file.attrs.get("runs", "[]"))
        runs.append({"started": time.strftime("%Y-%m-%dT%H:%M:%S"), "ranks": ranks, "host": socket.gethostname(),
                     "write_path": "mpio" if self.parallel else "rank0", "code_version": _code_version()})
        self.file.attrs.update(runs=json.dumps(runs), journal_bytes=self.journal.tell())

    def attach(self, parallel_file):
        """mpio path: swap the file rank 0 prepared alone for the one all ranks opened."""
        self.file.close()
        self.file = parallel_file

    # -- opening -----------------------------------------------------------
    def _check_same(self, campaign):
        try:
            with _open_read(self.path) as f:
                fingerprint, trials = f.attrs.get("fingerprint"), f.attrs.get("trials_fingerprint", "")
        except InputError:
            return            # unreadable: rebuilt from the journal below
        if fingerprint != campaign.fingerprint:
            raise InputError(f"{self.path} was made from a different campaign file; "
                             "use --new to start over (the old store is kept as a backup)")
        if trials not in ("", campaign.trials_fingerprint):
            raise InputError(f"{self.path} holds Monte-Carlo trials of a different [montecarlo] section; "
                             "use --new to start over (the old store is kept as a backup)")

    def _add_trials(self, campaign):
        """A store made without trials gains the campaign's (its compressions are kept).
        The fingerprint is set last: a group a kill left half made is made again."""
        f = self.file
        if not campaign.studies or f.attrs.get("trials_fingerprint", "") == campaign.trials_fingerprint:
            return
        image = hdf5_image(lambda g: self._create_trials(g.create_group("trials"), campaign))
        ensure_room(self.path, len(image))            # HDF5 grows the file: never into a full disk
        if "trials" in f:
            del f["trials"]
        self._create_trials(f.create_group("trials"), campaign)
        f.flush()
        f.attrs.update(config_text=campaign.text, trials_fingerprint=campaign.trials_fingerprint)
        f.flush()

    def _backup(self):
        stamp = time.strftime("%Y%m%d-%H%M%S")
        for p in (self.path, self.journal_path):
            if os.path.exists(p):
                _set_aside(p, f"{p}.bak-{stamp}")

    def _create(self, campaign, ranks):
        """The new file, built in memory and written by Python (`outputs.writing`)."""
        write_atomically(self.path, hdf5_image(lambda f: self._fill(f, campaign, ranks)))

    def _fill(self, f, campaign, ranks):
        h5py = _h5()
        n = len(campaign.shells)
        for key in PARAMS:
            f[key] = np.array([getattr(s, key) for s in campaign.shells], float)
        str_t = h5py.string_dtype()
        f.create_dataset("bending", data=np.array([s.bending for s in campaign.shells], object), dtype=str_t)
        f.create_dataset("task_id", data=np.array([task_id(s, campaign.method) for s in campaign.shells],
                                                  object), dtype=str_t)
        for key in RESULTS:
            f.create_dataset(key, data=np.full(n, np.nan))
        f["converged"] = np.zeros(n, np.int8)
        f["state"] = np.zeros(n, np.int8)
        f["attempts"] = np.zeros(n, np.int32)
        f["rank"] = np.full(n, -1, np.int32)
        f["started_unix_s"] = np.full(n, np.nan)
        f.create_dataset("error", data=np.zeros(n, _error_dtype()), dtype=_error_dtype())
        if campaign.studies:
            self._create_trials(f.create_group("trials"), campaign)
        f.attrs.update(self._provenance(campaign, ranks), format=FORMAT)

    @staticmethod
    def _create_trials(g, campaign):
        """One row per trial: study j's cells are rows j N .. j N + N - 1."""
        h5py = _h5()
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
        for key, attr in zip(TRIAL_PARAMS, ("nu_true", "bulk_mN_per_m", "shear_mN_per_m", "volume_um3")):
            g[key] = per(attr).astype(float)
        g["h0_true_um"] = np.repeat(np.array([s.heights_um for s in studies], float), N, axis=0)
        for key in CELL_KEYS:
            g.create_dataset(key, data=np.full(n, np.nan))
        for key in HEIGHT_KEYS:
            g.create_dataset(key, data=np.full((n, m), np.nan))
        g["state"] = np.zeros(n, np.int8)
        g["attempts"] = np.zeros(n, np.int32)
        g["rank"] = np.full(n, -1, np.int32)
        g["started_unix_s"] = np.full(n, np.nan)
        g.create_dataset("error", data=np.zeros(n, _error_dtype()), dtype=_error_dtype())
        g.attrs["cells_per_study"] = N

    @staticmethod
    def _provenance(campaign, ranks):
        import h5py
        import mpi4py
        import numpy
        import scipy
        return {"fingerprint": campaign.fingerprint, "trials_fingerprint": campaign.trials_fingerprint,
                "config_text": campaign.text,
                "name": campaign.name, "method": campaign.method, "code_version": _code_version(),
                "versions": json.dumps({"python": platform.python_version(), "numpy": numpy.__version__,
                                        "scipy": scipy.__version__, "h5py": h5py.version.version,
                                        "hdf5": h5py.version.hdf5_version, "mpi4py": mpi4py.__version__}),
                "host": socket.gethostname(), "ranks": ranks,
                "created": time.strftime("%Y-%m-%dT%H:%M:%S")}

    def _open_or_rebuild(self, campaign, ranks):
        h5py = _h5()
        try:
            f = h5py.File(self.path, "r+")
            f["state"][:1]
            return f
        except (OSError, KeyError):
            aside = _set_aside(self.path, f"{self.path}.unreadable-{time.strftime('%Y%m%d-%H%M%S')}")
            print(f"campaign: {self.path} was left unreadable (kept as {aside}); "
                  "rebuilding it from the journal", flush=True)
            self._create(campaign, ranks)
            return h5py.File(self.path, "r+")

    def _replay(self):
        self._write_rows(read_journal(self.journal_path, self.file.attrs.get("journal_bytes", 0)))

    # -- writing -----------------------------------------------------------
    def _write_rows(self, entries):
        write_entries(self.file, entries, self.cells, contiguous=self.parallel)

    def state(self):
        return self.file["state"][:]

    def trial_state(self):
        """Per trial task (study): the states of its N trials, shape (tasks, N)."""
        return self.file["trials/state"][:].reshape(-1, self.cells) if self.cells else np.zeros((0, 0))

    def trial_attempts(self):
        """Per trial task: its attempts so far."""
        return self.file["trials/attempts"][::self.cells] if self.cells else np.zeros(0, np.int32)

    def compressions(self):
        """(force_nN, state, error) of every compression, for the trials."""
        return self.file["force_nN"][:], self.file["state"][:], list(self.file["error"].asstr()[:])

    def attempts(self):
        return self.file["attempts"][:]

    def mark_running(self, rows):
        """Shown as running from the next flush on (the journal never holds `running`).
        A row is a compression's index, or ("task", j) for trial task j."""
        self.running.update(r if isinstance(r, tuple) else int(r) for r in rows)

    def record(self, entry):
        """Journal first; the HDF5 rows follow in batches, after the journal's fsync (`flush`)."""
        with named_failures(self.journal_path):
            self.journal.write(json.dumps(entry, default=_encode) + "\n")
        self.unsynced = True
        if not self.parallel or entry["rank"] == 0:
            self.buffer.append(entry)
        self.running.discard(entry["row"] if "row" in entry else ("task", entry["task"]))
        faults.kill_mid_write(self, entry)        # tests only

    def flush(self):
        """fsync the journal, then write the buffered rows and the new running
        marks into HDF5 (a row that was shown running and is no longer has been
        finished: its entry is written). On the mpio path the buffer holds only
        rank 0's own entries, and nothing collective happens."""
        if self.unsynced:
            with named_failures(self.journal_path):
                self.journal.flush()
                os.fsync(self.journal.fileno())
            self.unsynced = False
        if self.buffer:
            self._write_rows(self.buffer)
            self.buffer = []
            if not self.parallel:
                self.file.flush()             # the rows first, then the mark that they are in
                self.file.attrs["journal_bytes"] = self.journal.tell()
        new = self.running - self.shown_running
        rows = sorted(r for r in new if not isinstance(r, tuple))
        trials = sorted(i for r in new if isinstance(r, tuple)
                        for i in range(r[1] * self.cells, r[1] * self.cells + self.cells))
        for name, marks in (("state", rows), ("trials/state", trials)):
            if marks:
                _put(self.file[name], np.array(marks), np.full(len(marks), RUNNING, np.int8), self.parallel)
        self.shown_running = set(self.running)
        if not self.parallel:
            self.file.flush()

    def close(self):
        """Write what is left and close; on the mpio path every rank closes the
        file together, then rank 0 notes that the rows hold the whole journal."""
        self.flush()
        self.file.close()
        if self.parallel:
            with _h5().File(self.path, "r+") as f:
                f.attrs["journal_bytes"] = self.journal.tell()
        self.journal.close()
        self._unlock()

    def abort(self):
        """After a failed write: close without writing anything more. The rows
        hold what the journal held at the last flush, the journal what was
        fsync'd (a line a full disk cut is trimmed on the next open), so the
        rerun replays it and resumes. On the mpio path every rank closes the
        file together, as in `close`."""
        self.file.close()
        with contextlib.suppress(OSError):
            self.journal.close()                   # what it still buffers may not fit
        self._unlock()

    def _unlock(self):
        fcntl.flock(self.lock, fcntl.LOCK_UN)
        self.lock.close()


def write_entries(f, entries, cells, contiguous=False):
    """Write journal entries into their rows of the open file `f` (the one place
    rows are written): compressions (`row`) one HDF5 write per column (per run
    of consecutive rows if `contiguous`: the mpio path writes no scattered
    selections), trial tasks (`task`) one slice of N = `cells` rows per column
    and run of consecutive tasks; the last entry of a row wins."""
    _write_trials(f, {e["task"]: e for e in entries if "task" in e}, cells)
    by_row = {e["row"]: e for e in entries if "row" in e}
    if not by_row:
        return
    rows = np.array(sorted(by_row))
    batch = [by_row[i] for i in rows]
    results = [e.get("results", {}) for e in batch]
    columns = {
        "state": np.array([STATES.index(e["state"]) for e in batch], np.int8),
        "attempts": np.array([e["attempts"] for e in batch], np.int32),
        "rank": np.array([e["rank"] for e in batch], np.int32),
        "error": np.array([e.get("error", "") for e in batch], object),
        "converged": np.array([int(bool(r.get("converged", False))) for r in results], np.int8),
        "started_unix_s": np.array([e.get("started", np.nan) for e in batch], float)}
    for key in RESULTS:
        if key in f:                      # a store made before the viscous columns lacks them
            columns[key] = np.array([r.get(key, np.nan) for r in results], float)
    for key, values in columns.items():
        _put(f[key], rows, values, contiguous)


def _runs(rows):
    """Sorted row numbers as (start, stop, index range) of consecutive runs."""
    cuts = np.flatnonzero(np.diff(rows) != 1) + 1
    starts, stops = np.r_[0, cuts], np.r_[cuts, len(rows)]
    return [(int(rows[a]), int(rows[b - 1]) + 1, slice(a, b)) for a, b in zip(starts, stops)]


def _fit(dset, values):
    """`values` as `dset` stores them (error messages clipped to fixed length)."""
    return np.array([_clip(v) for v in values], dset.dtype) if dset.dtype.kind == "S" else values


def _put(dset, rows, values, contiguous):
    values = _fit(dset, values)
    if not contiguous:
        dset[rows] = values
        return
    for start, stop, part in _runs(rows):
        dset[start:stop] = values[part]


def _write_trials(f, by_task, N):
    """Trial tasks' entries (`_trial_columns`), one slice write per column
    for each run of consecutive tasks."""
    if not by_task:
        return
    g = f["trials"]
    tasks = np.array(sorted(by_task))
    for start, stop, _ in _runs(tasks):
        parts = [_trial_columns(by_task[t], N, g["h0_true_um"].shape[1]) for t in range(start, stop)]
        for key in parts[0]:
            g[key][start * N:stop * N] = _fit(g[key], np.concatenate([p[key] for p in parts]))


class Writer:
    """A worker's side of the mpio path: its finished entries, written into
    its rows once rank 0's journal holds them (`written_upto`)."""

    def __init__(self, f):
        self.file, self.entries, self.sent = f, [], 0
        self.cells = int(f["trials"].attrs["cells_per_study"]) if "trials" in f else 0

    def keep(self, entry):
        self.entries.append(entry)
        self.sent += 1

    def written_upto(self, count):
        """Rank 0's journal holds this worker's first `count` entries: write those not yet written."""
        ready = len(self.entries) - (self.sent - count)
        write_entries(self.file, self.entries[:ready], self.cells, contiguous=True)
        del self.entries[:ready]

    def close(self):
        self.file.close()


def _error_dtype():
    """Error messages: fixed-length UTF-8 (parallel HDF5 cannot write
    variable-length strings); the journal keeps them whole."""
    return _h5().string_dtype("utf-8", ERROR_BYTES)


def _clip(text):
    """`text` as at most ERROR_BYTES bytes of UTF-8, cut between characters."""
    return text.encode()[:ERROR_BYTES].decode(errors="ignore").encode()


def _code_version():
    from importlib.metadata import version      # package metadata: campaign/ never imports cortex/
    return version("cortex-poisson")


def _trial_columns(entry, N, m):
    """A trial task's journal entry as the columns of its N rows. `cells` holds
    per-cell lists (`state`, `error`, CELL_KEYS) and per-cell lists of
    per-height values (HEIGHT_KEYS); a task that failed as a whole has no
    `cells`: all its trials are failed with its error, their values NaN.
    m: heights per trial."""
    cells = entry.get("cells") or {}
    out = {"state": np.array([STATES.index(x) for x in cells.get("state", [entry["state"]] * N)], np.int8),
           "error": np.array(cells.get("error", [entry.get("error", "")] * N), object),
           "attempts": np.full(N, entry["attempts"], np.int32), "rank": np.full(N, entry["rank"], np.int32),
           "started_unix_s": np.full(N, entry.get("started", np.nan), float)}
    for key in CELL_KEYS + HEIGHT_KEYS:
        shape = (N,) if key in CELL_KEYS else (N, m)
        out[key] = _decode(cells[key]) if key in cells else np.full(shape, np.nan)
    return out


def _encode(array):
    """A float array in a journal line: its float64 bytes in base64 (exact, and
    ~15 times faster to write and read than a list of decimal numbers)."""
    if not isinstance(array, np.ndarray):
        raise TypeError(f"cannot journal {type(array).__name__}")
    a = np.ascontiguousarray(array, "<f8")
    return {"f8": base64.b64encode(a.tobytes()).decode("ascii"), "shape": list(a.shape)}


def _decode(value):
    """`_encode`'s inverse; a plain list (journals of earlier versions) too."""
    if isinstance(value, dict):
        return np.frombuffer(base64.b64decode(value["f8"]), "<f8").reshape(value["shape"]).copy()
    return np.array(value, float)


def _set_aside(path, name):
    """Rename our file `path` to `name`, or `name-2`, `name-3`, ... if that is
    taken (never onto someone else's file); returns the name used."""
    target, k = name, 1
    while os.path.lexists(target):
        k += 1
        target = f"{name}-{k}"
    shutil.move(path, target)
    return target


def _trim_cut_line(path):
    """Cut a journal's last line if a kill or a full disk left it without its
    newline: it was never fsync'd whole, so no row holds it, and entries
    appended after it must stay readable."""
    if not os.path.exists(path) or os.path.getsize(path) == 0:
        return
    with open(path, "rb+") as fh:
        fh.seek(-1, os.SEEK_END)
        if fh.read(1) == b"\n":
            return
        size, chunk = fh.tell(), 1 << 16
        end = 0
        while size > 0 and not end:
            start = max(0, size - chunk)
            fh.seek(start)
            block = fh.read(size - start)
            cut = block.rfind(b"\n")
            end = start + cut + 1 if cut >= 0 else 0
            size = start
        fh.truncate(end)


def read_journal(path, start=0):
    """Entries of a journal from byte `start` on (the file's `journal_bytes`:
    everything before is in the HDF5 rows); a last line cut by a kill is ignored."""
    entries = []
    if os.path.exists(path):
        with open(path, "rb") as fh:
            fh.seek(int(start))
            for line in fh:
                try:
                    entries.append(json.loads(line))
                except (json.JSONDecodeError, UnicodeDecodeError):
                    break
    return entries


def read_results(path):
    """One row per compression task: parameters, state and results (NaN where
    not done), with the journal of a running campaign overlaid."""
    import pandas as pd           # here: a campaign run need not load it
    with _open_read(path) as f:
        if "fingerprint" not in f.attrs or "state" not in f:
            raise InputError(f"{path}: not a campaign store")
        frame = pd.DataFrame({key: f[key][:] if key in f else np.full(len(f["state"]), np.nan)
                              for key in PARAMS + RESULTS})
        frame.insert(0, "task_id", f["task_id"].asstr()[:])
        frame.insert(1, "bending", f["bending"].asstr()[:])
        state = f["state"][:]
        converged = f["converged"][:].astype(bool)
        attempts, rank, error = f["attempts"][:], f["rank"][:], list(f["error"].asstr()[:])
        start = f.attrs.get("journal_bytes", 0)
    for entry in read_journal(str(path) + ".journal", start):
        if "row" not in entry:
            continue                      # a trial task's entry
        i = entry["row"]
        state[i], attempts[i], rank[i] = STATES.index(entry["state"]), entry["attempts"], entry["rank"]
        error[i] = entry.get("error", "")
        for key, value in entry.get("results", {}).items():
            if key in RESULTS:
                frame.at[i, key] = value
        converged[i] = bool(entry.get("results", {}).get("converged", False))
    frame.insert(1, "state", [STATES[s] for s in state])
    frame["converged"], frame["attempts"], frame["rank"], frame["error"] = converged, attempts, rank, error
    return frame


def _trial_arrays(path):
    """The trials group as a dict of arrays (None without one), journal overlaid."""
    with _open_read(path) as f:
        if "trials" not in f:
            return None
        g = f["trials"]
        a = {key: (g[key].asstr()[:] if _h5().check_string_dtype(g[key].dtype) else g[key][:]) for key in g}
        N = int(g.attrs["cells_per_study"])
        start = f.attrs.get("journal_bytes", 0)
    a["error"] = a["error"].astype(object)
    for e in read_journal(str(path) + ".journal", start):
        if "task" in e:
            for key, values in _trial_columns(e, N, a["h0_true_um"].shape[1]).items():
                a[key][e["task"] * N:e["task"] * N + N] = values
    return a


def read_trials(path):
    """Monte-Carlo trial curves, long format: one row per trial and height with
    the columns TRIAL_COLUMNS, then `error` and `attempts` (how often its
    study ran); empty, with those columns, for a store without trials. Values
    of trials not done are NaN."""
    import pandas as pd
    a = _trial_arrays(path)
    if a is None:
        return pd.DataFrame({c: [] for c in TRIAL_COLUMNS + ("error", "attempts")})
    n, m = a["h0_true_um"].shape
    rep = lambda x: np.repeat(x, m)  # noqa: E731
    columns = {"trial_id": rep(a["trial_id"]), "state": rep(np.array(STATES, object)[a["state"]]),
               "nu_true": rep(a["nu_true"]), "bending": rep(a["bending"]),
               "height_error_mode": rep(a["height_error_mode"]), "study": rep(a["study"]),
               "cell": rep(a["cell"]), "bulk_mN_per_m": rep(a["bulk_mN_per_m"]),
               "shear_mN_per_m": rep(a["shear_mN_per_m"]), "tension_mN_per_m": rep(a["tension_mN_per_m"]),
               "volume_true_um3": rep(a["volume_true_um3"]), "volume_used_um3": rep(a["volume_used_um3"]),
               "h0_true_um": a["h0_true_um"].ravel(), "h0_used_um": a["h0_used_um"].ravel(),
               "h1_used_um": a["h1_used_um"].ravel(), "h_tilde": a["h_tilde"].ravel(),
               "modulus_mN_per_m": a["modulus_mN_per_m"].ravel(),
               "gamma_eff_mN_per_m": a["gamma_eff_mN_per_m"].ravel(),
               "tension_seen_mN_per_m": a["tension_seen_mN_per_m"].ravel(), "error": rep(a["error"]),
               "attempts": rep(a["attempts"])}
    return pd.DataFrame(columns)


def summary(path, now=time.time):
    """Counts by state, failures with their messages, throughput and ETA;
    `now()` is the clock (Unix s) a running campaign's rate is taken up to."""
    frame = read_results(path)
    counts = frame["state"].value_counts().to_dict()
    done = frame[frame["state"] == "done"]
    rate = None
    with _open_read(path) as f:
        started = f["started_unix_s"][:]
    left = int(len(frame) - counts.get("done", 0) - counts.get("failed", 0))
    if len(done) and np.isfinite(started).any():
        # a finished campaign's rate over its own span, a running one's up to now
        span = (now() if left else np.nanmax(started + np.nan_to_num(frame["wall_s"].to_numpy()))) \
            - np.nanmin(started)
        rate = len(done) / span if span > 0 else None
    info = {"tasks": int(len(frame)), **{s: int(counts.get(s, 0)) for s in STATES},
            "failures": frame.loc[frame["state"] == "failed", ["task_id", "error"]].values.tolist(),
            "tasks_per_s": rate, "eta_s": (left / rate) if rate else None}
    a = _trial_arrays(path)
    if a is not None:
        failed = a["state"] == FAILED
        info["trials"] = {"trials": int(a["state"].size),
                          **{s: int(np.sum(a["state"] == i)) for i, s in enumerate(STATES)},
                          "failures": sorted({e for e in a["error"][failed]})[:10]}
    return info


def read_provenance(path):
    """What made a store: its campaign file's text, fingerprint, code and library
    versions, host and creation time (the attributes written when it was created)."""
    keys = ("name", "config_text", "fingerprint", "code_version", "versions", "host", "created")
    with _open_read(path) as f:
        if "fingerprint" not in f.attrs:
            raise InputError(f"{path}: not a campaign store")
        out = {k: f.attrs[k] for k in keys if k in f.attrs}
    return {k: (v.decode() if isinstance(v, bytes) else v.item() if hasattr(v, "item") else v)
            for k, v in out.items()}
