"""The protocol-aware reading: the segments corrected for the stress each cell carries (SPEC 10, 12).

The correction of a cell's segments (`analysis.afm.replayed`) needs the cell's power laws and
γ_a, which the reading of the corrected segments gives: a fixed point, found in rounds

    θ_0 = the viscoelastic point fit of the raw segments (tension filter lifted), γ_a from the
          shallowest height (`started`),
    S_i = the raw segments corrected with the power laws of θ_{i-1},   θ_i = the point fit of S_i,

each round the selected variant's inversion of S_i and its complex point fit
(`analysis.viscoelastic_fit.fit`, no bootstrap). Only the cells whose power laws moved by more
than SETTLED since their last replay are replayed again (`unsettled`, the policy; a cell the
round's fit leaves out keeps its last correction), until none moved or MAX_ROUNDS rounds. The
rounds replay linearised (`cell_correction`'s default, fast); with `full_last` (FULL_LAST, the
default) every replayed cell's last correction is then its full replay with its last power laws
(the linearised replay's |c| is off the full one's by up to ~6 %, bench/linearised_replay.py).
What follows (every variant with the tension filter on the corrected mean tensions, the
population, the viscoelastic reading and its intervals) reads the last S. The cells' replays run
in `jobs` processes.

The segments gain CORRECTION_COLUMNS (`analysis.afm.replayed`), `protocol_corrected`,
`protocol_reason`, `protocol_settled` and `protocol_replays` (how often the cell was replayed
linearised). A cell is not corrected (False, the reason beside it)
without a point fit, without a recorded protocol, where its replay found no equilibrium, or where
a corrected mean tension <γ_eff>_j - Δγ_j would be ≤ 0 (`refused`: the correction is refused,
never used); its segments stay as recorded (and the tension filter, on their kept stress, mostly
excludes it). `protocol_settled` False: the cell's power laws still moved after MAX_ROUNDS.

`wait_s`: None takes each recording's own waits, a number sets T_w at every height; inf (the
relaxed-state reading) is no correction and does not come here.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd
from tqdm import tqdm

from analysis.afm.analyze import Measured, inverted, measured_of
from analysis.afm.replayed import apply, cell_correction
from analysis.afm.rheology import cortex_laws, point_moduli
from common.pool import pool

if TYPE_CHECKING:
    from analysis.afm.cell import Cell
    from analysis.calibration.file import ComplexModel
    from analysis.invert.measurement_errors import MeasurementErrors
    from analysis.invert.method import Inversion

MAX_ROUNDS = 8
FULL_LAST = True        # the last correction by the full replay (the linearised one's bias: bench/linearised_replay.py)
SHALLOWEST_UM = 0.1     # µm: segments this close to a cell's largest mean height are its shallowest
SETTLED = {"bulk_beta": 0.01, "shear_beta": 0.01, "bulk_1s": 0.02, "shear_1s": 0.02, "tension": 0.02}


def is_on(wait_s: float | None) -> bool:
    """Whether `wait_s` asks for the protocol-aware reading (inf: the relaxed-state reading)."""
    return wait_s is None or math.isfinite(wait_s)


def _cells(segments: pd.DataFrame) -> pd.DataFrame:
    """Per cell: corrected, reason, settled."""
    return segments.groupby("cell_id", sort=False).agg(
        corrected=("protocol_corrected", "all"), reason=("protocol_reason", "first"),
        settled=("protocol_settled", "all"))


def summary(segments: pd.DataFrame, wait_s: float | None) -> dict[str, object]:
    """summary.json's `protocol`: the wait (s, or "recorded"), which cells were corrected, why
    the others were not, which did not settle in MAX_ROUNDS, and how often a cell was replayed
    on average (`replays_per_cell`)."""
    cells = _cells(segments)
    left = cells[~cells["corrected"]]
    replays = segments.groupby("cell_id")["protocol_replays"].first() if "protocol_replays" in segments else None
    return {"reading": "protocol-aware: each cell's protocol replayed with its fitted power-law cortex",
            "wait_s": "recorded" if wait_s is None else wait_s, "cells_corrected": int(cells["corrected"].sum()),
            "cells_not_corrected": [str(c) for c in left.index],
            "not_corrected_reasons": {str(c): str(r) for c, r in left["reason"].items()},
            "cells_not_settled": [str(c) for c in cells.index[~cells["settled"].to_numpy()]],
            "replays_per_cell": None if replays is None or replays.empty else float(replays.mean())}


def markdown(segments: pd.DataFrame) -> list[str]:
    """report.md's section: every cell not corrected and every cell not settled, and why."""
    cells = _cells(segments)
    lines = ["", "## Protocol-aware correction", "",
             f"{int(cells['corrected'].sum())} of {len(cells)} cells corrected for the stress kept from "
             "their earlier height steps; a cell not corrected keeps its recorded segments.", ""]
    rows = [f"| {c} | not corrected: {r.reason} |" for c, r in cells[~cells["corrected"]].iterrows()]
    rows += [f"| {c} | not settled: its power laws still moved after {MAX_ROUNDS} rounds (its last "
             "correction is used) |" for c in cells.index[~cells["settled"].to_numpy()]]
    return lines + (["| cell | reason |", "|---|---|", *rows, ""] if rows else [])


def refused(tension_mN_per_m: np.ndarray, factors: np.ndarray) -> str | None:
    """Why a cell's correction is refused: a corrected mean tension <γ_eff>_j - Δγ_j ≤ 0; None if none."""
    after = np.asarray(tension_mN_per_m, float) - factors[:, 2]
    bad = np.flatnonzero(after <= 0)
    if not bad.size:
        return None
    j = int(bad[0])
    return (f"corrected tension ≤ 0 refused (segment {j}: {tension_mN_per_m[j]:.3g} - "
            f"{factors[j, 2]:.3g} = {after[j]:.3g} mN/m)")


def unsettled(laws: dict[str, dict[str, float]], found: pd.DataFrame) -> list[str]:
    """The cells of `found` (`analysis.afm.rheology.cortex_laws`) whose power laws are new or moved
    by more than SETTLED from `laws` (β by the difference, moduli and γ_a by the log ratio)."""
    moved = []
    for row in found.to_dict("records"):
        old = laws.get(row["cell_id"])
        if old is None or any(abs(row[k] - old[k]) > tol if k.endswith("beta") else
                              abs(math.log(row[k] / old[k])) > tol for k, tol in SETTLED.items()):
            moved.append(row["cell_id"])
    return moved


def started(found: pd.DataFrame, segments: pd.DataFrame) -> pd.DataFrame:
    """θ_0 (`cortex_laws` of the raw segments) with γ_a the median mean tension of each cell's
    segments at its shallowest height (within SHALLOWEST_UM of its largest mean height): the
    height that keeps least stress from the steps before it, so the rounds start near their end."""
    top = segments.groupby("cell_id")["mean_height_um"].transform("max")
    shallow = segments[segments["mean_height_um"] >= top - SHALLOWEST_UM]
    tension = shallow.groupby("cell_id")["tension_mN_per_m"].median()
    out = found.copy()
    out["tension"] = out["cell_id"].map(tension).fillna(out["tension"])
    return out


def _one(job: tuple[Cell, dict[str, float], str, float | None, bool]) -> np.ndarray | str:
    """The cell's factors, or why it is not corrected (`cell_correction`)."""
    cell, law, bending, wait_s, linearised = job
    return cell_correction(cell, law, bending, wait_s, linearised)


def _factors(cells: list[Cell], laws: dict[str, dict[str, float]], bending: str, wait_s: float | None,
             jobs: int, label: str, linearised: bool = True) -> list[np.ndarray | str]:
    """Per cell of `cells` its (segments, 3) correction factors or why not, `jobs` processes."""
    bar = tqdm(total=len(cells), unit="cell", desc=label)
    with pool(jobs) as workers:
        out = []
        for f in workers.map(_one, [(c, laws[c.cell_id], bending, wait_s, linearised) for c in cells]):
            out.append(f)
            bar.update()
    bar.close()
    return out


def corrected(measured: Measured, cells: list[Cell], inversion: Inversion, model: ComplexModel, bending: str,
              errors: MeasurementErrors | None, wait_s: float | None, lags: dict[float, float] | None = None,
              jobs: int = 1, full_last: bool = FULL_LAST) -> Measured:
    """`measured` with its segments corrected for the carried stress (module docstring)."""
    volumes = pd.Series({c.cell_id: c.volume_um3 for c in cells})
    raw = measured.segments
    rows = {c.cell_id: np.flatnonzero(raw["cell_id"].to_numpy() == c.cell_id) for c in cells}
    factors = np.full((len(raw), 3), np.nan)
    why = {c.cell_id: "no viscoelastic point fit of its segments" for c in cells}
    now = _measured(raw, factors, volumes, measured, why, [])
    table, tension = inverted(measured, inversion, bending, errors, math.inf), raw["tension_mN_per_m"].to_numpy(float)
    laws: dict[str, dict[str, float]] = {}
    replays, moving = {c.cell_id: 0 for c in cells}, []
    for i in range(MAX_ROUNDS):
        found = cortex_laws(point_moduli(table, now.segments, model, bending, lags))
        if i == 0:
            found = started(found, raw)
        todo = unsettled(laws, found)
        if not todo:
            break
        laws.update({r["cell_id"]: r for r in found.to_dict("records") if r["cell_id"] in todo})
        replay_cells = [c for c in cells if c.cell_id in todo]
        for c, f in zip(replay_cells, _factors(replay_cells, laws, bending, wait_s, jobs,
                                               f"protocol round {i + 1} (at most {MAX_ROUNDS})")):
            at, replays[c.cell_id] = rows[c.cell_id], replays[c.cell_id] + 1
            why[c.cell_id] = f if isinstance(f, str) else (refused(tension[at], f) or "")
            factors[at] = np.nan if why[c.cell_id] else f
        now = _measured(raw, factors, volumes, measured, why, [], replays)
        table = inverted(now, inversion, bending, errors, math.inf)
    else:
        moving = todo
    if full_last:
        last = [c for c in cells if c.cell_id in laws]
        for c, f in zip(last, _factors(last, laws, bending, wait_s, jobs, "protocol: the full replay", False)):
            at = rows[c.cell_id]
            why[c.cell_id] = f if isinstance(f, str) else (refused(tension[at], f) or "")
            factors[at] = np.nan if why[c.cell_id] else f
    return _measured(raw, factors, volumes, measured, why, moving, replays)


def _measured(raw: pd.DataFrame, factors: np.ndarray, volumes: pd.Series, measured: Measured,
              why: dict[str, str], moving: list[str], replays: dict[str, int] | None = None) -> Measured:
    """The `Measured` of the raw segments corrected by `factors` (NaN rows: not corrected, for
    the reason `why` gives); `moving` the cells not settled, `replays` how often each was replayed."""
    segments = apply(raw, factors)
    segments["protocol_corrected"] = ~np.isnan(factors[:, 0])
    segments["protocol_reason"] = segments["cell_id"].map(why).fillna("").where(~segments["protocol_corrected"], "")
    segments["protocol_settled"] = ~segments["cell_id"].isin(moving)
    segments["protocol_replays"] = segments["cell_id"].map(replays or {}).fillna(0).astype(int)
    return measured_of(segments.assign(volume_um3=segments["cell_id"].map(volumes)), measured.order)
