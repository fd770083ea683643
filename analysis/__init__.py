"""Analysis of campaign stores: calibration laws (SPEC 4), the per-cell
inversion (SPEC 6) shared with the measured cells, the reconstruction check,
the Monte-Carlo error study (SPEC 5), figures and reports.

Modules: `laws` (the law and its fits), `calibration` (steps 1-4, the
`Calibration` file), `emulator` (the spline of the solver's K/K_B), `shipped`
(the calibration file: law and emulator, read once), `calibrate/` (`cortex
analysis calibrate`: pipeline, reconstruction check, Monte-Carlo study, figures,
report), `invert/` (the `Inversion` interface with the law and the emulator as
its two implementations, the intervals, the table of curves), `viscoelastic_table`
and `viscoelastic_fit` (the complex modulus), `viscosity`, `cli`, `synthetic`
(store tables generated from the laws, for tests and benchmarks), `afm/`.

Public API (imported on first use):

- `calibrate(results)` -> `Calibration` (a `Law` per bending variant), from
  `campaign.read_results(store)`; `Calibration.load(path)`.
- `load_calibration(path=None)` -> (Calibration or None, Emulator or None,
  provenance): a calibration file, by default the one shipped in the package
  (`shipped_path()`).
- `invert_cell(h_tilde, K, gamma_a, calibration, bending)` -> `CellInversion`
  (ν of one cell by the law); `invert_rows(rows, method, ...)`: a table of
  K(h̃) per cell by either method, with 95 % intervals (`Errors`); `METHODS`,
  the inversion methods.
"""

from typing import TYPE_CHECKING

from common.lazy_exports import lazy_exports

if TYPE_CHECKING:
    from analysis.calibrate.reconstruction import reconstruct
    from analysis.calibration import Calibration, Law, calibrate
    from analysis.emulator import Emulator
    from analysis.invert.intervals import Errors
    from analysis.invert.inversion import CellInversion, invert_cell
    from analysis.invert.method import invert_rows
    from analysis.invert.table import METHODS
    from analysis.shipped import load as load_calibration
    from analysis.shipped import shipped_path

__all__, __getattr__, __dir__ = lazy_exports(__name__, {
    "calibrate": "analysis.calibration", "Calibration": "analysis.calibration", "Law": "analysis.calibration",
    "load_calibration": "analysis.shipped:load", "shipped_path": "analysis.shipped",
    "Emulator": "analysis.emulator",
    "invert_cell": "analysis.invert.inversion", "CellInversion": "analysis.invert.inversion",
    "invert_rows": "analysis.invert.method", "Errors": "analysis.invert.intervals", "METHODS": "analysis.invert.table",
    "reconstruct": "analysis.calibrate.reconstruction",
})
