"""What the project may write: the one rule every command follows for its
output paths (`outputs.ownership`), and writes that a full disk stops cleanly
(`outputs.writing`).

Public API: `OutputDir(path)` (an output folder with its manifest),
`check_file(path, is_ours, what)` (a single output file), `write_atomically(path, data)`.
"""

from typing import TYPE_CHECKING

from common.lazy_exports import lazy_exports

if TYPE_CHECKING:
    from outputs.ownership import MANIFEST, OutputDir, check_file
    from outputs.writing import write_atomically

__all__, __getattr__, __dir__ = lazy_exports(__name__, {
    "OutputDir": "outputs.ownership", "check_file": "outputs.ownership", "MANIFEST": "outputs.ownership",
    "write_atomically": "outputs.writing",
})
