"""Instrument recordings (JPK, Bruker NanoScope) -> cells of the native
experiment format (policy: which files, which volume, which dish reference,
which height).

Files: JPK text exports (`.txt`, `.txt.gz`), `.jpk-force`, `.jpk-force-map`,
`.jpk-qi-data`; Bruker NanoScope force curves (`NAME.000`, `.001`, ...) and
their NanoScope Analysis text exports (`.txt`, `.txt.gz`); or folders of
them (not recursive). A text file is told apart by its content (`#` header
lines: JPK). `cell_id` is the file name without its suffix (`.txt`, `.gz`,
the JPK suffixes; a NanoScope file keeps its curve number, `NAME.000`), with
`-px<P>` for pixel P of a map or QI file. The first file that cannot be
read stops an import or an analysis: one line naming it, status 2, nothing
written.

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
grows away from the dish. A NanoScope height is the piezo's travel from an
arbitrary origin (`analysis/afm/formats/bruker/nanoscope.py`): its cell heights need Z.

Volumes: one value for every cell, or a table (CSV with columns `cell_id`,
`volume_um3`, or `equator_radius_um` with `imaged_height_um` (the volume of
the confined droplet of that shape, `solver.geometry.volume_from_image`), or
`diameter_um` of the free cell (V = π d³/6), and optionally
`volume_source`); the cell's `volume_source` says which was used; a cell
without a volume is an error. Segment kinds: approach, pause and retract are kept; JPK's
`modulation` is the native `oscillation`, with its frequency and amplitude.
"""

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pandas as pd

from analysis.afm.cell import Cell, Segment
from analysis.afm.formats.jpk.archive import SUFFIXES, read_archive
from analysis.afm.formats.recording import RecordedSegment, Recording
from common.errors import InputError

TEXT_SUFFIXES = (".txt", ".txt.gz")
NATIVE_KIND = {"approach": "approach", "pause": "pause", "retract": "retract", "modulation": "oscillation"}
NAMES = "JPK (.txt, .txt.gz, " + ", ".join(SUFFIXES) + ") or Bruker NanoScope (.000, .001, ..., or a text export)"


def _name_kind(path: Path) -> str | None:
    """'archive', 'text' or 'nanoscope' by the file's name; None for any other name."""
    from analysis.afm.formats.bruker.nanoscope import is_nanoscope_name
    name = Path(path).name.lower()
    if name.endswith(SUFFIXES):
        return "archive"
    if name.endswith(TEXT_SUFFIXES):
        return "text"
    return "nanoscope" if is_nanoscope_name(path) else None


def is_instrument_file(path: str | Path) -> bool:
    """True for a folder or a file named as a JPK or Bruker NanoScope recording."""
    path = Path(path)
    return path.is_dir() or _name_kind(path) is not None


def read_file(path: str | Path, spring_constant_N_per_m: float | None = None) -> list[Recording]:
    """The recordings of one JPK or NanoScope file. The format is told by the
    file's first bytes (NanoScope header, JPK `#` header lines, else a
    NanoScope Analysis export); `spring_constant_N_per_m` (N/m) serves the
    exports that hold none (NanoScope Analysis)."""
    from analysis.afm.formats.textfiles import head
    path = Path(path)
    kind = _name_kind(path)
    if kind is None:
        raise InputError(f"{path}: not a recording file (expected {NAMES})")
    if not path.is_file():
        raise InputError(f"{path}: no such file")
    if kind == "archive":
        return read_archive(path)
    start = head(path, 4096)
    if start.startswith(b"\\*") or kind == "nanoscope":          # a NanoScope header: \*Force file list
        from analysis.afm.formats.bruker.nanoscope import read_nanoscope
        return [read_nanoscope(path)]
    if start.lstrip().startswith(b"#"):
        from analysis.afm.formats.jpk.text import read_jpk_recording
        return [read_jpk_recording(path)]
    from analysis.afm.formats.bruker.text import read_nanoscope_text
    return [read_nanoscope_text(path, spring_constant_N_per_m)]


def read_recordings(paths: Sequence[str | Path], spring_constant_N_per_m: float | None = None) -> list[Recording]:
    """Every recording of `paths` (files, or folders of them: not recursive), cell ids unique.
    The first file that cannot be read stops it (InputError, one line)."""
    recs = []
    for p in map(Path, paths):
        if p.is_dir():
            files = sorted(f for f in p.iterdir() if f.is_file() and _name_kind(f) is not None)
            if not files:
                raise InputError(f"{p}: folder holds no recording file ({NAMES})")
            for f in files:
                recs += read_file(f, spring_constant_N_per_m)
        elif not p.exists():
            raise InputError(f"{p}: no such file or folder")
        else:
            recs += read_file(p, spring_constant_N_per_m)
    seen: dict[str, str] = {}
    for r in recs:
        if r.cell_id in seen:
            raise InputError(f"cell id '{r.cell_id}' twice ({seen[r.cell_id]} and {r.source})")
        seen[r.cell_id] = r.source
    return recs


def _table_volume(row: dict[str, Any], name: str) -> tuple[float, str] | None:
    """(V µm³, how) of one table row: volume_um3, else equator_radius_um at
    imaged_height_um (the confined droplet of that shape), else diameter_um of
    the free cell (V = π d³/6); None where the row gives none of them."""
    from solver.geometry import volume_from_image
    v, r, h, d = (row.get(c, np.nan) for c in ("volume_um3", "equator_radius_um", "imaged_height_um",
                                                "diameter_um"))
    if np.isfinite(v):
        return v, f"table {name}"
    if np.isfinite(r) and np.isfinite(h):
        try:
            return volume_from_image(h, r), f"equator radius {r:g} um at imaged height {h:g} um (table {name})"
        except InputError as err:
            raise InputError(f"{name}: cell '{row['cell_id']}': {err}") from None
    if np.isfinite(d):
        return np.pi * d**3 / 6.0, f"free-cell diameter {d:g} um (table {name})"
    return None


def read_volumes(path: str | Path) -> dict[str, tuple[float, str]]:
    """{cell_id: (volume_um3, volume_source)} from a CSV table: per cell a
    `volume_um3`, or `equator_radius_um` with `imaged_height_um`, or
    `diameter_um` (in that order of precedence). The source is the table's
    `volume_source` (else the table's name) for a volume_um3, and says which
    measure gave any other volume, after the table's own source."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: volume table not found (or not a file)")
    try:
        df = pd.read_csv(path, dtype={"cell_id": str})
    except (UnicodeDecodeError, pd.errors.ParserError, pd.errors.EmptyDataError) as err:
        raise InputError(f"{path}: not a readable CSV table ({str(err).splitlines()[0]})") from None
    ways = ("volume_um3", "equator_radius_um", "diameter_um")
    if "cell_id" not in df.columns or not any(c in df.columns for c in ways):
        raise InputError(f"{path}: columns cell_id and one of volume_um3, equator_radius_um (with "
                         f"imaged_height_um), diameter_um needed (has {', '.join(map(str, df.columns))})")
    if "equator_radius_um" in df.columns and "imaged_height_um" not in df.columns:
        raise InputError(f"{path}: equator_radius_um needs the column imaged_height_um")
    for c in ways + ("imaged_height_um",):
        if c in df.columns:
            df[c] = pd.to_numeric(df[c], errors="coerce")
    dup = df["cell_id"][df["cell_id"].duplicated()]
    if len(dup):
        raise InputError(f"{path}: cell '{dup.iloc[0]}' listed twice")
    table = {}
    for row in df.to_dict("records"):
        found = _table_volume(row, path.name)
        if found is None or not found[0] > 0:
            raise InputError(f"{path}: cell '{row['cell_id']}' has no positive volume_um3, equator_radius_um "
                             "with imaged_height_um, or diameter_um")
        given = row.get("volume_source")
        given = given.strip() if isinstance(given, str) else ""
        measured = np.isfinite(row.get("volume_um3", np.nan))
        source = (given or found[1]) if measured else f"{given}: {found[1]}" if given else found[1]
        table[row["cell_id"]] = (float(found[0]), source)
    return table


def wedge_height_um(segment: RecordedSegment, spring_constant_N_per_m: float) -> npt.NDArray[np.float64]:
    """z + F/k (µm) of every sample: the height of the (bent) cantilever's wedge."""
    return segment.height_um + 1e-3 * segment.force_nN / spring_constant_N_per_m


def dish_from_curve(path: str | Path) -> float:
    """Z (µm) from a force curve on the bare dish: z + F/k where its approach force is largest."""
    recs = read_recordings([path])
    if len(recs) != 1:
        raise InputError(f"{path}: a dish curve must hold one recording (has {len(recs)})")
    rec = recs[0]
    app = [s for s in rec.segments if s.kind == "approach" and s.n_samples]
    if not app:
        raise InputError(f"{path}: dish curve without an approach segment")
    best = max(app, key=lambda s: s.force_nN.max())
    i = int(np.argmax(best.force_nN))
    return float(wedge_height_um(best, rec.spring_constant_N_per_m)[i])


def to_cell(rec: Recording, volume_um3: float, volume_source: str, dish_um: float = 0.0,
            dish_known: bool = True, untimed: bool = False) -> Cell:
    """One recording as a native `Cell` (h = z + F/k - Z), validated; with `dish_known` False
    (no dish reference) the heights are not checked to be gaps; with `untimed` a recording
    without sample times is kept (`Cell.timed` False) instead of refused."""
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
    timed = not np.isnan(t).any()
    if not timed and not untimed:
        raise InputError(f"{rec.source}: cell '{rec.cell_id}': sample times unknown (a NanoScope Analysis "
                         "export without the NanoScope file it was exported from beside it; afm tension reads "
                         "its ramp)")
    if dish_known and np.min(h) <= 0:
        raise InputError(f"{rec.source}: cell '{rec.cell_id}': height z + F/k - Z reaches {np.min(h):.4g} um "
                         f"with dish reference Z = {dish_um:g} um: give the dish with --dish-height-um or "
                         "--dish-curve")
    cell = Cell(cell_id=rec.cell_id, volume_um3=float(volume_um3), time_s=t, force_nN=f, height_um=h,
                segments=segs, volume_source=volume_source,
                spring_constant_N_per_m=float(rec.spring_constant_N_per_m), date=rec.date, dish_known=dish_known,
                timed=timed)
    return cell.validate(f"{rec.source}: ")
