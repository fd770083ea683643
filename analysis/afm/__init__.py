"""Measured cells (SPEC 6): AFM recording formats, synthetic recordings,
per-cell inversion and population statistics.

Public API (imported on first use):

- `read_experiment(path)` / `write_experiment(path, cells, provenance)`: the native
  experiment file (HDF5) of `Cell`s and how they were made (`analysis.afm.provenance`:
  `MEASURED`, `FREQUENCY_DOMAIN`, `time_domain(...)`; `read_provenance(path)`); `open(paths, ImportOptions(...))` (the one
  reader, in `analysis.afm.formats`): cells from an experiment, a single-cell CSV,
  or JPK or Bruker files and folders, as every `cortex afm` command reads them.
- `protocol_of(cell, wait_s=None)`: the `solver.protocol.Protocol` a recording went through,
  read off its samples and segments (`analysis.afm.recorded_protocol`).

Every public name is its definition's own. The commands' pipelines are used as modules:
`analysis.afm.synth.cells.generate(n_cells, seed, errors, forward)` -> (cells, truth)
(`cortex afm synth`); `analysis.afm.analyze_pipeline.run(data, calibration_file, out,
Settings(bending, method, errors, import_options))` (the whole `cortex afm analyze` into
a folder, with the parts of the calibration file `analysis.calibration.load_calibration`
read); the cells alone: `analysis.afm.analyze.measure(cells)` (their curves, once), then
`analysis.invert.method.choose(...).invert(curves, bending, errors)` and `analysis.afm.analyze.cell_table`;
`analysis.afm.population.summary.summary(table)`.
"""

from typing import TYPE_CHECKING

from common.lazy_exports import lazy_exports

if TYPE_CHECKING:           # what the type checker sees of the names below
    from analysis.afm.cell import Cell, Segment
    from analysis.afm.formats.h5 import read_experiment, write_experiment
    from analysis.afm.recorded_protocol import protocol_of

__all__, __getattr__, __dir__ = lazy_exports(__name__, {
    "Cell": "analysis.afm.cell", "Segment": "analysis.afm.cell",
    "read_experiment": "analysis.afm.formats.h5", "write_experiment": "analysis.afm.formats.h5",
    "protocol_of": "analysis.afm.recorded_protocol",
})
