"""A store's files: which are ours, opening one to read, setting one aside.

Only a file that is ours is ever opened for writing, set aside or rebuilt
(the rule of `outputs.ownership`): an HDF5 file with our `format` attribute,
or one a kill left unreadable with our journal and lock beside it.

A journal is written only once its store exists (a run makes the store, then
opens the journal), so records where no store is belong to another store: one
moved or deleted, of this campaign or another. A store being created never
takes them (`check_no_stale_journal`). A store's journal is its own when its
first record carries the store's mark (`journal_mark`; a store made before
records were marked has none) and it is not shorter than the rows hold
(`journal_bytes`): `check_own_journal`.
"""

from __future__ import annotations

import os
import shutil
from typing import TYPE_CHECKING

from campaign.store import journal
from campaign.store.schema import FORMAT
from outputs.ownership import check_file, hdf5_format
from common.errors import InputError

if TYPE_CHECKING:
    import h5py


def open_read(path: str | os.PathLike[str]) -> h5py.File:
    """The store opened read-only, without HDF5's file locking (a campaign may
    be writing it); InputError if it is missing or not HDF5."""
    import h5py
    if not os.path.exists(path):
        raise InputError(f"{path}: no such store")
    try:
        try:
            return h5py.File(path, "r", locking=False)
        except TypeError:
            return h5py.File(path, "r")
    except OSError as err:
        raise InputError(f"{path}: not a readable HDF5 store ({err})") from None


def open_store(path: str | os.PathLike[str]) -> h5py.File:
    """`open_read`, and InputError (one line) for an HDF5 file that is not a campaign store."""
    f = open_read(path)
    if "fingerprint" not in f.attrs or "state" not in f:
        f.close()
        raise InputError(f"{path}: not a campaign store")
    return f


def is_our_store(path: str | os.PathLike[str]) -> bool:
    """Whether `path` is a campaign store (see the module's docstring)."""
    path = str(path)
    if hdf5_format(path) == FORMAT:
        return True
    try:
        open_read(path).close()
        return False                                  # readable HDF5 without our format: not ours
    except InputError:
        return os.path.isfile(path + ".lock") and os.path.isfile(path + ".journal") \
            and journal.is_ours(path + ".journal")


def check_store_path(path: str) -> None:
    """Refuse (InputError) a --store that is a folder or a file that is not ours,
    or whose journal is not ours; they are left as they are."""
    check_file(path, is_our_store, "--store")
    check_file(path + ".journal", journal.is_ours, "--store's journal")


def check_no_stale_journal(path: str) -> None:
    """Refuse (InputError, one line) to create a store at `path` beside a journal that holds
    records: they were written for another store, and the new one would take them as its
    own results. An empty journal holds nothing: it is used."""
    stale = path + ".journal"
    if not os.path.exists(path) and os.path.isfile(stale) and os.path.getsize(stale) > 0:
        raise InputError(f"--store {path}: no store there, but {stale} holds "
                         f"{os.path.getsize(stale):,} bytes of another store's finished tasks, which a new "
                         "store must not take as its own; move or delete that journal, give another --store, "
                         "or use --new (it is kept as a backup)")


def check_own_journal(path: str, journal_bytes: int, mark: str) -> None:
    """Refuse (InputError, one line) the store at `path` (its rows hold `journal_bytes` of its journal,
    its journal's records are marked `mark`, '' if unmarked) beside another store's journal: one
    whose first record carries another mark or none, or (not empty) one shorter than the rows hold
    (a store's journal only grows; an empty or missing one holds nothing and is started again).
    A first record that is damaged tells nothing: the length alone is checked."""
    size = os.path.getsize(path + ".journal") if os.path.isfile(path + ".journal") else 0
    found = journal.mark(path + ".journal") if mark and size else None
    if found is not None and found != mark:
        raise InputError(f"{path}: {path}.journal is another store's journal (its first record is not marked "
                         f"as this store's); move the store or that journal so that each is beside its own "
                         "(both are left as they are)")
    if 0 < size < journal_bytes:
        raise InputError(f"{path}: its rows hold {journal_bytes:,} bytes of its journal but {path}.journal "
                         f"has {size:,}: it is another store's journal; move the store or that journal so "
                         "that each is beside its own (both are left as they are)")


def set_aside(path: str, name: str) -> str:
    """Rename our file `path` to `name`, or `name-2`, `name-3`, ... if that is
    taken (never onto someone else's file); returns the name used."""
    target = _free(name)
    shutil.move(path, target)
    return target


def keep_aside(path: str, name: str) -> tuple[str, bool]:
    """Our file `path` kept as `name` (or `name-2`, ... as `set_aside`) and still at `path`, by a
    second name (a hard link), so that what replaces `path` replaces it at once and `path` is never
    missing; where the file system has no hard links, set aside (moved). Returns (the name used,
    whether `path` still holds it)."""
    target = _free(name)
    try:
        os.link(path, target)
        return target, True
    except OSError:
        return set_aside(path, target), False


def _free(name: str) -> str:
    """`name`, or `name-2`, `name-3`, ... whichever is not taken."""
    target, k = name, 1
    while os.path.lexists(target):
        k += 1
        target = f"{name}-{k}"
    return target
