"""The protocol-aware reading: each segment corrected for the stress its cell carries (SPEC 10, 12).

The relaxed-state reading assumes each oscillation about the relaxed droplet at its mean height.
A power-law cortex keeps part of every earlier step's stress (`solver.carried_state`). For each
oscillation segment j of a cell its history is read off the recording (`histories`):

- h_ref, the stress-free height: the height just before the cell's first approach, at most the
  cell's diameter 2R (a recording that starts out of contact is referenced to the free sphere);
- the steps k before j: Δh_k (h_ref → h_1 → h_2 ... the mean heights of the segments after each
  step) and their ages t_j - t_k at the segment's middle (t_k the step's end,
  `analysis.afm.waits.step_end_s`); with a wait S given (`afm analyze --wait-s S`), t_k is S
  before the first oscillation after step k. Without S, a segment whose step held its height
  less than MIN_HOLD_S before its first oscillation has no recorded wait: no history (None).

Given the cell's fitted moduli at f (|K_B*|, δ_B, |K_S*|, δ_S) and γ_a, `correct` computes per
segment K_eff = Σ_k K(t_j - t_k) Δh_k / Σ Δh_k of each modulus (the power law the fit at f
implies, `solver.carried_state.power_law_relaxation`) and (c, Δγ) of
`solver.carried_state.carried_correction`, and returns the segments as the relaxed model would
have seen them: |K| / |c|, δ - arg c, <γ_eff> - Δγ, with the factors in their own columns
(`protocol_modulus_factor`, `protocol_phase_rad`, `protocol_tension_shift_mN_per_m`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt
import pandas as pd
from tqdm import tqdm

from analysis.afm.waits import step_end_s
from common.errors import SolverError
from solver.carried_state import CarriedState, carried_correction, effective_modulus, power_law_relaxation
from solver.geometry import cell_radius

if TYPE_CHECKING:
    from analysis.afm.cell import Cell, Segment

FREE_SPHERE = 0.999      # h_ref at most this fraction of the cell's diameter
MIN_HOLD_S = 2.0         # s: a step whose first oscillation comes sooner has no recorded wait (1 Hz approaches)
MAX_LOSS_ANGLE_RAD = 1.4   # the fitted loss angles are held in [0, this] (a power law needs δ < π/2)
CORRECTION_COLUMNS = ("protocol_modulus_factor", "protocol_phase_rad", "protocol_tension_shift_mN_per_m")


@dataclass(frozen=True)
class History:
    """One segment's history: h_ref (µm), the steps Δh_k (µm) and their ages t_j - t_k (s)."""

    reference_um: float
    steps_um: npt.NDArray[np.float64]
    ages_s: npt.NDArray[np.float64]


def _reference_um(cell: Cell, first: Segment) -> float:
    approach = next((s for s in cell.segments if s.kind == "approach" and s.stop <= first.start), None)
    at = 0 if approach is None else max(approach.start - 1, 0)
    return float(min(cell.height_um[at], FREE_SPHERE * 2 * float(cell_radius(cell.volume_um3))))


def histories(cell: Cell, wait_s: float | None = None) -> list[History | None]:
    """Every oscillation segment's `History` in order (None where no approach precedes it)."""
    osc = cell.oscillations()
    if not osc:
        return []
    ref = _reference_um(cell, osc[0])
    steps: list[tuple[float, float, float]] = []        # (t_s, h_k, start of its first oscillation)
    out: list[History | None] = []
    for seg in osc:
        t_s = step_end_s(cell, seg)
        if math.isnan(t_s) or (wait_s is None and not steps_hold(steps, t_s, float(cell.time_s[seg.start]))):
            out.append(None)
            continue
        if not steps or steps[-1][0] != t_s:
            steps.append((t_s, float(cell.height_um[seg.start:seg.stop].mean()), float(cell.time_s[seg.start])))
        heights = np.r_[ref, [h for _, h, _ in steps]]
        t_k = np.array([t if wait_s is None else first - wait_s for t, _, first in steps])
        t_mid = float(cell.time_s[(seg.start + seg.stop - 1) // 2])
        out.append(History(ref, -np.diff(heights), t_mid - t_k))
    return out


def steps_hold(steps: list[tuple[float, float, float]], t_s: float, start_s: float) -> bool:
    """Whether the step ending at `t_s` held its height MIN_HOLD_S before its first oscillation."""
    first = next((f for t, _, f in steps if t == t_s), start_s)
    return first - t_s >= MIN_HOLD_S


def cell_power_laws(moduli: pd.DataFrame) -> pd.DataFrame:
    """Per cell its power laws from the fitted rows: β of each modulus the least-squares slope of
    ln |K*| in ln f (2δ/π at one frequency), anchored at the lowest frequency f_0 (the nearest to
    the ages of the steps): columns `f0`, `bulk0`, `bulk_beta`, `shear0`, `shear_beta`."""
    rows = []
    for cell, g in moduli.dropna(subset=["bulk_abs", "shear_abs", "bulk_delta", "shear_delta"]).groupby("cell_id"):
        g = g.sort_values("frequency_hz")
        x = np.log(g["frequency_hz"].to_numpy(float))
        row = {"cell_id": cell, "f0": float(g["frequency_hz"].iloc[0])}
        for name in ("bulk", "shear"):
            y = np.log(g[f"{name}_abs"].to_numpy(float))
            beta = np.polyfit(x, y, 1)[0] if len(g) > 1 else 2 * g[f"{name}_delta"].iloc[0] / np.pi
            row[f"{name}0"], row[f"{name}_beta"] = float(g[f"{name}_abs"].iloc[0]), float(np.clip(beta, 0.0, 0.9))
        rows.append(row)
    return pd.DataFrame(rows, columns=["cell_id", "f0", "bulk0", "bulk_beta", "shear0", "shear_beta"])


def _row_correction(history: History | None, row: pd.Series, bending: str) -> tuple[float, float, float]:
    """(|c|, arg c, Δγ) of one segment; no correction (1, 0, 0) without a history or a fit."""
    if history is None or not np.isfinite(row.get("f0", np.nan)) or np.any(history.steps_um <= 0):
        return 1.0, 0.0, 0.0
    f, f0 = float(row["frequency_hz"]), float(row["f0"])
    star, eff = [], []
    for name in ("bulk", "shear"):
        k0, beta = float(row[f"{name}0"]), float(row[f"{name}_beta"])
        eff.append(effective_modulus(power_law_relaxation(k0, beta * np.pi / 2, f0, history.ages_s),
                                     history.steps_um))
        k, d = row[f"{name}_abs"], row[f"{name}_delta"]
        if not (np.isfinite(k) and np.isfinite(d)):        # no fit at f: the power law's value there
            k, d = k0 * (f / f0) ** beta, beta * np.pi / 2
        star.append(k * np.exp(1j * float(np.clip(d, 0.0, MAX_LOSS_ANGLE_RAD))))
    state = CarriedState(float(row["volume"]), float(row["tension"]), bending, history.reference_um,
                         float(row["mean_height_um"]), *eff)
    try:
        c, shift = carried_correction(state, star[0], star[1], f)
    except SolverError:
        return math.nan, math.nan, math.nan
    return abs(c), float(np.angle(c)), shift


def correct(segments: pd.DataFrame, cells: list[Cell], moduli: pd.DataFrame, bending: str,
            wait_s: float | None = None, progress: bool = True) -> pd.DataFrame:
    """`segments` (the recordings' order, `analysis.afm.analyze.measure`) as the relaxed model
    would read them, given per (cell_id, frequency_hz) of `moduli` the fitted `bulk_abs`,
    `bulk_delta`, `shear_abs`, `shear_delta` (mN/m, rad), `tension` (γ_a) and `volume`."""
    hist = [h for c in cells for h in histories(c, wait_s)]
    if len(hist) != len(segments):
        raise ValueError("the segments are not the cells' oscillations in order")
    laws = cell_power_laws(moduli)
    cell_fill = moduli.groupby("cell_id")[["tension", "volume"]].median()
    rows = segments.merge(moduli, on=["cell_id", "frequency_hz"], how="left").merge(laws, on="cell_id", how="left")
    for col in ("tension", "volume"):
        rows[col] = rows[col].fillna(rows["cell_id"].map(cell_fill[col]))
    found = [_row_correction(h, r, bending) for h, (_, r) in
             tqdm(zip(hist, rows.iterrows()), total=len(rows), desc="protocol correction", unit="segment",
                  disable=not progress)]
    factor, phase, shift = (np.array(x, float) for x in zip(*found))
    out = segments.copy()
    out["modulus_mN_per_m"] = segments["modulus_mN_per_m"].to_numpy(float) / factor
    out["loss_angle_rad"] = segments["loss_angle_rad"].to_numpy(float) - phase
    out["tension_mN_per_m"] = segments["tension_mN_per_m"].to_numpy(float) - shift
    out["step_age_s"] = [h.ages_s[-1] if h is not None else math.nan for h in hist]
    for name, x in zip(CORRECTION_COLUMNS, (factor, phase, shift)):
        out[name] = x
    return out
