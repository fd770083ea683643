"""The native experiment file (HDF5, one file, many cells).

Layout (format "cortex-afm", version 1):

    /                          attrs: format="cortex-afm", version=1
    /cells/<cell_id>/          attrs: volume_um3, volume_source, spring_constant_N_per_m, date
        time_s, force_nN, height_um      float64 (n,)
        segments                        compound (m,): kind (str: approach, pause, retract,
                                        oscillation), start, stop (int64, samples [start, stop)),
                                        frequency_hz (float64, NaN but for oscillations)
        segment_amplitude_um            float64 (m,), optional: an oscillation's piezo amplitude
                                        (NaN where unknown; written by `cortex afm import`)
    /provenance/               how the experiment was made: measured or synthetic, with its model
                               (`analysis.afm.provenance`; absent from files written before it was
                               recorded, which read as unknown)

Writing builds the file in memory and writes it to `FILE.tmp`, renamed at
the end, so no file is left half-written and a full disk is one clear error. Reading checks the layout and every cell
(`Cell.validate`) and raises InputError naming the file and cell.
"""

from collections.abc import Iterable
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from analysis.afm import provenance as prov
from analysis.afm.cell import Cell, Segment
from analysis.afm.provenance import Provenance
from outputs.writing import hdf5_image, write_atomically
from common.errors import InputError

FORMAT, VERSION = "cortex-afm", 1
SEG_DTYPE = np.dtype([("kind", h5py.string_dtype()), ("start", "i8"), ("stop", "i8"), ("frequency_hz", "f8")])


def write_experiment(path: str | Path, cells: Iterable[Cell], provenance: Provenance = prov.UNKNOWN) -> Path:
    """Write `cells` made as `provenance` says to `path` (built in memory, written atomically: a full
    disk gives a WriteError naming `path`, never a half-written file); an unknown provenance is not written."""
    return Path(write_atomically(path, hdf5_image(lambda f: _fill(f, cells, provenance))))


def _fill(f: h5py.File, cells: Iterable[Cell], provenance: Provenance) -> None:
    f.attrs["format"], f.attrs["version"] = FORMAT, VERSION
    prov.write(f, provenance)
    root = f.create_group("cells")
    for c in cells:
        g = root.create_group(c.cell_id)
        g.attrs.update(volume_um3=float(c.volume_um3), volume_source=c.volume_source,
                       spring_constant_N_per_m=float(c.spring_constant_N_per_m), date=c.date)
        for name in ("time_s", "force_nN", "height_um"):
            g.create_dataset(name, data=np.asarray(getattr(c, name), float))
        seg = np.array([(s.kind, s.start, s.stop, s.frequency_hz) for s in c.segments], dtype=SEG_DTYPE)
        g.create_dataset("segments", data=seg)
        amp = np.array([s.amplitude_um for s in c.segments], float)
        if np.isfinite(amp).any():
            g.create_dataset("segment_amplitude_um", data=amp)


def _attr(g: h5py.Group, key: str, where: str, default: Any = None) -> Any:
    if key not in g.attrs:
        if default is not None:
            return default
        raise InputError(f"{where}: attribute '{key}' missing")
    v = g.attrs[key]
    return v.decode() if isinstance(v, bytes) else v


def _segments(seg: Any, amp: Any, where: str) -> list[Segment]:
    """Segment objects from the `segments` table and the optional amplitudes."""
    try:
        amp = np.full(len(seg), np.nan) if amp is None else np.asarray(amp, float).ravel()
    except (ValueError, TypeError):
        raise InputError(f"{where}: segment_amplitude_um is not numeric") from None
    if len(amp) != len(seg):
        raise InputError(f"{where}: segment_amplitude_um has {len(amp)} values for {len(seg)} segments")
    try:
        return [Segment(kind=k.decode() if isinstance(k, bytes) else str(k), start=int(a), stop=int(b),
                        frequency_hz=float(fr), amplitude_um=float(am))
                for k, a, b, fr, am in zip(seg["kind"], seg["start"], seg["stop"], seg["frequency_hz"], amp)]
    except (ValueError, TypeError, KeyError, IndexError):
        raise InputError(f"{where}: 'segments' is not a table of kind, start, stop, frequency_hz") from None


def _open(path: Path) -> h5py.File:
    """The experiment file at `path`, open for reading, its format and version checked."""
    if not path.is_file():
        raise InputError(f"{path}: no such file")
    try:
        f = h5py.File(path, "r")
    except OSError:
        raise InputError(f"{path}: not an HDF5 file (truncated or corrupt?)") from None
    form, version = f.attrs.get("format"), f.attrs.get("version", -1)
    if form != FORMAT or int(version) != VERSION:
        f.close()
        if form != FORMAT:
            raise InputError(f"{path}: not a cortex-afm experiment (attribute format != '{FORMAT}')")
        raise InputError(f"{path}: format version {version} (this reader knows {VERSION})")
    return f


def read_provenance(path: str | Path) -> Provenance:
    """How the experiment file at `path` was made (`analysis.afm.provenance`; unknown if not recorded)."""
    with _open(Path(path)) as f:
        return prov.read(f, str(path))


def read_experiment(path: str | Path) -> list[Cell]:
    """All cells of an experiment file, validated (its provenance too)."""
    path = Path(path)
    with _open(path) as f:
        prov.read(f, str(path))
        if "cells" not in f or not len(f["cells"]):
            raise InputError(f"{path}: no cells in /cells")
        cells = []
        for cid, g in f["cells"].items():
            where = f"{path}: cell '{cid}'"
            try:
                cols = {}
                for name in ("time_s", "force_nN", "height_um", "segments"):
                    if name not in g:
                        raise InputError(f"{where}: dataset '{name}' missing")
                    cols[name] = g[name][()]
                amp = g["segment_amplitude_um"][()] if "segment_amplitude_um" in g else None
            except OSError:
                raise InputError(f"{where}: data unreadable (truncated or corrupt file)") from None
            segments = _segments(cols.pop("segments"), amp, where)
            volume = _attr(g, "volume_um3", where, default=np.nan)
            arr = {k: np.asarray(v, float) if np.issubdtype(np.asarray(v).dtype, np.number) else np.asarray(v)
                   for k, v in cols.items()}
            cell = Cell(cell_id=cid, volume_um3=float(volume), segments=segments,
                        volume_source=str(_attr(g, "volume_source", where, "")),
                        spring_constant_N_per_m=float(_attr(g, "spring_constant_N_per_m", where, np.nan)),
                        date=str(_attr(g, "date", where, "")),
                        time_s=arr["time_s"], force_nN=arr["force_nN"], height_um=arr["height_um"])
            cells.append(cell.validate(f"{path}: "))
    return cells
