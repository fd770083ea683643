"""The protocol-aware reading: the segments corrected for the stress each cell carries (SPEC 10, 12).

The correction of a cell's segments (`analysis.afm.replayed`) needs the cell's power laws and
γ_a, which the reading of the corrected segments gives: a fixed point, found in rounds

    θ_0 = the viscoelastic point fit of the raw segments (tension filter lifted), γ_a from the
          shallowest height (`started`),
    S_i = the raw segments corrected with the power laws θ_{i-1},   g_i = the point fit of S_i,

each round the selected variant's inversion of S_i and its complex point fit
(`analysis.viscoelastic_fit.fit`, no bootstrap), and θ_i Anderson's mixing of the cell's last
rounds (`analysis.afm.law_rounds`, the policy: a fixed point that contracts slowly is
extrapolated, not crept towards). Only the cells whose θ_i differs by more than SETTLED from the
laws of their last replay are replayed again (`proposed`, `law_rounds.moved`; a cell the
round's fit leaves out keeps its last correction), until none moved or MAX_ROUNDS rounds. A
cell's first replay is a replay at every memory τ_c of `analysis.afm.memory_fit.MEMORY_GRID_S`
(`memory_s` None, the default) or at the one given; the cell's memory is then chosen from the
drift of its corrected mean tensions and the relaxation in its waits (fitted, pooled or assumed:
`analysis.afm.protocol_factors`),
its factors interpolated there. A later replay of a cell whose memory is its own is made only at
the memories that decide it and its interval, the others carried along
(`analysis.afm.memory_nodes`); when the rounds end, every deciding memory not replayed at a cell's
last laws is (`_closed`), so its memory and interval rest on replays at the laws they are read
with. The
rounds replay linearised (`cell_correction`'s default, fast; its arg c is off the full replay's by
up to 0.017 rad, at 0.02 Hz, and its |c| by up to 1.0 %: bench/linearised_replay.py), and settle
at a fixed point biased by that. With `full_last` (FULL_LAST, the default) rounds of the full
replay follow, each cell at its chosen memory (held), from the laws the linearised rounds settled
at, each cell's next laws Anderson's mixing of its full rounds only (`_full_rounds`), until none
moved or MAX_FULL_ROUNDS: the fixed point of the full replay (on the noiseless ∞ cell of
tests/test_protocol_replay.py β_S 0.323 and β_B 0.071 for 0.329 and 0.073). Then each corrected
cell is replayed linearised three times more at its memory, with its laws and with β_B and β_S
each moved by 0.02 (`_widenings`): the correction's feedback on the exponents, by which their
intervals are widened (`analysis.afm.fixed_point_span`).
What follows (every variant with the tension filter on the corrected mean tensions, the
population, the viscoelastic reading and its intervals) reads the last S. The cells' replays run
in `jobs` processes, each kept in the reading's folder as it is back, and read back by a reading
run again there (`analysis.afm.replay_store`: a stopped reading resumes).

The segments gain CORRECTION_COLUMNS (`analysis.afm.replayed`), `protocol_corrected`,
`protocol_reason`, `protocol_settled`, `protocol_replays` (how often the cell was replayed
linearised: its rounds and the closing ones), `protocol_memory_replays` (the linearised replays at
one memory those made), `protocol_full_replays` and MEMORY_COLUMNS (τ_c in s, its 95 % interval,
its source). A cell is not corrected (False, the reason beside it)
without a point fit, without a recorded protocol, where its replay found no equilibrium, or where
a corrected mean tension <γ_eff>_j - Δγ_j would be ≤ 0 (`protocol_factors.refused`: the correction is refused,
never used); its segments stay as recorded (and the tension filter, on their kept stress, mostly
excludes it). `protocol_settled` False: the cell's power laws still moved after its last round.

`wait_s`: None takes each recording's own waits, a number sets T_w at every height; inf (the
relaxed-state reading) is no correction and does not come here.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd
from tqdm import tqdm

from analysis.afm.analyze import Measured, inverted
from analysis.afm.fixed_point_span import MOVED, jacobian, shifted, widening
from analysis.afm.law_rounds import Laws, moved, next_laws
from analysis.afm.memory_fit import MEMORY_GRID_S, RELAXED, Node
from analysis.afm.protocol_factors import MEMORY_COLUMNS, Factors, node
from analysis.afm.replay_store import Job, Replays, ReplayStore
from analysis.afm.replayed import cell_replays
from analysis.afm.rheology import cortex_laws, point_moduli
from common.pool import pool

if TYPE_CHECKING:
    from analysis.afm.cell import Cell
    from analysis.calibration.file import ComplexModel
    from analysis.invert.measurement_errors import MeasurementErrors
    from analysis.invert.method import Inversion

MAX_ROUNDS = 8
MAX_FULL_ROUNDS = 4    # rounds of the full replay after the linearised ones settle
FULL_LAST = True        # the last correction by the full replay (the linearised one's bias: bench/linearised_replay.py)
SHALLOWEST_UM = 0.1     # µm: segments this close to a cell's largest mean height are its shallowest


def is_on(wait_s: float | None) -> bool:
    """Whether `wait_s` asks for the protocol-aware reading (inf: the relaxed-state reading)."""
    return wait_s is None or math.isfinite(wait_s)


def _cells(segments: pd.DataFrame) -> pd.DataFrame:
    """Per cell: corrected, reason, settled, and its memory (MEMORY_COLUMNS)."""
    memory = {k: (k, "first") for k in MEMORY_COLUMNS if k in segments}
    return segments.groupby("cell_id", sort=False).agg(
        corrected=("protocol_corrected", "all"), reason=("protocol_reason", "first"),
        settled=("protocol_settled", "all"), **memory)


def _seconds(value: float) -> float | None:
    """A memory in s for JSON: null for ∞ or none."""
    return None if not math.isfinite(value) else float(value)


def _memory(cells: pd.DataFrame, memory_s: float | None) -> dict[str, object]:
    """summary.json's `memory`: given or from the data, the grid, and per cell τ_c (s, null ∞), its
    95 % interval (null: ∞, or no carried history in the set), where it came from and the history
    (`analysis.afm.protocol_factors`)."""
    per_cell = {str(c): {"memory_s": _seconds(r.protocol_memory_s), "lo95_s": _seconds(r.protocol_memory_lo95_s),
                         "hi95_s": _seconds(r.protocol_memory_hi95_s), "source": r.protocol_memory_source,
                         "history": r.protocol_history}
                for c, r in cells.iterrows() if r.protocol_memory_source}
    sources = cells["protocol_memory_source"]
    return {"memory_s": "from the data" if memory_s is None else _seconds(memory_s),
            "grid_s": [_seconds(m) for m in MEMORY_GRID_S] if memory_s is None else None,
            **{f"cells_{k}": int((sources == k).sum()) for k in ("fitted", "pooled", "assumed", "given")},
            "cells_relaxed_history": int((cells["protocol_history"] == RELAXED).sum()),
            "cells": per_cell}


def summary(segments: pd.DataFrame, wait_s: float | None, memory_s: float | None = None) -> dict[str, object]:
    """summary.json's `protocol`: the wait (s, or "recorded"), the memory (`_memory`), which cells
    were corrected, why the others were not, which did not settle in MAX_ROUNDS, and how often a
    cell was replayed on average (`replays_per_cell`; `memory_replays_per_cell` counts each memory of
    those, `full_replays_per_cell` the full ones)."""
    cells = _cells(segments)
    left = cells[~cells["corrected"]]
    replays = segments.groupby("cell_id")["protocol_replays"].first() if "protocol_replays" in segments else None
    fulls = segments.groupby("cell_id")["protocol_full_replays"].first() if "protocol_full_replays" in segments else None
    at = segments.groupby("cell_id")["protocol_memory_replays"].first() if "protocol_memory_replays" in segments else None
    return {"reading": "protocol-aware: each cell's protocol replayed with its fitted power-law cortex and memory",
            "wait_s": "recorded" if wait_s is None else wait_s,
            "memory": _memory(cells, memory_s) if "protocol_memory_source" in cells else None,
            "cells_corrected": int(cells["corrected"].sum()),
            "cells_not_corrected": [str(c) for c in left.index],
            "not_corrected_reasons": {str(c): str(r) for c, r in left["reason"].items()},
            "cells_not_settled": [str(c) for c in cells.index[~cells["settled"].to_numpy()]],
            "replays_per_cell": None if replays is None or replays.empty else float(replays.mean()),
            "memory_replays_per_cell": None if at is None or at.empty else float(at.mean()),
            "full_replays_per_cell": None if fulls is None or fulls.empty else float(fulls.mean())}


def _memory_lines(cells: pd.DataFrame) -> list[str]:
    """report.md's sentences on the memory: how many cells read it, pooled it or assumed it."""
    if "protocol_memory_source" not in cells:
        return []
    src = cells["protocol_memory_source"]
    if (src == "given").any():
        return [f"The cortex's memory τ_c is given: {cells['protocol_memory_s'].iloc[0]:g} s for every cell.", ""]
    pooled = cells[src == "pooled"]["protocol_memory_s"]
    return [f"The cortex's memory τ_c (K(t) ∝ t^-β e^(-t/τ_c)) from the drift of each cell's mean tension "
            f"across heights and the relaxation in its waits: {int((src == 'fitted').sum())} cells read their own; "
            f"{len(pooled)} cells could not and take the population's"
            + (f" ({pooled.iloc[0]:g} s)" if len(pooled) else "")
            + f"; {int((src == 'assumed').sum())} cells are undecided by the data and assume the pure power law "
            f"(τ_c = ∞). {int((cells['protocol_history'] == RELAXED).sum())} cells read best with the history relaxed "
            "at every height (only the last step's stress kept).", ""]


def markdown(segments: pd.DataFrame) -> list[str]:
    """report.md's section: the memory, every cell not corrected and every cell not settled, and why."""
    cells = _cells(segments)
    lines = ["", "## Protocol-aware correction", "",
             f"{int(cells['corrected'].sum())} of {len(cells)} cells corrected for the stress kept from "
             "their earlier height steps; a cell not corrected keeps its recorded segments.", "",
             *_memory_lines(cells)]
    rows = [f"| {c} | not corrected: {r.reason} |" for c, r in cells[~cells["corrected"]].iterrows()]
    rows += [f"| {c} | not settled: its power laws still moved after its last round ({MAX_ROUNDS} linearised, "
             f"{MAX_FULL_ROUNDS} full at most; its last correction is used) |" for c in cells.index[~cells["settled"].to_numpy()]]
    return lines + (["| cell | reason |", "|---|---|", *rows, ""] if rows else [])


def proposed(laws: dict[str, Laws], rounds: dict[str, list[tuple[Laws, Laws]]],
             found: pd.DataFrame) -> dict[str, Laws]:
    """Per cell of `found` (`analysis.afm.rheology.cortex_laws`) the laws for its next replay
    (`law_rounds.next_laws` of its rounds, each the laws it was replayed with and those then
    found; `rounds` gains this one, a cell not replayed since its last round replacing it)."""
    out = {}
    for row in found.to_dict("records"):
        c = row["cell_id"]
        if c in laws:
            kept = rounds.setdefault(c, [])
            if kept and kept[-1][0] is laws[c]:
                kept.pop()
            kept.append((laws[c], row))
            out[c] = next_laws(kept)
        else:
            out[c] = row
    return out


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


def _one(job: Job) -> Replays:
    """The cell's factors at each memory (a τ_c or RELAXED), or why it is not corrected, and its
    waits (`cell_replays`)."""
    return cell_replays(*job)


def _factors(cells: list[Cell], laws: dict[str, dict[str, float]], bending: str, wait_s: float | None,
             jobs: int, label: str, memories: Mapping[str, Sequence[Node]],
             linearised: bool = True, store: ReplayStore | None = None) -> dict[str, Replays]:
    """Per cell of `cells` and memory of `memories[cell]` its (segments, 3) correction factors or
    why not, and its waits; `jobs` processes (one task a cell); each read back from `store` where
    a reading wrote it there, else replayed and written there (`analysis.afm.replay_store`)."""
    tasks: dict[str, Job] = {c.cell_id: (c, laws[c.cell_id], bending, wait_s, linearised, memories[c.cell_id])
                             for c in cells}
    out = {c: r for c, job in tasks.items() if (r := store.get(job)) is not None} if store is not None else {}
    todo = [c for c in tasks if c not in out]
    bar = tqdm(total=len(cells), initial=len(out), unit="cell", desc=label)
    if todo:
        with pool(jobs) as workers:
            for c, f in zip(todo, workers.map(_one, [tasks[c] for c in todo])):
                if store is not None:
                    store.put(tasks[c], f)
                out[c] = f
                bar.update()
    bar.close()
    return {c: out[c] for c in tasks}


def _linearised_rounds(state: Factors, laws: dict[str, Laws], cells: list[Cell], replay: Callable[[list[Cell], int], None],
                       refit: Callable[[int], pd.DataFrame]) -> list[str]:
    """The rounds of the module docstring: `refit(i)` the laws found before round i (θ_0: `started`),
    `replay` the moved cells at the memories each needs (into `state`), until none moved or MAX_ROUNDS; `laws`
    gains the laws replayed; returns the cells still moving."""
    rounds: dict[str, list[tuple[Laws, Laws]]] = {}
    for i in range(MAX_ROUNDS):
        following = proposed(laws, rounds, refit(i))
        todo = [c for c, new in following.items() if moved(laws.get(c), new)]
        if not todo:
            return []
        laws.update({c: following[c] for c in todo})
        replay([c for c in cells if c.cell_id in todo], i)
    return todo


def _closed(state: Factors, cells: list[Cell], nodes: tuple[Node, ...],
            replay: Callable[[list[Cell], str, dict[str, tuple[Node, ...]]], None]) -> None:
    """Every memory a cell's memory and interval rest on replayed at its last laws: the stale
    ones (carried along since: `analysis.afm.memory_nodes`) replayed (`replay(todo, label,
    asked)`, the laws unchanged) until none is left (each pass adds fresh nodes, so at most one a
    node)."""
    for k in range(len(nodes)):
        stale = state.stale(nodes)
        if not stale:
            return
        replay([c for c in cells if c.cell_id in stale], f"protocol: the memory's own nodes {k + 1}", stale)


def _full_rounds(state: Factors, laws: dict[str, Laws], cells: list[Cell], replay: Callable[[list[Cell], int], None],
                 refit: Callable[[], pd.DataFrame]) -> list[str]:
    """Rounds of the full replay (`replay`: at each cell's chosen memory, into `state`) from the
    linearised rounds' `laws`, each cell's next laws Anderson's mixing of its full rounds, until
    none moved or MAX_FULL_ROUNDS; a cell whose full replay is not usable leaves them. `laws` gains
    the laws replayed; returns the cells still moving."""
    rounds: dict[str, list[tuple[Laws, Laws]]] = {}
    todo = [c for c in cells if c.cell_id in laws]
    for i in range(MAX_FULL_ROUNDS):
        replay(todo, i)
        kept = {c.cell_id for c in todo if not state.why[c.cell_id]}
        found = refit()
        following = proposed(laws, rounds, found[found["cell_id"].isin(kept)])
        ids = [c for c, new in following.items() if moved(laws[c], new)]
        laws.update({c: following[c] for c in ids})
        todo = [c for c in cells if c.cell_id in ids]
        if not todo:
            break
    return [c.cell_id for c in todo]


def _widenings(state: Factors, laws: dict[str, Laws], cells: list[Cell],
               replay: Callable[[list[Cell], dict[str, Laws], str], dict[str, np.ndarray | str]],
               fit: Callable[[np.ndarray], pd.DataFrame]) -> dict[str, dict[str, float]]:
    """Each corrected cell's widening per exponent (`analysis.afm.fixed_point_span`): `replay(todo,
    laws, label)` its linearised replay at its memory with `laws` and with each of MOVED `shifted`,
    `fit(factors)` the laws of the segments corrected by `factors` (the reading's own factors plus
    a replay's difference from the first); a cell a replay fails is not widened."""
    todo = [c for c in cells if c.cell_id in laws and not state.why[c.cell_id]]
    ids = [c.cell_id for c in todo]
    label = f"protocol: the exponents' feedback {{}} (of {len(MOVED) + 1})"
    base = replay(todo, laws, label.format(1))
    found = fit(state.factors).set_index("cell_id")
    tried: dict[str, list[Laws]] = {c: [] for c in ids}
    refound: dict[str, list[Laws]] = {c: [] for c in ids}
    usable = set(c for c in ids if isinstance(base[c], np.ndarray) and c in found.index)
    for k, law in enumerate(MOVED):
        these = {c: shifted(laws[c], law) for c in ids}
        again, factors = replay(todo, these, label.format(k + 2)), state.factors.copy()
        for c in ids:
            b, a = base[c], again[c]
            if isinstance(b, np.ndarray) and isinstance(a, np.ndarray):
                factors[state.rows[c]] += a - b
            else:
                usable.discard(c)
        now = fit(factors).set_index("cell_id")
        usable &= set(now.index)
        for c in usable:
            tried[c].append(these[c])
            refound[c].append(now.loc[c].to_dict())
    return {c: widening(jacobian(laws[c], found.loc[c].to_dict(), tried[c], refound[c])) for c in usable}


def corrected(measured: Measured, cells: list[Cell], inversion: Inversion, model: ComplexModel, bending: str,
              errors: MeasurementErrors | None, wait_s: float | None, lags: dict[float, float] | None = None,
              jobs: int = 1, full_last: bool = FULL_LAST, memory_s: float | None = None,
              store: ReplayStore | None = None) -> tuple[Measured, list[Measured], dict[str, dict[str, float]]]:
    """`measured` with its segments corrected for the carried stress (module docstring), the same
    corrected with each cell's memory at the ends of its 95 % interval (`Factors.ends`; none for a
    given memory), and each corrected cell's widening per exponent (`_widenings`); `memory_s` τ_c
    (s), None: each cell's own from its data (`analysis.afm.memory_fit`); every replay read back
    from `store` where a reading wrote it, else written there (`analysis.afm.replay_store`)."""
    volumes = pd.Series({c.cell_id: c.volume_um3 for c in cells})
    raw = measured.segments
    rows = {c.cell_id: np.flatnonzero(raw["cell_id"].to_numpy() == c.cell_id) for c in cells}
    nodes: tuple[Node, ...] = (*MEMORY_GRID_S, RELAXED) if memory_s is None else (memory_s,)
    state = Factors(raw, rows, {c.cell_id: "no viscoelastic point fit of its segments" for c in cells})
    replays, fulls = {c.cell_id: 0 for c in cells}, {c.cell_id: 0 for c in cells}
    laws: dict[str, Laws] = {}

    def found(now: Measured, table: Measured) -> pd.DataFrame:
        return cortex_laws(point_moduli(inverted(table, inversion, bending, errors, math.inf), now.segments, model,
                                        bending, lags))

    def refit(i: int = 1) -> pd.DataFrame:
        now = state.measured(volumes, measured, [], replays, fulls)
        return started(found(now, measured), raw) if i == 0 else found(now, now)

    def replayed(todo: list[Cell], label: str, asked: dict[str, tuple[Node, ...]], new_laws: bool) -> None:
        state.replayed(_factors(todo, laws, bending, wait_s, jobs, label, asked, store=store), new_laws)
        replays.update({c.cell_id: replays[c.cell_id] + 1 for c in todo})
        state.choose(memory_s)

    def linearised(todo: list[Cell], i: int) -> None:
        replayed(todo, f"protocol round {i + 1} (at most {MAX_ROUNDS})",
                 {c.cell_id: state.asked(c.cell_id, nodes) for c in todo}, new_laws=True)

    def closing(todo: list[Cell], label: str, asked: dict[str, tuple[Node, ...]]) -> None:
        replayed(todo, label, asked, new_laws=False)

    def at_memory(todo: list[Cell], these: dict[str, Laws], label: str,
                  linearised: bool = True) -> dict[str, np.ndarray | str]:
        chosen = {c.cell_id: (node(state.memory[c.cell_id]),) for c in todo}
        return {c: next(iter(f[0].values())) for c, f in _factors(todo, these, bending, wait_s, jobs, label,
                                                                   chosen, linearised, store).items()}

    def full(todo: list[Cell], i: int) -> None:
        state.full(at_memory(todo, laws, f"protocol: full replay {i + 1} (at most {MAX_FULL_ROUNDS})", False))
        fulls.update({c.cell_id: fulls[c.cell_id] + 1 for c in todo})

    def fitted(factors: np.ndarray) -> pd.DataFrame:
        now = state.measured(volumes, measured, [], replays, fulls, factors)
        return found(now, now)

    moving = _linearised_rounds(state, laws, cells, linearised, refit)
    _closed(state, cells, nodes, closing)
    if full_last:
        moving = _full_rounds(state, laws, cells, full, refit)
    ends = [] if memory_s is not None else state.ends()
    widenings = _widenings(state, laws, cells, at_memory, fitted)
    return (state.measured(volumes, measured, moving, replays, fulls),
            [state.measured(volumes, measured, moving, replays, fulls, f) for f in ends], widenings)
