"""The per-cell inversion of K(h̃) curves (`curves.Curves`) into ν (SPEC 6, 9): one
interface (`method.Inversion`, `invert(curves, bending, errors)` -> table) with two
implementations, the paper's law (`inversion`) and the emulator (`emulator_fit`, with
the 95 % intervals of `intervals` from the measurement errors of `measurement_errors`);
`table` inverts a long table of curves, `table_input` reads the one `cortex analysis
invert` takes.

Public API (imported on first use): `INVERSIONS` (method name -> `Inversion`
class), `choose(method, calibration, emulator)`, `invert_rows(rows, method, ...)`,
`invert_with(inversion, rows, ...)`, `curves_of(rows)`, `Curves`, `invert_cell`, `MeasurementErrors`.
"""

from common.lazy_exports import lazy_exports

__all__, __getattr__, __dir__ = lazy_exports(__name__, {
    "Inversion": "analysis.invert.method", "LawInversion": "analysis.invert.method",
    "EmulatorInversion": "analysis.invert.method", "INVERSIONS": "analysis.invert.method",
    "choose": "analysis.invert.method", "invert_rows": "analysis.invert.method",
    "invert_with": "analysis.invert.table", "invert_cell": "analysis.invert.inversion",
    "CellInversion": "analysis.invert.inversion", "MeasurementErrors": "analysis.invert.measurement_errors",
    "Curves": "analysis.invert.curves", "curves_of": "analysis.invert.curves",
})
