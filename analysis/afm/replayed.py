"""The protocol-aware correction of each segment: the cell's own protocol replayed in time with
its fitted cortex, against the relaxed-state model (SPEC 10, 12; docs/viscoelastic.md).

The relaxed-state reading takes every oscillation about the relaxed droplet at its mean height.
A power-law cortex keeps part of the stress of every earlier height step. Given a cell's power
laws (K_B(t) = K_B,1s t^-β_B, K_S(t) = K_S,1s t^-β_S, `power_laws`) and γ_a, its recording's
protocol (`visits`: the stress-free height and time before its first approach, every height
step's end, `analysis.afm.waits.step_end_s`, and every oscillation's start, frequency and
periods) is replayed in time (`solver.protocol_replay`) and read as the recording is read
(`analysis.afm.timeseries.segment_moduli`): per segment j K*_td,j and the mean tension γ_td,j.
The relaxed-state model gives K*_r,j (`solver.relaxed_state`) and γ_a. Then

    c_j = K*_td,j / K*_r,j,   Δγ_j = γ_td,j - γ_a,

and the segment as the relaxed-state reading should see it is K*_j / c_j with mean tension
<γ_eff>_j - Δγ_j (`correct`; the factors in `CORRECTION_COLUMNS`).

h_ref is the height just before the first approach, at most FREE_SPHERE of the cell's diameter
(a recording that starts out of contact is referenced to the free sphere). With a wait S
(`afm analyze --wait-s S`) every height's wait is S: the timeline after each step shifts by S
minus the recorded wait. Without S a cell whose approaches do not hold the height for
MIN_HOLD_S before the oscillations has no recorded wait and is not corrected.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from analysis.afm.cell import Cell, Segment
from analysis.afm.timeseries import segment_moduli
from analysis.afm.waits import step_end_s
from common.errors import SolverError
from solver.cell_protocol import power_law_cortex
from solver.geometry import cell_radius
from solver.model import Shell
from solver.protocol_replay import AMPLITUDE_UM, Replay, Visit, replay
from solver.relaxed_state import relaxed_state
from solver.time_domain import Cortex

FREE_SPHERE = 0.999      # h_ref at most this fraction of the cell's diameter
MIN_HOLD_S = 2.0         # s: an approach that holds its height less long records no wait (1 Hz samples)
EXPONENT_RANGE = (0.0, 0.9)
CORRECTION_COLUMNS = ("protocol_modulus_factor", "protocol_phase_rad", "protocol_tension_shift_mN_per_m")


@dataclass(frozen=True)
class Protocol:
    """A recording's protocol: h_ref (µm) at `start_s` (s), and one `Visit` per oscillation."""

    reference_um: float
    start_s: float
    visits: list[Visit]


def _cycles(cell: Cell, seg: Segment) -> int:
    t = cell.time_s[seg.start:seg.stop]
    step = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    return max(int(round((float(t[-1] - t[0]) + step) * seg.frequency_hz)), 1)


def visits(cell: Cell, wait_s: float | None = None) -> Protocol | None:
    """The cell's `Protocol` (module docstring); None where an oscillation has no approach before
    it or, without `wait_s`, an approach does not hold its height MIN_HOLD_S."""
    osc = cell.oscillations()
    first = next((s for s in cell.segments if s.kind == "approach"), None)
    if not osc or first is None or first.start >= osc[0].start:
        return None
    at = max(first.start - 1, 0)
    ref = min(float(cell.height_um[at]), FREE_SPHERE * 2 * float(cell_radius(cell.volume_um3)))
    out, shift, last_end = [], 0.0, math.nan
    for seg in osc:
        end, start = step_end_s(cell, seg), float(cell.time_s[seg.start])
        if math.isnan(end):
            return None
        step_end = math.nan
        if end != last_end:                     # the first oscillation after a height step
            held = start - end
            if wait_s is None and held < MIN_HOLD_S:
                return None
            step_end, last_end = end + shift, end
            shift += 0.0 if wait_s is None else wait_s - held
        out.append(Visit(float(cell.height_um[seg.start:seg.stop].mean()), float(seg.frequency_hz),
                         _cycles(cell, seg), start + shift, step_end))
    return Protocol(ref, float(cell.time_s[at]), out)


def power_laws(moduli: pd.DataFrame) -> pd.DataFrame:
    """Per cell its power laws from the per-frequency fits (`cell_id`, `frequency_hz`, `bulk_abs`,
    `bulk_delta`, `shear_abs`, `shear_delta`, `tension`): β the least-squares slope of ln |K*| in
    ln f (one frequency: 2δ/π), clipped to EXPONENT_RANGE, K(1 s) = |K*(1 Hz)| / (Γ(1-β) (2π)^β)
    from the line's value at 1 Hz, and γ_a the median tension. Columns `bulk_1s`, `bulk_beta`,
    `shear_1s`, `shear_beta`, `tension`."""
    from scipy.special import gamma
    rows = []
    for cell, g in moduli.dropna(subset=["bulk_abs", "shear_abs", "bulk_delta", "shear_delta"]).groupby("cell_id"):
        x = np.log(g["frequency_hz"].to_numpy(float))
        row: dict[str, Any] = {"cell_id": cell, "tension": float(g["tension"].median())}
        for name in ("bulk", "shear"):
            y = np.log(g[f"{name}_abs"].to_numpy(float))
            if len(g) > 1:
                beta, at_1hz = np.polyfit(x, y, 1)
            else:
                beta, at_1hz = 2 * float(g[f"{name}_delta"].iloc[0]) / np.pi, float(y[0])
                at_1hz -= beta * float(x[0])
            beta = float(np.clip(beta, *EXPONENT_RANGE))
            row[f"{name}_beta"] = beta
            row[f"{name}_1s"] = float(np.exp(at_1hz) / (gamma(1.0 - beta) * (2 * np.pi) ** beta))
        rows.append(row)
    return pd.DataFrame(rows, columns=["cell_id", "tension", "bulk_beta", "bulk_1s", "shear_beta", "shear_1s"])


def replayed_segments(cell: Cell, rep: Replay) -> list[dict[str, Any]]:
    """`segment_moduli` of the replay, read as a recording of the cell's volume."""
    t, h, f, segs, n, t0 = [], [], [], [], 0, 0.0
    for ts, hs, fs, freq in zip(rep.time_s, rep.height_um, rep.force_nN, [s.frequency_hz for s in cell.oscillations()]):
        t.append(t0 + ts)
        h.append(hs)
        f.append(fs)
        segs.append(Segment("oscillation", n, n + ts.size, freq))
        n, t0 = n + ts.size, t0 + float(ts[-1]) + 1.0
    read = Cell(cell.cell_id, cell.volume_um3, np.concatenate(t), np.concatenate(f), np.concatenate(h), segs)
    return segment_moduli(read)


def cell_correction(cell: Cell, law: dict[str, float], bending: str,
                    wait_s: float | None = None) -> np.ndarray | None:
    """(segments, 3): |c|, arg c and Δγ (mN/m) per oscillation of `cell` with the power laws
    `law` (a row of `power_laws`); None where the protocol is not recorded or the replay finds
    no equilibrium (the segments stay as recorded)."""
    protocol = visits(cell, wait_s)
    if protocol is None:
        return None
    cortex = power_law_cortex(law["bulk_1s"], law["shear_1s"], law["bulk_beta"], law["shear_beta"])
    shell = Shell(volume_um3=cell.volume_um3, h0_um=protocol.reference_um, bulk_mN_per_m=law["bulk_1s"],
                  shear_mN_per_m=law["shear_1s"], tension_mN_per_m=law["tension"], bending=bending)
    try:
        rows = replayed_segments(cell, replay(shell, cortex, protocol.start_s, protocol.visits))
    except SolverError:
        return None
    out = np.empty((len(rows), 3))
    for k, (row, v) in enumerate(zip(rows, protocol.visits)):
        K = row["modulus_mN_per_m"] * np.exp(1j * row["loss_angle_rad"]) / _relaxed(shell, cortex, v)
        out[k] = abs(K), float(np.angle(K)), row["tension_mN_per_m"] - law["tension"]
    return out


def _relaxed(shell: Shell, cortex: Cortex, v: Visit) -> complex:
    """K*_r (mN/m) of the relaxed-state model at the visit's mean height and frequency."""
    r = relaxed_state(Shell(volume_um3=shell.volume_um3, h0_um=v.mean_um + AMPLITUDE_UM, dh_um=2 * AMPLITUDE_UM,
                            bulk_mN_per_m=1.0, shear_mN_per_m=1.0, tension_mN_per_m=shell.tension_mN_per_m,
                            bending=shell.bending), cortex, v.frequency_hz)
    return complex(r["modulus_mN_per_m"] * np.exp(1j * r["loss_angle_rad"]))


def apply(segments: pd.DataFrame, factors: np.ndarray) -> pd.DataFrame:
    """`segments` divided by c and less Δγ (`factors`: (rows, 3) in the segments' order; NaN
    rows: not corrected), with the factors in CORRECTION_COLUMNS."""
    factors = np.where(np.isnan(factors), [1.0, 0.0, 0.0], factors)
    out = segments.copy()
    out["modulus_mN_per_m"] = segments["modulus_mN_per_m"].to_numpy(float) / factors[:, 0]
    out["loss_angle_rad"] = segments["loss_angle_rad"].to_numpy(float) - factors[:, 1]
    out["tension_mN_per_m"] = segments["tension_mN_per_m"].to_numpy(float) - factors[:, 2]
    for k, name in enumerate(CORRECTION_COLUMNS):
        out[name] = factors[:, k]
    return out
