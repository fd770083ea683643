"""Text exports as they are on disk: plain or gzip-compressed (`NAME.txt.gz`).

`open_text` opens either for reading text (gzip is recognised by its magic
bytes, not trusted to the suffix); `head` gives the first bytes after
decompression (what a format is recognised by); `export_name` is the file
name without `.gz` and `.txt`, the cell id of a text export.
"""

import gzip
import io
from pathlib import Path

from common.errors import InputError

GZIP_MAGIC = b"\x1f\x8b"
COMPRESSED_SUFFIX = ".gz"


def is_gzip(path: Path) -> bool:
    """True when the file starts with gzip's magic bytes."""
    with open(path, "rb") as fh:
        return fh.read(2) == GZIP_MAGIC


def read_bytes(path: Path) -> bytes:
    """The whole (decompressed) content; a damaged gzip stream is one InputError line."""
    try:
        if is_gzip(path):
            with gzip.open(path, "rb") as fh:
                return fh.read()
        return Path(path).read_bytes()
    except (OSError, EOFError, gzip.BadGzipFile) as err:
        raise InputError(f"{path}: cannot be read ({err})") from None


def head(path: Path, n: int = 64) -> bytes:
    """The first n (decompressed) bytes."""
    try:
        with (gzip.open(path, "rb") if is_gzip(path) else open(path, "rb")) as fh:
            return fh.read(n)
    except (OSError, EOFError, gzip.BadGzipFile) as err:
        raise InputError(f"{path}: cannot be read ({err})") from None


def open_text(path: Path, encoding: str = "utf-8", errors: str = "strict") -> io.TextIOBase:
    """A text stream of the file, decompressed if it is gzip."""
    if is_gzip(path):
        return io.TextIOWrapper(gzip.open(path, "rb"), encoding=encoding, errors=errors)
    return open(path, encoding=encoding, errors=errors)


def export_name(path: Path) -> str:
    """The file name without a trailing `.gz` and then `.txt` (case-insensitive)."""
    name = Path(path).name
    for suffix in (COMPRESSED_SUFFIX, ".txt"):
        if name.lower().endswith(suffix):
            name = name[: -len(suffix)]
    return name
