"""Measured cells (SPEC 6): AFM recording formats, synthetic recordings,
per-cell inversion and population statistics.

Public API (imported on first use):

- `read_experiment(path)` / `write_experiment(path, cells)`: the native
  experiment file (HDF5) of `Cell`s; `load_cells(paths)`: cells from an
  experiment, a single-cell CSV, or JPK or Bruker files and folders.
- `import_cells(paths, volume_um3=..., volumes_csv=...)`: JPK and Bruker
  NanoScope files -> (recordings, cells), as `cortex afm import`.
- `synthesize(n_cells, seed, errors, forward)` -> (cells, truth): synthetic recordings, as `cortex afm synth`.
- `analyze_cells(cells, calibration, bending, method, ...)` -> (per-cell
  table, per-segment table); `analyze_experiment(data, calibration_file, out,
  AnalyzeSettings(bending, method, errors, jpk_options))`: the whole `cortex afm
  analyze` into a folder; `population_summary(table)`.
"""

from typing import TYPE_CHECKING

from common.lazy_exports import lazy_exports

if TYPE_CHECKING:           # what the type checker sees of the names below
    from analysis.afm.analyze_pipeline import analyze as analyze_cells
    from analysis.afm.analyze_pipeline import Settings as AnalyzeSettings, load as load_cells, run as analyze_experiment
    from analysis.afm.cell import Cell, Segment
    from analysis.afm.formats.h5 import read_experiment, write_experiment
    from analysis.afm.formats.instruments import import_cells
    from analysis.afm.population.summary import summary as population_summary
    from analysis.afm.synth.cells import generate as synthesize

__all__, __getattr__, __dir__ = lazy_exports(__name__, {
    "Cell": "analysis.afm.cell", "Segment": "analysis.afm.cell",
    "read_experiment": "analysis.afm.formats.h5", "write_experiment": "analysis.afm.formats.h5",
    "load_cells": "analysis.afm.analyze_pipeline:load", "import_cells": "analysis.afm.formats.instruments",
    "synthesize": "analysis.afm.synth.cells:generate",
    "analyze_cells": "analysis.afm.analyze_pipeline:analyze",
    "analyze_experiment": "analysis.afm.analyze_pipeline:run", "AnalyzeSettings": "analysis.afm.analyze_pipeline:Settings",
    "population_summary": "analysis.afm.population.summary:summary",
})
