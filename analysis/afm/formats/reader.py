"""The one reader of recordings: `open(paths, ImportOptions) -> list[Cell]`, what `cortex afm
import`, `afm analyze` and `afm tension` read their files with.

paths    one experiment (.h5/.hdf5) or single-cell CSV (volumes and heights their own;
         the import options are refused for them), or JPK and Bruker NanoScope files and
         folders of them (`instruments.read_recordings`; not a mixture of both kinds);
volume   of an instrument recording, in this order: `volumes_csv` (`instruments.read_volumes`),
         `volume_um3` (one for every cell), `radius_um` (a free cell, V = 4πR³/3);
height   h = z + F/k - Z (`instruments.to_cell`), Z the dish reference: `dish_um`, or from
         `dish_curve` (`instruments.dish_from_curve`), else 0, the height channel taken as the
         gap and checked for it (h > 0); with `contact_heights` a recording without a dish
         reference keeps the channel unchecked (`Cell.dish_known` False), for `afm tension` to
         refer it to the approach's contact point;
times    with `untimed_ramps` a recording whose file holds no sample times (a NanoScope
         Analysis export without its NanoScope file) is read with NaN times (`Cell.timed`
         False: `afm tension` fits its ramps, which need none); refused otherwise.

Every instrument cell keeps the file it came from (`Cell.source`) and what the file said of
the recording (`Cell.recorded`, `Recording.summary`: `afm import`'s lines). The first file
that cannot be read stops the reading (InputError, one line naming it).
"""

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from analysis.afm.cell import Cell
from common.errors import InputError

NATIVE = (".h5", ".hdf5", ".csv")       # the native formats: one file, volumes and heights its own


@dataclass(frozen=True)
class ImportOptions:
    """How to read instrument recordings: one of the volume sources, the dish reference, the
    spring constant of exports that hold none, whether heights may stay unreferenced, and
    whether a recording without sample times is read (its ramps only: `Cell.timed` False)."""

    volume_um3: float | None = None
    volumes_csv: str | None = None
    radius_um: float | None = None
    dish_um: float | None = None
    dish_curve: str | None = None
    spring_constant_N_per_m: float | None = None
    contact_heights: bool = False
    untimed_ramps: bool = False

    def given(self) -> list[str]:
        """The options of instrument files that are given, as the command line names them."""
        flags = {"--volume": self.volume_um3, "--volumes": self.volumes_csv, "--radius-um": self.radius_um,
                 "--dish-height-um": self.dish_um, "--dish-curve": self.dish_curve,
                 "--spring-constant": self.spring_constant_N_per_m}
        return [flag for flag, value in flags.items() if value is not None]

    def check(self) -> "ImportOptions":
        """Itself; InputError (one line) for a volume, radius or spring constant not a positive number."""
        for name, value, unit in (("--volume", self.volume_um3, "um^3"), ("--radius-um", self.radius_um, "um"),
                                  ("--spring-constant", self.spring_constant_N_per_m, "N/m")):
            if value is not None and not (np.isfinite(value) and value > 0):
                raise InputError(f"{name} must be a positive number of {unit} (got {value})")
        return self


def open(paths: str | Path | Sequence[str | Path], options: ImportOptions = ImportOptions()) -> list[Cell]:
    """The cells of `paths`: one experiment or single-cell CSV, or instrument files and folders."""
    from analysis.afm.formats.instruments import is_instrument_file
    paths = [paths] if isinstance(paths, (str, Path)) else list(paths)
    options.check()
    if all(is_instrument_file(p) for p in paths):
        return _instrument_cells(paths, options)
    if len(paths) != 1:
        raise InputError("give one experiment (.h5) or CSV file, or JPK or Bruker files and folders (not a mixture)")
    path = Path(paths[0])
    if options.given():
        raise InputError(f"{path}: {', '.join(options.given())} given: the import options apply to instrument "
                         "files only; the experiment and CSV formats carry their own volumes and heights")
    suffix = path.suffix.lower()
    if suffix in (".h5", ".hdf5"):
        from analysis.afm.formats.h5 import read_experiment
        cells = read_experiment(path)
    elif suffix == ".csv":
        from analysis.afm.formats.csvcell import read_csv_cell
        cells = [read_csv_cell(path)]
    else:
        raise InputError(f"{path}: unknown recording format '{suffix}' (expected .h5, .hdf5, .csv, "
                         "a JPK or Bruker file or a folder of them)")
    for c in cells:
        c.source = str(path)
    return cells


def _volume(cell_id: str, options: ImportOptions, table: dict[str, tuple[float, str]] | None) -> tuple[float, str]:
    """(V µm³, how it was obtained) of one recording."""
    if table is not None:
        if cell_id not in table:
            raise InputError(f"{options.volumes_csv}: no volume for cell '{cell_id}'")
        return table[cell_id]
    if options.volume_um3 is not None:
        return options.volume_um3, "one value for every cell (--volume)"
    if options.radius_um is not None:
        return 4.0 * np.pi * options.radius_um ** 3 / 3.0, f"free-cell radius {options.radius_um:g} um (--radius-um)"
    ways = "--volume UM3, --volumes TABLE.csv or --radius-um R" if options.contact_heights else \
        "--volumes TABLE.csv or --volume UM3"
    raise InputError(f"no volume for cell '{cell_id}': give {ways}")


def _instrument_cells(paths: Sequence[str | Path], options: ImportOptions) -> list[Cell]:
    """Cells of JPK and Bruker files (`instruments`), each with its volume and height."""
    from analysis.afm.formats.instruments import dish_from_curve, read_recordings, read_volumes, to_cell
    recs = read_recordings(paths, options.spring_constant_N_per_m)
    dish = dish_from_curve(options.dish_curve) if options.dish_curve is not None else options.dish_um
    table = read_volumes(options.volumes_csv) if options.volumes_csv is not None else None
    cells = []
    for r in recs:
        volume, how = _volume(r.cell_id, options, table)
        known = dish is not None or not options.contact_heights
        cell = to_cell(r, volume, how, dish or 0.0, dish_known=known, untimed=options.untimed_ramps)
        cell.source, cell.recorded = r.source or str(paths[0]), r.summary()
        cells.append(cell)
    return cells
