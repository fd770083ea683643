"""May the project write here? The one rule for every output path.

The project never overwrites, moves or deletes anything it did not write
itself. Two kinds of output path:

- a single file (a campaign store, an experiment file): writable if it does
  not exist; if it exists, only when the caller's recogniser says it is ours
  (`check_file`; e.g. our `format` attribute in an HDF5 file). A folder, or
  anything that is not a regular file, is never ours.
- an output folder (`OutputDir`): writable if it does not exist or is empty;
  it then gets a manifest, `.cortex-outputs`, one line per file the project
  wrote there. A later run may replace exactly those files. A non-empty
  folder without the manifest, or a file in it that the manifest does not
  list, is refused.

A refusal is `InputError` (one line, exit status 2), raised before anything
is written.
"""

import contextlib
import os
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

from outputs.writing import named_failures
from common.errors import InputError

MANIFEST = ".cortex-outputs"
HEADER = "# files written here by cortex; a rerun replaces only these\n"


def check_file(path: str | os.PathLike[str], is_ours: Callable[[Path], bool], what: str) -> Path:
    """Refuse `path` unless it is missing or `is_ours(path)` says it is ours.
    `what` names the option in the message (e.g. "--store")."""
    path = Path(path)
    if not os.path.lexists(path):
        return path
    if path.is_dir():
        raise InputError(f"{what} {path}: is a folder, not a file; name a file (it is left as it is)")
    if not path.is_file() or path.is_symlink() or not is_ours(path):
        raise InputError(f"{what} {path}: exists and was not written by cortex; it is left as it is "
                         "(choose another path)")
    return path


def json_document(path: str | os.PathLike[str]) -> dict[str, Any]:
    """The object a JSON file holds; {} if it is missing, not JSON or not an object."""
    import json
    try:
        doc = json.loads(Path(path).read_text())
    except (OSError, ValueError, UnicodeDecodeError):
        return {}
    return doc if isinstance(doc, dict) else {}


def hdf5_format(path: str | os.PathLike[str]) -> str:
    """The `format` attribute of an HDF5 file, '' if it has none or is not readable HDF5."""
    import h5py
    try:
        with h5py.File(path, "r", locking=False) as f:
            value = f.attrs.get("format", "")
    except (OSError, TypeError):
        return ""
    return value.decode() if isinstance(value, bytes) else str(value)


class OutputDir:
    """An output folder that holds only what the project wrote (its manifest)."""

    def __init__(self, path: str | os.PathLike[str], what: str = "--out"):
        self.path, self.what = Path(path), what
        self.manifest = self.path / MANIFEST
        if os.path.lexists(self.path) and not self.path.is_dir():
            raise InputError(f"{what} {self.path}: exists and is not a directory")
        self.ours = self._listed()
        if self.path.is_dir() and self.ours is None and any(self.path.iterdir()):
            raise InputError(f"{what} {self.path}: a folder that cortex did not write (no {MANIFEST} "
                             "in it) and not empty; choose a new or empty folder (it is left as it is)")
        self.ours = self.ours or set()

    def _listed(self):
        """Names the manifest lists; None without a manifest."""
        if not self.manifest.is_file():
            return None
        return {line.strip() for line in self.manifest.read_text(errors="replace").splitlines()
                if line.strip() and not line.startswith("#")}

    def check(self, names: Iterable[str]) -> None:
        """Refuse now if any of `names` exists here and the project did not write it."""
        for name in names:
            target = self.path / name
            if os.path.lexists(target) and name not in self.ours:
                raise InputError(f"{self.what} {self.path}: {name} is there and cortex did not write it "
                                 f"(not in {MANIFEST}); it is left as it is (choose another folder)")

    def claim(self, name: str) -> Path:
        """The path of file `name`, to be written now: checked, and listed in the
        manifest before it is written (so a kill mid-write leaves it ours)."""
        self.check([name])
        if name not in self.ours:
            self.path.mkdir(parents=True, exist_ok=True)
            new = not self.manifest.exists()
            with named_failures(self.manifest), open(self.manifest, "a") as fh:
                fh.write((HEADER if new else "") + name + "\n")
            self.ours.add(name)
        return self.path / name


    def writing(self, name: str) -> contextlib.AbstractContextManager[Path]:
        """`with out.writing(name) as path:` claim `name`, write it in the block;
        a full disk there becomes a WriteError naming it."""
        return named_failures(self.claim(name))
