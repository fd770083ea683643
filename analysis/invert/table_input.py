"""The input table of `cortex analysis invert`: K(h̃) per cell from other software.

CSV with a header; columns `cell_id, h_tilde, modulus_mN_per_m, tension_mN_per_m`
(required) and `frequency_hz`, `volume_um3` (optional), one row per cell (and
frequency) and height. Every value must be a finite number (cell_id: any
text), h̃ in (0, 1), the modulus finite, tension and volume > 0. Anything else
is an InputError naming the file, the line and the column. This is where a
table's cell volumes are checked: a table without `volume_um3` needs one
volume for all its cells (`cortex analysis invert --volume`); there is no
default.
"""

from os import PathLike
from pathlib import Path

import numpy as np
import pandas as pd

from common.errors import InputError

REQUIRED = ("cell_id", "h_tilde", "modulus_mN_per_m", "tension_mN_per_m")
OPTIONAL = ("frequency_hz", "volume_um3")
POSITIVE = ("tension_mN_per_m", "volume_um3", "frequency_hz")


def read_table(path: str | PathLike[str], volume_um3: float | None = None) -> pd.DataFrame:
    """The rows of `path` as a DataFrame with a `volume_um3` column: the table's own, or
    `volume_um3` (µm³) for every cell where it has none (InputError, one line, if malformed,
    if both or neither give the volumes, or if `volume_um3` is not > 0)."""
    path = Path(path)
    if path.is_dir():
        raise InputError(f"{path}: is a directory, not a table")
    try:
        with open(path, "rb") as fh:
            if b"\0" in fh.read(65536):
                raise InputError(f"{path}: not a text (CSV) file")
        frame = pd.read_csv(path, dtype={"cell_id": str}, skipinitialspace=True)
    except FileNotFoundError:
        raise InputError(f"{path}: no such file") from None
    except UnicodeDecodeError:
        raise InputError(f"{path}: not a text (CSV) file") from None
    except (pd.errors.ParserError, pd.errors.EmptyDataError) as err:
        raise InputError(f"{path}: not a readable CSV table ({str(err).splitlines()[0]})") from None
    missing = [c for c in REQUIRED if c not in frame.columns]
    if missing:
        raise InputError(f"{path}: missing column(s) {', '.join(missing)} (need {', '.join(REQUIRED)})")
    if frame.empty:
        raise InputError(f"{path}: no rows")
    if frame["cell_id"].isna().any():
        raise InputError(f"{path}: line {int(np.flatnonzero(frame['cell_id'].isna())[0]) + 2}: empty cell_id")
    for col in REQUIRED[1:] + tuple(c for c in OPTIONAL if c in frame.columns):
        values = pd.to_numeric(frame[col], errors="coerce")
        bad = ~np.isfinite(values.to_numpy(float))
        if col in POSITIVE:
            bad |= ~(values.to_numpy(float) > 0)
        if col == "h_tilde":
            bad |= ~((values > 0) & (values < 1)).to_numpy()
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            want = "a number in (0, 1)" if col == "h_tilde" else "a number > 0" if col in POSITIVE \
                else "a finite number"
            raise InputError(f"{path}: line {i + 2}: {col} must be {want} (got {frame[col].iloc[i]!r})")
        frame[col] = values.astype(float)
    frame = frame[[c for c in REQUIRED + OPTIONAL if c in frame.columns]]
    if "volume_um3" in frame and volume_um3 is not None:
        raise InputError(f"{path}: has a volume_um3 column; --volume is for a table without one")
    return frame if "volume_um3" in frame else frame.assign(volume_um3=_one_volume(path, volume_um3))


def _one_volume(path: Path, volume_um3: float | None) -> float:
    """The one volume (µm³) of every cell of a table without a `volume_um3` column."""
    if volume_um3 is None:
        raise InputError(f"{path}: no volume_um3 column: give each cell's volume there, or one for "
                         "every cell with --volume UM3")
    if not volume_um3 > 0 or not np.isfinite(volume_um3):
        raise InputError(f"--volume must be a number > 0 (got {volume_um3})")
    return float(volume_um3)
