"""The files a measured cell comes in: the native experiment file (`h5.py`), the
single-cell CSV (`csvcell.py`), and the instruments' files (`instruments.py`: which
reader for which file, the height and volume policy) read by `jpk/` and `bruker/`
into `recording.Recording`s; `textfiles.py` opens text exports plain or gzipped.
`reader.py` is the one way in: `open(paths, ImportOptions) -> list[Cell]`, what every
command reads recordings with.

Public API (imported on first use): `open`, `ImportOptions`.
"""

from typing import TYPE_CHECKING

from common.lazy_exports import lazy_exports

if TYPE_CHECKING:
    from analysis.afm.formats.reader import ImportOptions, open

__all__, __getattr__, __dir__ = lazy_exports(__name__, {
    "open": "analysis.afm.formats.reader", "ImportOptions": "analysis.afm.formats.reader",
})
