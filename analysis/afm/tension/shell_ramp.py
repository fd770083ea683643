"""The shell ramp model: the force of an elastic cortex (SPEC 2) pressed from its
free sphere, the droplet's force plus the elastic share read from a table of the
solver (`analysis.calibration.ramp_table`).

A cell of radius R, active tension γ_a, moduli K_B and K_S = K̃_S K_B, at
deformation δ of its free sphere (δ ≥ 0; 0 above the contact):

    F(δ) = γ_a R ĝ(δ/R) + K_B R e(δ/R, γ̃_a, K̃_S, R),   γ̃_a = γ_a / K_B,

with ĝ the droplet's unit force (`solver.droplet_table`: the tension alone,
exact) and e = f - γ̃_a ĝ the elastic stress's share of the table's
f = F/(K_B R) (`ramp_table.ShellTable.elastic`: how it is interpolated, and
held at the table's edges). A cell with K_B = 0 is the droplet, exactly.

The table is the calibration bundle's (`CalibrationFile.shell_ramp`, the one loader
`analysis.calibration.file.load_calibration`), passed down the reading as an argument
(`shell_fit.Fixed.table`, `ShellFit.table`; `cortex afm tension --calibration`'s is chosen by
`tension.calibration_parts`); None stands for the shipped bundle's, resolved here alone (`resolve`).
"""

from functools import lru_cache

import numpy as np
import numpy.typing as npt

from analysis.calibration.ramp_table import ShellTable
from solver.droplet_table import DEPTH_MAX, unit_force_per_tension


def force_nN(depth_um: npt.ArrayLike, radius_um: float, tension_mN_per_m: float, bulk_mN_per_m: float,
             shear_tilde: float, table: ShellTable | None = None) -> np.ndarray:
    """F (nN) of the shell (module doc) at deformations δ (µm; ≤ 0: no contact);
    `table` the shell ramp table (None: the shipped one, `resolve`)."""
    t = resolve(table)
    d = np.clip(np.asarray(depth_um, float), 0.0, None) / radius_um
    out = tension_mN_per_m * radius_um * unit_force_per_tension(np.minimum(d, DEPTH_MAX))   # as `ramp`
    if bulk_mN_per_m > 0:
        out = out + bulk_mN_per_m * radius_um * t.elastic(d, tension_mN_per_m / bulk_mN_per_m, shear_tilde,
                                                               radius_um)
    return out


def resolve(table: ShellTable | None) -> ShellTable:
    """`table`, or where None the shipped bundle's: the one place the default is read."""
    return shipped() if table is None else table


@lru_cache(maxsize=1)
def shipped() -> ShellTable:
    """The shell ramp table of the shipped calibration file (read once, by its one loader)."""
    from analysis.calibration.file import load_calibration
    return load_calibration(None).shell_ramp
