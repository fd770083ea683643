"""JPK recordings -> cells of the native experiment format (policy: which
files, which volume, which dish reference, which height).

Files: JPK text exports (`.txt`), `.jpk-force`, `.jpk-force-map`,
`.jpk-qi-data`, or folders of them (not recursive). `cell_id` is the file
name without its suffix, with `-px<P>` for pixel P of a map or QI file.

Cell height. The height channel z (µm) is the cantilever's position; a
compressive force F (nN) bends the cantilever up by d = F / k (k in N/m:
d = 10⁻³ F / k µm), which lifts the wedge that touches the cell. With Z
the height at which the unbent cantilever would touch the bare dish,

    h = z + F / k - Z.

Z is `--dish-height-um`, or from `--dish-curve FILE` (a force curve pressed
onto the bare dish): Z = z + F/k at the sample of largest force of its
approach segments, where the wedge rests on the dish; without either, Z = 0
(the height channel already measured from the dish). On the real files the
force rises as z falls in every approach segment (a test checks it), so z
grows away from the dish.

Volumes: one value for every cell, or a table (CSV with columns `cell_id`,
`volume_um3` and optionally `volume_source`); a cell without a volume is an
error. Segment kinds: approach, pause and retract are kept; JPK's
`modulation` is the native `oscillation`, with its frequency and amplitude.
"""

from pathlib import Path

import numpy as np
import pandas as pd

from analysis.afm.cell import Cell, Segment
from analysis.afm.jpk_archive import SUFFIXES, read_archive
from solver.errors import InputError

TEXT_SUFFIXES = (".txt",)
NATIVE_KIND = {"approach": "approach", "pause": "pause", "retract": "retract", "modulation": "oscillation"}


def is_jpk(path):
    """True for a folder or a file with a JPK suffix."""
    path = Path(path)
    return path.is_dir() or path.suffix.lower() in SUFFIXES + TEXT_SUFFIXES


def read_file(path):
    """The recordings of one JPK file."""
    path = Path(path)
    if path.suffix.lower() in TEXT_SUFFIXES:
        from analysis.afm.jpk import read_jpk_recording
        return [read_jpk_recording(path)]
    if path.suffix.lower() in SUFFIXES:
        return read_archive(path)
    raise InputError(f"{path}: not a JPK file (expected {', '.join(TEXT_SUFFIXES + SUFFIXES)})")


def read_recordings(paths):
    """Every recording of `paths` (files or folders of JPK files), cell ids unique."""
    recs = []
    for p in map(Path, paths):
        if p.is_dir():
            files = sorted(f for f in p.iterdir() if f.is_file() and f.suffix.lower() in SUFFIXES + TEXT_SUFFIXES)
            if not files:
                raise InputError(f"{p}: folder holds no JPK file ({', '.join(TEXT_SUFFIXES + SUFFIXES)})")
            for f in files:
                recs += read_file(f)
        elif not p.exists():
            raise InputError(f"{p}: no such file or folder")
        else:
            recs += read_file(p)
    seen = {}
    for r in recs:
        if r.cell_id in seen:
            raise InputError(f"cell id '{r.cell_id}' twice ({seen[r.cell_id]} and {r.source})")
        seen[r.cell_id] = r.source
    return recs


def read_volumes(path):
    """{cell_id: (volume_um3, volume_source)} from a CSV table."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: volume table not found (or not a file)")
    try:
        df = pd.read_csv(path, dtype={"cell_id": str})
    except (UnicodeDecodeError, pd.errors.ParserError, pd.errors.EmptyDataError) as err:
        raise InputError(f"{path}: not a readable CSV table ({str(err).splitlines()[0]})") from None
    if not {"cell_id", "volume_um3"} <= set(df.columns):
        raise InputError(f"{path}: columns cell_id and volume_um3 needed (has {', '.join(map(str, df.columns))})")
    vol = pd.to_numeric(df["volume_um3"], errors="coerce")
    bad = df["cell_id"][~(vol > 0)]
    if len(bad):
        raise InputError(f"{path}: volume_um3 of cell '{bad.iloc[0]}' is not a positive number")
    dup = df["cell_id"][df["cell_id"].duplicated()]
    if len(dup):
        raise InputError(f"{path}: cell '{dup.iloc[0]}' listed twice")
    src = df["volume_source"].fillna("").astype(str) if "volume_source" in df else [f"table {path.name}"] * len(df)
    return {c: (float(v), s) for c, v, s in zip(df["cell_id"], vol, src)}


def wedge_height_um(segment, spring_constant_N_per_m):
    """z + F/k (µm) of every sample: the height of the (bent) cantilever's wedge."""
    return segment.height_um + 1e-3 * segment.force_nN / spring_constant_N_per_m


def dish_from_curve(path):
    """Z (µm) from a force curve on the bare dish: z + F/k where its approach force is largest."""
    rec = read_recordings([path])
    if len(rec) != 1:
        raise InputError(f"{path}: a dish curve must hold one recording (has {len(rec)})")
    rec = rec[0]
    app = [s for s in rec.segments if s.kind == "approach" and s.n_samples]
    if not app:
        raise InputError(f"{path}: dish curve without an approach segment")
    best = max(app, key=lambda s: s.force_nN.max())
    i = int(np.argmax(best.force_nN))
    return float(wedge_height_um(best, rec.spring_constant_N_per_m)[i])


def to_cell(rec, volume_um3, volume_source, dish_um=0.0):
    """One recording as a native `Cell` (h = z + F/k - Z), validated."""
    segs, parts, n0 = [], [], 0
    for s in rec.segments:
        if not s.n_samples:
            continue
        segs.append(Segment(NATIVE_KIND[s.kind], n0, n0 + s.n_samples, s.frequency_hz, s.amplitude_um))
        parts.append((s.time_s, s.force_nN, wedge_height_um(s, rec.spring_constant_N_per_m) - dish_um))
        n0 += s.n_samples
    if not parts:
        raise InputError(f"{rec.source}: cell '{rec.cell_id}': no samples in any segment")
    t, f, h = (np.concatenate(c) for c in zip(*parts))
    if np.min(h) <= 0:
        raise InputError(f"{rec.source}: cell '{rec.cell_id}': height z + F/k - Z reaches {np.min(h):.4g} um "
                         f"with dish reference Z = {dish_um:g} um: give the dish with --dish-height-um or "
                         "--dish-curve")
    cell = Cell(cell_id=rec.cell_id, volume_um3=float(volume_um3), time_s=t, force_nN=f, height_um=h,
                segments=segs, volume_source=volume_source,
                spring_constant_N_per_m=float(rec.spring_constant_N_per_m), date=rec.date)
    return cell.validate(f"{rec.source}: ")


def import_cells(paths, volume_um3=None, volumes_csv=None, dish_um=None, dish_curve=None):
    """(recordings, cells) of JPK files, every cell with its volume and height."""
    recs = read_recordings(paths)
    if dish_curve is not None:
        dish_um = dish_from_curve(dish_curve)
    table = read_volumes(volumes_csv) if volumes_csv is not None else None
    cells = []
    for r in recs:
        if table is not None:
            if r.cell_id not in table:
                raise InputError(f"{volumes_csv}: no volume for cell '{r.cell_id}'")
            vol, src = table[r.cell_id]
        elif volume_um3 is not None:
            vol, src = volume_um3, "one value for every cell (--volume)"
        else:
            raise InputError(f"no volume for cell '{r.cell_id}': give --volumes TABLE.csv or --volume UM3")
        cells.append(to_cell(r, vol, src, dish_um or 0.0))
    return recs, cells
