"""Analysis of campaign stores: calibration laws (SPEC 4), the per-cell
inversion (SPEC 6) shared with the measured cells, the reconstruction check,
the Monte-Carlo error study (SPEC 5), figures and reports.

Modules: `calibration/` (everything a measured K(h̃) is read with: the law and its
fits, the emulator, the complex-modulus table, the calibration file with its one
loader, and `cortex analysis calibrate`'s pipeline under `calibration/command/`),
`invert/` (the `Inversion` interface with the law and the emulator as its two
implementations, the intervals, the table of curves), `viscoelastic_fit` (the
complex modulus of a cell), `viscosity`, `synthetic` (store tables generated from
the laws, for tests and benchmarks), `afm/`.

Public API (imported on first use):

- `calibrate(results)` -> `Calibration` (a `Law` per bending variant), from
  `campaign.read_results(store)`.
- `load_calibration(path=None)` -> `CalibrationFile` (its `calibration`, `emulator`,
  `provenance`, the viscoelastic reading's `viscoelastic` and the tension analysis's
  `shell_ramp`, `sources`: where each part came from): a calibration bundle, by default the one
  shipped in the package (`shipped_path()`); it holds only the parts it embeds or names.
- `invert_cell(h_tilde, K, gamma_a, calibration, bending)` -> `CellInversion`
  (ν of one cell by the law); `invert_rows(rows, method, ...)`: a table of
  K(h̃) per cell by either method, with 95 % intervals (`MeasurementErrors`); `METHODS`,
  the inversion methods.
"""

from typing import TYPE_CHECKING

from common.lazy_exports import lazy_exports

if TYPE_CHECKING:
    from analysis.calibration.command.reconstruction import reconstruct
    from analysis.calibration.emulator import Emulator
    from analysis.calibration.file import CalibrationFile, load_calibration, shipped_path
    from analysis.calibration.law import Calibration, Law, calibrate
    from analysis.invert.measurement_errors import MeasurementErrors
    from analysis.invert.inversion import CellInversion, invert_cell
    from analysis.invert.method import invert_rows
    from analysis.invert.table import METHODS

__all__, __getattr__, __dir__ = lazy_exports(__name__, {
    "calibrate": "analysis.calibration.law", "Calibration": "analysis.calibration.law",
    "Law": "analysis.calibration.law", "load_calibration": "analysis.calibration.file",
    "CalibrationFile": "analysis.calibration.file", "shipped_path": "analysis.calibration.file",
    "Emulator": "analysis.calibration.emulator",
    "invert_cell": "analysis.invert.inversion", "CellInversion": "analysis.invert.inversion",
    "invert_rows": "analysis.invert.method", "MeasurementErrors": "analysis.invert.measurement_errors", "METHODS": "analysis.invert.table",
    "reconstruct": "analysis.calibration.command.reconstruction",
})
