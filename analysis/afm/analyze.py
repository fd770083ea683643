"""Per cell and frequency: moduli from the oscillations, the tension filter,
the inversion (`analysis.invert.method`: each method's `analyze_cells` lands here).

γ_a = mean over the segments at that frequency of <γ_eff>. Tension filter
(published): the segment means over the whole recording (all frequencies)
stay within 10 % of their median, max |<γ_eff>_i - median| / median ≤ 0.10;
a cell failing it (e.g. blebbing) is excluded with that reason. The K(h̃)
filters and the fit are those of `analysis.invert.inversion`.

`outside_calibration` flags a result whose K̃_S or γ̃_a lies outside the
calibration grid (the law's α-table axes): there ν rests on the log law's
extrapolation (no flag, None, for a law without a table).

`analyze_each` inverts by the law, cell by cell (`analyze_cell`);
`analyze_together` inverts all cells at once by an inversion with 95 % intervals
(the emulator's, `analysis.invert.table.invert_with`); the same filters,
`outside_calibration` then says the fit left the emulator's grid.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from analysis.afm.timeseries import segment_moduli
from analysis.invert.inversion import invert_cell
from analysis.invert.table import CurveInversion, invert_with
from common.errors import InputError

if TYPE_CHECKING:
    from analysis.afm.cell import Cell
    from analysis.calibration.law import Calibration
    from analysis.invert.measurement_errors import MeasurementErrors

TENSION_TOLERANCE = 0.10


def analyze_cell(cell: Cell, calibration: Calibration,
                 bending: str = "standard") -> tuple[list[dict[str, Any]], pd.DataFrame]:
    """Returns (per-frequency rows, per-segment rows) for one cell (InputError without oscillations:
    `analysis.afm.analyze_pipeline.read` sets such recordings aside)."""
    if not cell.oscillations():
        raise InputError(f"cell '{cell.cell_id}': no oscillation segment to analyse")
    segs = pd.DataFrame(segment_moduli(cell))
    segs.insert(0, "cell_id", cell.cell_id)
    med = float(np.median(segs["tension_mN_per_m"]))
    dev = float(np.max(np.abs(segs["tension_mN_per_m"] - med)) / med) if med > 0 else np.inf
    rows = []
    for f, g in segs.groupby("frequency_hz", sort=True):
        tension = float(g["tension_mN_per_m"].mean())
        inv = invert_cell(g["h_tilde"], g["modulus_mN_per_m"], tension, calibration, bending).to_dict()
        if dev > TENSION_TOLERANCE:
            inv["excluded_reason"] = (f"average tension not constant: deviates {100 * dev:.0f} % from its "
                                      f"median {med:.3g} mN/m (limit {100 * TENSION_TOLERANCE:.0f} %)")
        inv["outside_calibration"] = _outside(calibration[bending], inv.get("ks_tilde"), inv.get("gamma_tilde"))
        rows.append({"cell_id": cell.cell_id, "frequency_hz": float(f), "bending": bending,
                     "volume_um3": cell.volume_um3, "tension_mN_per_m": tension,
                     "tension_deviation": dev, "n_segments": len(g),
                     "loss_angle_rad": float(g["loss_angle_rad"].median()), **inv})
    return rows, segs


def _outside(law, ks, gamma):
    if not law.ks_tilde or not law.gamma_tilde or ks is None or gamma is None:
        return None
    if not (np.isfinite(ks) and np.isfinite(gamma)):
        return None
    return bool(not min(law.ks_tilde) <= ks <= max(law.ks_tilde)
                or not min(law.gamma_tilde) <= gamma <= max(law.gamma_tilde))


def analyze_each(cells: list[Cell], calibration: Calibration,
                 bending: str = "standard") -> tuple[pd.DataFrame, pd.DataFrame]:
    """All cells by the law, one at a time: (per cell-and-frequency DataFrame, per-segment DataFrame)."""
    rows, segs = [], []
    for c in cells:
        r, s = analyze_cell(c, calibration, bending)
        rows += r
        segs.append(s)
    return pd.DataFrame(rows), pd.concat(segs, ignore_index=True)


def analyze_together(cells: list[Cell], inversion: CurveInversion, bending: str = "standard",
                     errors: MeasurementErrors | None = None) -> tuple[pd.DataFrame, pd.DataFrame]:
    """All cells at once by `inversion` (with intervals): (per cell-and-frequency DataFrame,
    per-segment DataFrame)."""
    segs, dev = [], {}
    for c in cells:
        s = pd.DataFrame(segment_moduli(c))
        s.insert(0, "cell_id", c.cell_id)
        s["volume_um3"] = c.volume_um3
        med = float(np.median(s["tension_mN_per_m"]))
        dev[c.cell_id] = float(np.max(np.abs(s["tension_mN_per_m"] - med)) / med) if med > 0 else np.inf
        segs.append(s)
    segs = pd.concat(segs, ignore_index=True)
    table = invert_with(inversion, segs, bending, errors)
    table["tension_deviation"] = table["cell_id"].map(dev)
    grouped = segs.groupby(["cell_id", "frequency_hz"])
    idx = pd.MultiIndex.from_frame(table[["cell_id", "frequency_hz"]])
    table["n_segments"] = grouped.size().reindex(idx).to_numpy()
    table["loss_angle_rad"] = grouped["loss_angle_rad"].median().reindex(idx).to_numpy()
    table["outside_calibration"] = table["outside_emulator"]
    bad = table["tension_deviation"] > TENSION_TOLERANCE
    table.loc[bad, "excluded_reason"] = [
        f"average tension not constant: deviates {100 * d:.0f} % from its median (limit "
        f"{100 * TENSION_TOLERANCE:.0f} %)" for d in table.loc[bad, "tension_deviation"]]
    return table, segs.drop(columns=["volume_um3"])
