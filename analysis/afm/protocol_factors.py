"""Each cell's protocol correction at its memory: the state the protocol-aware reading's rounds
keep (`analysis.afm.protocol_reading`).

A cell's replays give its factors (|c|, arg c, Δγ per segment, `analysis.afm.replayed`) at each
memory asked for (the nodes of `analysis.afm.memory_fit.MEMORY_GRID_S` and its RELAXED history,
or the τ_c given).
A node is usable where its replay found an equilibrium and no corrected mean tension
<γ_eff>_j - Δγ_j is ≤ 0 (`refused`). The cell's memory (`choose`), and where it comes from
(MEMORY_COLUMNS' `protocol_memory_source`):

    given    --memory-s S: every cell's;
    fitted   the cell's own profile identifies it (`memory_fit.profile`);
    pooled   it does not, the population's summed profile does (`memory_fit.pooled`);
    assumed  neither does: UNDECIDED_S (the pure power law), said in the report.

The factors at a memory between nodes are interpolated linearly in the carried coordinate φ
(`memory_fit.carried`), as the profile interpolates Δγ; the reading's last correction replays the
memory itself (`full`). MEMORY_COLUMNS: τ_c (s; inf with a relaxed history: nothing forgotten
within a height), its 95 % interval over the carried history (NaN where only the relaxed history
is in the set), the source and the history (carried | relaxed).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
import pandas as pd

from analysis.afm.analyze import Measured, measured_of
from analysis.afm.memory_fit import RELAXED, UNDECIDED, MemoryFit, Node, carried, pooled, profile
from analysis.afm.memory_nodes import deciding, merged, merged_waits
from analysis.afm.replayed import apply
from analysis.afm.wait_relaxation import Waits, excess

MEMORY_COLUMNS = ("protocol_memory_s", "protocol_memory_lo95_s", "protocol_memory_hi95_s", "protocol_memory_source",
                  "protocol_history")
Grid = dict[Node, "np.ndarray | str"]


def refused(tension_mN_per_m: np.ndarray, factors: np.ndarray) -> str | None:
    """Why a cell's correction is refused: a corrected mean tension <γ_eff>_j - Δγ_j ≤ 0; None if none."""
    after = np.asarray(tension_mN_per_m, float) - factors[:, 2]
    bad = np.flatnonzero(after <= 0)
    if not bad.size:
        return None
    j = int(bad[0])
    return (f"corrected tension ≤ 0 refused (segment {j}: {tension_mN_per_m[j]:.3g} - "
            f"{factors[j, 2]:.3g} = {after[j]:.3g} mN/m)")


def _why(f: np.ndarray | str, tension: np.ndarray) -> str:
    """Why the factors `f` cannot be used ("" if they can)."""
    return f if isinstance(f, str) else (refused(tension, f) or "")


def node(fit: MemoryFit) -> Node:
    """The replay a memory asks for: RELAXED, or its τ_c (s)."""
    return RELAXED if fit.relaxed else fit.memory_s


def interpolated(grid: Grid, tension: np.ndarray, fit: MemoryFit) -> np.ndarray | str:
    """The factors at the memory `fit`, linear in φ between the grid's usable carried nodes; outside
    them, why not."""
    if fit.relaxed or node(fit) in grid:
        found = grid[node(fit)]
        return _why(found, tension) or found
    memory_s = fit.memory_s
    usable = {m: f for m, f in grid.items() if m != RELAXED and not _why(f, tension)}
    if not usable:
        return next(_why(f, tension) for f in grid.values())
    nodes = sorted(usable)
    phi, x = carried(nodes), float(carried(memory_s))
    if not phi[0] <= x <= phi[-1]:
        near = min((m for m in grid if m != RELAXED), key=lambda m: abs(float(carried(m)) - x))
        return _why(grid[near], tension) or f"no usable replay at a memory of {memory_s:g} s"
    stack = np.array([usable[m] for m in nodes], float)
    return np.apply_along_axis(lambda y: np.interp(x, phi, y), 0, stack)


@dataclass
class Factors:
    """The rounds' state: per cell its replays (`grids`), memory and its source, and the factors
    of every raw segment (NaN rows: not corrected, for the reason `why` gives)."""

    raw: pd.DataFrame
    rows: dict[str, np.ndarray]
    why: dict[str, str]
    grids: dict[str, Grid] = field(default_factory=dict)
    waits: dict[str, Waits | None] = field(default_factory=dict)
    memory: dict[str, MemoryFit] = field(default_factory=dict)
    source: dict[str, str] = field(default_factory=dict)
    fulls: dict[str, np.ndarray] = field(default_factory=dict)
    fresh: dict[str, set[Node]] = field(default_factory=dict)
    at_memories: dict[str, int] = field(default_factory=dict)     # replays at one memory (τ_c = 0 needs none)

    def __post_init__(self) -> None:
        self.factors = np.full((len(self.raw), 3), np.nan)
        self.tension = self.raw["tension_mN_per_m"].to_numpy(float)

    def _set(self, cell: str, f: np.ndarray | str) -> None:
        at = self.rows[cell]
        self.why[cell] = _why(f, self.tension[at])
        self.factors[at] = np.nan if self.why[cell] else f

    def replayed(self, found: dict[str, tuple[Grid, Waits | None]], new_laws: bool = True) -> None:
        """A round's replays: per cell its factors at the memories replayed and its waits, the
        others carried along from its last replay (`analysis.afm.memory_nodes.merged`); with
        `new_laws` only those replayed are fresh, else they join the fresh ones (the same laws)."""
        for c, (grid, waits) in found.items():
            self.grids[c] = merged(self.grids.get(c, {}), grid)
            self.waits[c] = merged_waits(self.waits.get(c), waits)
            self.fresh[c] = set(grid) | (set() if new_laws else self.fresh.get(c, set()))
            self.at_memories[c] = self.at_memories.get(c, 0) + sum(m != 0 for m in grid)

    def asked(self, cell: str, nodes: tuple[Node, ...]) -> tuple[Node, ...]:
        """The memories of `nodes` the cell's next replay needs: all of them for a cell not yet
        replayed or whose memory is not its own (`fitted`), else those that decide its memory
        and interval (`analysis.afm.memory_nodes.deciding`)."""
        if cell not in self.memory or self.source.get(cell) != "fitted":
            return nodes
        return deciding(self.memory[cell], nodes)

    def stale(self, nodes: tuple[Node, ...]) -> dict[str, tuple[Node, ...]]:
        """Per cell the memories its memory and interval rest on (`deciding`) that were not
        replayed at its last laws (carried along instead; τ_c = 0 needs no replay); only cells
        with any."""
        out = {}
        for c in self.grids:
            missing = tuple(m for m in self.asked(c, nodes) if m != 0 and m not in self.fresh.get(c, set()))
            if missing:
                out[c] = missing
        return out

    def _profile(self, cell: str) -> MemoryFit:
        """The cell's memory from the drift of its mean tensions and its waits, over the usable nodes."""
        at = self.rows[cell]
        t = self.tension[at]
        usable = {m: f for m, f in self.grids[cell].items() if isinstance(f, np.ndarray) and not _why(f, t)}
        waits = self.waits.get(cell)
        witness = None if waits is None else excess(replace(waits, model={m: waits.model[m] for m in usable
                                                                          if m in waits.model}))
        return profile(t, {m: f[:, 2] for m, f in usable.items()}, self.raw["frequency_hz"].to_numpy(float)[at],
                       witness)

    def choose(self, memory_s: float | None) -> None:
        """Every replayed cell's memory (module docstring) and its factors there."""
        fits = {c: self._profile(c) for c in self.grids} if memory_s is None else {}
        population = pooled(list(fits.values()))
        for c in self.grids:
            if memory_s is not None:
                self.memory[c], self.source[c] = MemoryFit(memory_s, memory_s, memory_s, True), "given"
            elif fits[c].identified:
                self.memory[c], self.source[c] = fits[c], "fitted"
            elif population.identified:
                self.memory[c], self.source[c] = population, "pooled"
            else:
                self.memory[c], self.source[c] = UNDECIDED, "assumed"
            self._set(c, interpolated(self.grids[c], self.tension[self.rows[c]], self.memory[c]))

    def full(self, found: dict[str, np.ndarray | str]) -> None:
        """The full replays' factors at each cell's memory replace the interpolated ones."""
        for c, f in found.items():
            self._set(c, f)
            if isinstance(f, np.ndarray) and not self.why[c]:
                self.fulls[c] = f
            else:
                self.fulls.pop(c, None)

    def ends(self) -> list[np.ndarray]:
        """The factors of every raw segment with each cell's memory moved to the ends of its 95 %
        interval (`memory_ends`; a cell without such an end keeps its own factors): the lower end,
        the upper, the other history. Each from the cell's grid shifted by its full replay's defect
        at its memory (`shifted_grid`), so that an end differs from the memory by what the grid
        says the memory changes, not by the linearised replay's bias. A given memory keeps its own."""
        out = [self.factors.copy() for _ in range(3)]
        for c, fit in self.memory.items():
            if self.source[c] == "given" or self.why[c]:
                continue
            grid, at = self.shifted_grid(c), self.rows[c]
            for k, end in enumerate(memory_ends(fit)):
                f = None if end is None else interpolated(grid, self.tension[at], end)
                if isinstance(f, np.ndarray):
                    out[k][at] = f
        return out

    def shifted_grid(self, cell: str) -> Grid:
        """The cell's grid with every node that keeps stress (all but τ_c = 0) shifted by the full
        replay's defect at its memory, d = f_full - the grid's there; the grid itself where the cell
        has no usable full replay."""
        grid, full = self.grids[cell], self.fulls.get(cell)
        at = interpolated(grid, self.tension[self.rows[cell]], self.memory[cell])
        if full is None or not isinstance(at, np.ndarray):
            return grid
        d = full - at
        return {m: g + d if isinstance(g, np.ndarray) and m != 0 else g for m, g in grid.items()}

    def measured(self, volumes: pd.Series, measured: Measured, moving: list[str], replays: dict[str, int],
                 fulls: dict[str, int], factors: np.ndarray | None = None) -> Measured:
        """The `Measured` of the raw segments corrected by the factors (`factors`: others in their
        place, as `ends`); `moving` the cells not settled, `replays` how often each was replayed
        linearised, `fulls` fully; the memory in MEMORY_COLUMNS."""
        segments = apply(self.raw, self.factors if factors is None else factors)
        cells = segments["cell_id"]
        segments["protocol_corrected"] = ~np.isnan(self.factors[:, 0])
        segments["protocol_reason"] = cells.map(self.why).fillna("").where(~segments["protocol_corrected"], "")
        segments["protocol_settled"] = ~cells.isin(moving)
        segments["protocol_replays"] = cells.map(replays).fillna(0).astype(int)
        segments["protocol_memory_replays"] = cells.map(self.at_memories).fillna(0).astype(int)
        segments["protocol_full_replays"] = cells.map(fulls).fillna(0).astype(int)
        for name, value in zip(MEMORY_COLUMNS, (lambda f: f.memory_s, lambda f: f.lo95_s, lambda f: f.hi95_s)):
            segments[name] = cells.map({c: value(f) for c, f in self.memory.items()}).astype(float)
        segments["protocol_memory_source"] = cells.map(lambda c: self.source.get(c, ""))
        segments["protocol_history"] = cells.map(lambda c: (RELAXED if self.memory[c].relaxed else "carried")
                                                 if c in self.memory else "")
        return measured_of(segments.assign(volume_um3=cells.map(volumes)), measured.order)


def memory_ends(fit: MemoryFit) -> tuple[MemoryFit | None, MemoryFit | None, MemoryFit | None]:
    """The memories at the ends of `fit`'s 95 % interval: τ_c at the lower and the upper end of its
    carried part (None where it has none, or where the end is the memory itself), and the relaxed
    history where a carried memory's set holds it (a relaxed memory's other history is its
    carried part, so its third is None)."""
    ends = [None if math.isnan(e) or (e == fit.memory_s and not fit.relaxed) else _given(e)
            for e in (fit.lo95_s, fit.hi95_s)]
    other = _given(math.inf, relaxed=True) if fit.relaxed_in_set and not fit.relaxed else None
    return ends[0], ends[1], other


def _given(memory_s: float, relaxed: bool = False) -> MemoryFit:
    """A memory taken as it is: its interval itself."""
    return MemoryFit(memory_s, memory_s, memory_s, True, relaxed=relaxed)


def with_memory(cells: pd.DataFrame, segments: pd.DataFrame) -> pd.DataFrame:
    """A cells table with each cell's memory (MEMORY_COLUMNS) from its corrected segments."""
    per_cell = segments.groupby("cell_id")[list(MEMORY_COLUMNS)].first()
    return cells.join(per_cell, on="cell_id")
