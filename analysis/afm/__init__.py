"""Measured cells (SPEC 6): AFM recording formats, synthetic recordings,
per-cell inversion and population statistics.

Public API (imported on first use):

- `read_experiment(path)` / `write_experiment(path, cells)`: the native
  experiment file (HDF5) of `Cell`s; `open(paths, ImportOptions(...))` (the one
  reader, in `analysis.afm.formats`): cells from an experiment, a single-cell CSV,
  or JPK or Bruker files and folders, as every `cortex afm` command reads them.
- `synthesize(n_cells, seed, errors, forward)` -> (cells, truth): synthetic recordings, as `cortex afm synth`.
- `analyze_experiment(data, calibration_file, out, AnalyzeSettings(bending, method,
  errors, import_options))`: the whole `cortex afm analyze` into a folder, with the
  calibration file's parts (`analysis.calibration.load_calibration`); the cells alone
  by a method: `analysis.invert.method.choose(...).analyze_cells(...)`;
  `population_summary(table)`.
"""

from typing import TYPE_CHECKING

from common.lazy_exports import lazy_exports

if TYPE_CHECKING:           # what the type checker sees of the names below
    from analysis.afm.analyze import analyze_cell
    from analysis.afm.analyze_pipeline import Settings as AnalyzeSettings, run as analyze_experiment
    from analysis.afm.cell import Cell, Segment
    from analysis.afm.formats.h5 import read_experiment, write_experiment
    from analysis.afm.population.summary import summary as population_summary
    from analysis.afm.synth.cells import generate as synthesize

__all__, __getattr__, __dir__ = lazy_exports(__name__, {
    "Cell": "analysis.afm.cell", "Segment": "analysis.afm.cell",
    "read_experiment": "analysis.afm.formats.h5", "write_experiment": "analysis.afm.formats.h5",
    "synthesize": "analysis.afm.synth.cells:generate",
    "analyze_cell": "analysis.afm.analyze",
    "analyze_experiment": "analysis.afm.analyze_pipeline:run", "AnalyzeSettings": "analysis.afm.analyze_pipeline:Settings",
    "population_summary": "analysis.afm.population.summary:summary",
})
