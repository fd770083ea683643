"""Single-cell CSV import/export.

    # cell_id: c001
    # volume_um3: 4300
    # volume_source: confocal imaging
    # spring_constant_N_per_m: 0.5
    # date: 2020-10-29
    time_s,force_nN,height_um,segment,kind,frequency_hz
    0.00,41.2,15.10,0,approach,
    ...

One row per sample; `segment` numbers consecutive samples of one segment,
`kind` is approach or oscillation, `frequency_hz` is empty for approach.
Metadata lines are `# key: value`; `volume_um3` is required.
"""

from pathlib import Path

import numpy as np
import pandas as pd

from analysis.afm.cell import Cell, Segment
from common.errors import InputError

COLUMNS = ("time_s", "force_nN", "height_um", "segment", "kind", "frequency_hz")


def write_csv_cell(path: str | Path, cell: Cell) -> str | Path:
    seg = np.empty(len(cell.time_s), int)
    kind = np.empty(len(cell.time_s), object)
    freq = np.full(len(cell.time_s), np.nan)
    for i, s in enumerate(cell.segments):
        seg[s.start:s.stop], kind[s.start:s.stop], freq[s.start:s.stop] = i, s.kind, s.frequency_hz
    head = (f"# cell_id: {cell.cell_id}\n# volume_um3: {cell.volume_um3!r}\n# volume_source: {cell.volume_source}\n"
            f"# spring_constant_N_per_m: {cell.spring_constant_N_per_m!r}\n# date: {cell.date}\n")
    df = pd.DataFrame({"time_s": cell.time_s, "force_nN": cell.force_nN, "height_um": cell.height_um,
                       "segment": seg, "kind": kind, "frequency_hz": freq})
    Path(path).write_text(head + df.to_csv(index=False))
    return path


def _read_table(path: Path) -> tuple[dict[str, str], pd.DataFrame]:
    """The '# key: value' metadata lines and the table below them, checked."""
    meta, n_head = {}, 0
    try:
        with open(path) as fh:
            for line in fh:
                if not line.startswith("#"):
                    break
                key, sep, value = line[1:].partition(":")
                if sep:
                    meta[key.strip()] = value.strip()
                n_head += 1
        df = pd.read_csv(path, skiprows=n_head)
    except UnicodeDecodeError:
        raise InputError(f"{path}: not a text CSV file") from None
    except (pd.errors.ParserError, pd.errors.EmptyDataError) as err:
        raise InputError(f"{path}: not a readable CSV ({str(err).splitlines()[0]})") from None
    missing = [c for c in COLUMNS if c not in df.columns]
    if missing:
        raise InputError(f"{path}: column(s) {', '.join(missing)} missing (need {', '.join(COLUMNS)}; "
                         "units in the names: s, nN, um, Hz)")
    for c in ("time_s", "force_nN", "height_um"):
        if not pd.api.types.is_numeric_dtype(df[c]):
            raise InputError(f"{path}: column {c} is not numeric")
    return meta, df


def _segments(df: pd.DataFrame) -> list[Segment]:
    """One `Segment` per run of equal values in the `segment` column."""
    seg = df["segment"].to_numpy()
    edges = np.r_[0, np.flatnonzero(np.diff(seg) != 0) + 1, len(seg)]
    segments = []
    for a, b in zip(edges[:-1], edges[1:]):
        kind = str(df["kind"].iat[a])
        freq = float(df["frequency_hz"].iat[a]) if kind == "oscillation" else float("nan")
        segments.append(Segment(kind=kind, start=int(a), stop=int(b), frequency_hz=freq))
    return segments


def read_csv_cell(path: str | Path) -> Cell:
    """One cell of the single-cell CSV format (module docstring); InputError for bad input."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such file")
    meta, df = _read_table(path)
    if "volume_um3" not in meta:
        raise InputError(f"{path}: metadata line '# volume_um3: ...' missing")
    try:
        volume = float(meta["volume_um3"])
    except ValueError:
        raise InputError(f"{path}: volume_um3 = {meta['volume_um3']!r} is not a number") from None
    if len(df) == 0:
        raise InputError(f"{path}: no samples")
    try:
        spring = float(meta.get("spring_constant_N_per_m", "nan"))
    except ValueError:
        spring = float("nan")
    cell = Cell(cell_id=meta.get("cell_id", path.stem), volume_um3=volume,
                time_s=df["time_s"].to_numpy(float), force_nN=df["force_nN"].to_numpy(float),
                height_um=df["height_um"].to_numpy(float), segments=_segments(df),
                volume_source=meta.get("volume_source", ""), spring_constant_N_per_m=spring,
                date=meta.get("date", ""))
    return cell.validate(f"{path}: ")
