"""The calibration: everything that turns a measured K(h̃) into moduli, and the file that
holds it, read once per command.

- `law` (SPEC 4: steps 1-4, `Law` per bending variant, `Calibration`) and `law_fits`
  (the law K(h̃) = K_B (1 + α exp(h̃/c)) and its least-squares fits);
- `emulator` (SPEC 9: the spline of the solver's K/K_B);
- `viscoelastic_table` (SPEC 10: the complex-modulus correspondence factor C tabulated);
- `ramp_table` (the shell ramp table of `cortex afm tension` as read: the elastic share of
  the force of the cortex pressed from its free sphere, interpolated; built by
  `analysis.afm.tension.shell_table`);
- `file` (the calibration file: `CalibrationFile` with every part above, `load_calibration`
  its one loader, `build` for `make calibration`); the shipped files are in `data/`;
- `command/` (`cortex analysis calibrate`: the pipeline fitting a law to a store, the
  reconstruction check, the Monte-Carlo error study, figures, report.md).

Public API (imported on first use): `load_calibration(path=None)` -> `CalibrationFile`;
`calibrate(results)` -> (`Calibration`, ...); `Calibration`, `Law`, `Emulator`,
`ComplexTable`, `ComplexModel`, `shipped_path`.
"""

from typing import TYPE_CHECKING

from common.lazy_exports import lazy_exports

if TYPE_CHECKING:
    from analysis.calibration.emulator import Emulator
    from analysis.calibration.file import CalibrationFile, ComplexModel, load_calibration, shipped_path
    from analysis.calibration.law import Calibration, Law, calibrate
    from analysis.calibration.viscoelastic_table import ComplexTable

__all__, __getattr__, __dir__ = lazy_exports(__name__, {
    "load_calibration": "analysis.calibration.file", "CalibrationFile": "analysis.calibration.file",
    "ComplexModel": "analysis.calibration.file", "shipped_path": "analysis.calibration.file",
    "calibrate": "analysis.calibration.law", "Calibration": "analysis.calibration.law",
    "Law": "analysis.calibration.law", "Emulator": "analysis.calibration.emulator",
    "ComplexTable": "analysis.calibration.viscoelastic_table",
})
