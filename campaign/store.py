"""The campaign store: one HDF5 file, one row per task, plus its journal.

Every dataset is created up front at its final size; a task's parameters,
state (pending, running, done, failed), attempts, worker rank, timings, error
message and results live in its own row. Attributes keep the campaign file's
text, its fingerprint, the code and library versions, host and ranks.

Kill safety: each finished task is first appended to `STORE.journal` (one
JSON line, fsync'd in batches) and then written into the HDF5 rows; the HDF5
file is flushed after each batch. On opening, the journal is replayed into
the file (idempotent), rows left `running` become `pending` again, and a file
that a kill left unreadable is set aside and rebuilt from the campaign and the
journal. So a rerun finishes the remaining tasks and ends with the same rows as
an uninterrupted run. A lock file refuses a second run on the same store.
Readers (`read_results`, `summary`) open the file without HDF5's file locking
and overlay the journal, so they also work while a campaign is running.
"""

import fcntl
import json
import os
import platform
import shutil
import socket
import time

import numpy as np
import pandas as pd

from solver.errors import InputError

PARAMS = ("volume_um3", "h0_um", "dh_um", "bulk_mN_per_m", "shear_mN_per_m",
          "tension_mN_per_m", "thickness_um")
RESULTS = ("force_nN", "active_force_nN", "gamma_eff_mN_per_m", "delta_gamma_mN_per_m",
           "area_strain", "area_strain_shell", "modulus_mN_per_m", "h_mean_um", "h_tilde",
           "volume_error", "equator_shear_ratio", "iterations", "wall_s")
STATES = ("pending", "running", "done", "failed")
PENDING, RUNNING, DONE, FAILED = range(4)
TRIAL_COLUMNS = ("trial_id", "state", "nu_true", "bending", "height_error_mode", "study", "cell",
                 "bulk_mN_per_m", "shear_mN_per_m", "tension_mN_per_m", "volume_true_um3",
                 "volume_used_um3", "h0_true_um", "h0_used_um", "h1_used_um", "h_tilde",
                 "modulus_mN_per_m", "gamma_eff_mN_per_m", "tension_seen_mN_per_m")


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


class Store:
    """The writer's view of a store (rank 0 only)."""

    def __init__(self, path, campaign, new=False, ranks=1):
        self.path, self.journal_path = str(path), str(path) + ".journal"
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
        self._replay()
        state = self.file["state"][:]
        state[state == RUNNING] = PENDING
        self.file["state"][:] = state
        self.file.flush()
        self.journal = open(self.journal_path, "a")
        self.buffer, self.running, self.shown_running = [], set(), set()

    # -- opening -----------------------------------------------------------
    def _check_same(self, campaign):
        try:
            with _open_read(self.path) as f:
                fingerprint = f.attrs.get("fingerprint")
        except InputError:
            return            # unreadable: rebuilt from the journal below
        if fingerprint is None:
            raise InputError(f"{self.path}: not a campaign store (no fingerprint); "
                             "choose another --store")
        if fingerprint != campaign.fingerprint:
            raise InputError(f"{self.path} was made from a different campaign file; "
                             "use --new to start over (the old store is kept as a backup)")

    def _backup(self):
        stamp = time.strftime("%Y%m%d-%H%M%S")
        for p in (self.path, self.journal_path):
            if os.path.exists(p):
                shutil.move(p, f"{p}.bak-{stamp}")

    def _create(self, campaign, ranks):
        h5py = _h5()
        n = len(campaign.shells)
        tmp = self.path + ".tmp"
        with h5py.File(tmp, "w") as f:
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
            f.create_dataset("error", data=np.array([""] * n, object), dtype=str_t)
            f.attrs.update(self._provenance(campaign, ranks))
        os.replace(tmp, self.path)

    @staticmethod
    def _provenance(campaign, ranks):
        import h5py
        import mpi4py
        import numpy
        import scipy
        from cortex import __version__
        return {"fingerprint": campaign.fingerprint, "config_text": campaign.text,
                "name": campaign.name, "method": campaign.method, "code_version": __version__,
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
            aside = f"{self.path}.unreadable-{time.strftime('%Y%m%d-%H%M%S')}"
            shutil.move(self.path, aside)
            print(f"campaign: {self.path} was left unreadable (kept as {aside}); "
                  "rebuilding it from the journal", flush=True)
            self._create(campaign, ranks)
            return h5py.File(self.path, "r+")

    def _replay(self):
        self._write_rows(read_journal(self.journal_path))

    # -- writing -----------------------------------------------------------
    def _write_rows(self, entries):
        """Write entries into their rows, one HDF5 write per column (last entry of a row wins)."""
        by_row = {e["row"]: e for e in entries}
        if not by_row:
            return
        rows = np.array(sorted(by_row))
        batch = [by_row[i] for i in rows]
        f = self.file
        results = [e.get("results", {}) for e in batch]
        columns = {
            "state": np.array([STATES.index(e["state"]) for e in batch], np.int8),
            "attempts": np.array([e["attempts"] for e in batch], np.int32),
            "rank": np.array([e["rank"] for e in batch], np.int32),
            "error": np.array([e.get("error", "") for e in batch], object),
            "converged": np.array([int(bool(r.get("converged", False))) for r in results], np.int8),
            "started_unix_s": np.array([e.get("started", np.nan) for e in batch], float)}
        for key in RESULTS:
            columns[key] = np.array([r.get(key, np.nan) for r in results], float)
        for key, values in columns.items():
            f[key][rows] = values

    def state(self):
        return self.file["state"][:]

    def attempts(self):
        return self.file["attempts"][:]

    def mark_running(self, rows):
        """Shown as running from the next flush on (the journal never holds `running`)."""
        self.running.update(int(r) for r in rows)

    def record(self, entry):
        """Journal first; the HDF5 rows follow in batches, after the journal's fsync (`flush`)."""
        self.journal.write(json.dumps(entry) + "\n")
        self.buffer.append(entry)
        self.running.discard(entry["row"])
        if os.environ.get("CORTEX_TEST_KILL_MID_WRITE") == str(entry["row"]):
            self.flush()
            self.file["state"][entry["row"]] = DONE
            os.kill(os.getpid(), 9)

    def flush(self):
        """fsync the journal, then write the buffered rows and the running marks into HDF5."""
        if self.buffer:
            self.journal.flush()
            os.fsync(self.journal.fileno())
            self._write_rows(self.buffer)
            self.buffer = []
        if self.running != self.shown_running:
            state = self.file["state"][:]
            state[list(self.shown_running - self.running)] = np.where(
                state[list(self.shown_running - self.running)] == RUNNING, PENDING,
                state[list(self.shown_running - self.running)])
            state[list(self.running)] = RUNNING
            self.file["state"][:] = state
            self.shown_running = set(self.running)
        self.file.flush()

    def close(self):
        self.flush()
        self.file.close()
        self.journal.close()
        fcntl.flock(self.lock, fcntl.LOCK_UN)
        self.lock.close()


def read_journal(path):
    """Entries of a journal; a last line cut by a kill is ignored."""
    entries = []
    if os.path.exists(path):
        with open(path) as fh:
            for line in fh:
                try:
                    entries.append(json.loads(line))
                except json.JSONDecodeError:
                    break
    return entries


def read_results(path):
    """One row per compression task: parameters, state and results (NaN where
    not done), with the journal of a running campaign overlaid."""
    with _open_read(path) as f:
        if "fingerprint" not in f.attrs or "state" not in f:
            raise InputError(f"{path}: not a campaign store")
        frame = pd.DataFrame({key: f[key][:] for key in PARAMS + RESULTS})
        frame.insert(0, "task_id", f["task_id"].asstr()[:])
        frame.insert(1, "bending", f["bending"].asstr()[:])
        state = f["state"][:]
        converged = f["converged"][:].astype(bool)
        attempts, rank, error = f["attempts"][:], f["rank"][:], list(f["error"].asstr()[:])
    for entry in read_journal(str(path) + ".journal"):
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


def read_trials(path):
    """Monte-Carlo trial curves (long format). The engine does not run
    Monte-Carlo stages yet: the table is empty, with its columns."""
    _open_read(path).close()
    return pd.DataFrame({c: [] for c in TRIAL_COLUMNS})


def summary(path):
    """Counts by state, failures with their messages, throughput and ETA."""
    frame = read_results(path)
    counts = frame["state"].value_counts().to_dict()
    done = frame[frame["state"] == "done"]
    rate = None
    with _open_read(path) as f:
        started = f["started_unix_s"][:]
    if len(done) and np.isfinite(started).any():
        span = time.time() - np.nanmin(started)
        rate = len(done) / span if span > 0 else None
    left = int(len(frame) - counts.get("done", 0) - counts.get("failed", 0))
    return {"tasks": int(len(frame)), **{s: int(counts.get(s, 0)) for s in STATES},
            "failures": frame.loc[frame["state"] == "failed", ["task_id", "error"]].values.tolist(),
            "tasks_per_s": rate, "eta_s": (left / rate) if rate else None}
