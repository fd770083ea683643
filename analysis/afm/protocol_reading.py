"""The protocol-aware reading: the segments corrected for the stress each cell carries (SPEC 10, 12).

The correction of a cell's segments (`analysis.afm.replayed`) needs the cell's power laws and
γ_a, which the reading of the corrected segments gives: a fixed point, found in rounds

    θ_0 = the viscoelastic point fit of the raw segments (tension filter lifted),
    S_i = the raw segments corrected with the power laws of θ_{i-1},   θ_i = the point fit of S_i,

each round the selected variant's inversion of S_i and its complex point fit
(`analysis.viscoelastic_fit.fit`, no bootstrap). Only the cells whose power laws moved by more
than SETTLED since their last replay are replayed again (`unsettled`, the policy; a cell the
round's fit leaves out keeps its last correction), until none moved or MAX_ROUNDS rounds. What follows (every variant with the tension
filter on the corrected mean tensions, the population, the viscoelastic reading and its
intervals) reads the last S_i. The cells' replays run in `jobs` processes.

The segments gain CORRECTION_COLUMNS (`analysis.afm.replayed`) and `protocol_corrected`: False
for a cell without a fit, without a recorded protocol or whose replay found no equilibrium; its
segments stay as recorded (and the tension filter, on their kept stress, mostly excludes it).

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
SETTLED = {"bulk_beta": 0.01, "shear_beta": 0.01, "bulk_1s": 0.02, "shear_1s": 0.02, "tension": 0.02}


def is_on(wait_s: float | None) -> bool:
    """Whether `wait_s` asks for the protocol-aware reading (inf: the relaxed-state reading)."""
    return wait_s is None or math.isfinite(wait_s)


def summary(segments: pd.DataFrame, wait_s: float | None) -> dict[str, object]:
    """summary.json's `protocol`: the wait (s, or "recorded") and which cells were corrected."""
    done = segments.groupby("cell_id", sort=False)["protocol_corrected"].all()
    return {"reading": "protocol-aware: each cell's protocol replayed with its fitted power-law cortex",
            "wait_s": "recorded" if wait_s is None else wait_s, "cells_corrected": int(done.sum()),
            "cells_not_corrected": [str(c) for c in done.index[~done.to_numpy()]]}


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


def _one(job: tuple[Cell, dict[str, float], str, float | None]) -> np.ndarray:
    """The cell's factors; NaN rows where it is not corrected (`cell_correction` None)."""
    cell, law, bending, wait_s = job
    found = cell_correction(cell, law, bending, wait_s)
    return np.full((len(cell.oscillations()), 3), np.nan) if found is None else found


def _factors(cells: list[Cell], laws: dict[str, dict[str, float]], bending: str, wait_s: float | None,
             jobs: int, label: str) -> list[np.ndarray]:
    """Per cell of `cells` its (segments, 3) correction factors, `jobs` processes."""
    bar = tqdm(total=len(cells), unit="cell", desc=label)
    with pool(jobs) as workers:
        out = []
        for f in workers.map(_one, [(c, laws[c.cell_id], bending, wait_s) for c in cells]):
            out.append(f)
            bar.update()
    bar.close()
    return out


def corrected(measured: Measured, cells: list[Cell], inversion: Inversion, model: ComplexModel, bending: str,
              errors: MeasurementErrors | None, wait_s: float | None, lags: dict[float, float] | None = None,
              jobs: int = 1) -> Measured:
    """`measured` with its segments corrected for the carried stress (module docstring)."""
    volumes = pd.Series({c.cell_id: c.volume_um3 for c in cells})
    raw = measured.segments
    rows = {c.cell_id: np.flatnonzero(raw["cell_id"].to_numpy() == c.cell_id) for c in cells}
    factors = np.full((len(raw), 3), np.nan)
    table, now = inverted(measured, inversion, bending, errors, math.inf), _measured(raw, factors, volumes, measured)
    laws: dict[str, dict[str, float]] = {}
    for i in range(MAX_ROUNDS):
        found = cortex_laws(point_moduli(table, now.segments, model, bending, lags))
        todo = unsettled(laws, found)
        if not todo:
            break
        laws.update({r["cell_id"]: r for r in found.to_dict("records") if r["cell_id"] in todo})
        replay_cells = [c for c in cells if c.cell_id in todo]
        for c, f in zip(replay_cells, _factors(replay_cells, laws, bending, wait_s, jobs,
                                               f"protocol round {i + 1} (at most {MAX_ROUNDS})")):
            factors[rows[c.cell_id]] = f
        now = _measured(raw, factors, volumes, measured)
        table = inverted(now, inversion, bending, errors, math.inf)
    return now


def _measured(raw: pd.DataFrame, factors: np.ndarray, volumes: pd.Series, measured: Measured) -> Measured:
    """The `Measured` of the raw segments corrected by `factors` (NaN rows: not corrected)."""
    segments = apply(raw, factors)
    segments["protocol_corrected"] = ~np.isnan(factors[:, 0])
    return measured_of(segments.assign(volume_um3=segments["cell_id"].map(volumes)), measured.order)
