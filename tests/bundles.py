"""Test scaffolding: a copy of the shipped calibration bundle with some of its parts replaced."""

import json
import shutil
from pathlib import Path
from typing import Any

from analysis.calibration.file import POWERLAW_TABLE_NAME, RAMP_TABLE_NAME, TABLE_NAME, shipped_path


def bundle_copy(folder: Path, parts: dict[str, Any] | None = None) -> Path:
    """The shipped bundle's manifest and part files copied into `folder`, each part file named in
    `parts` (file name -> its JSON document) written instead of the shipped one; the manifest's path."""
    parts = parts or {}
    shutil.copy(shipped_path(), folder / "calibration.json")
    for name in (TABLE_NAME, RAMP_TABLE_NAME, POWERLAW_TABLE_NAME):
        if name in parts:
            (folder / name).write_text(json.dumps(parts[name]))
        else:
            shutil.copy(shipped_path(name), folder / name)
    return folder / "calibration.json"


def shipped_part(name: str) -> dict[str, Any]:
    """The JSON document of the shipped bundle's part file `name`."""
    return json.loads(shipped_path(name).read_text())
