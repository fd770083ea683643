"""Which memories a cell's next replay needs, and its replays at the others carried along.

The protocol-aware reading's first round replays a cell at every candidate memory
(`analysis.afm.memory_fit.MEMORY_GRID_S` and RELAXED); its profile F(τ_c) then sets the memory
and its 95 % interval, whose ends are the nearest nodes outside the set (`memory_fit._fit`). What
decides them is F at those nodes, at the nodes between and at the next node beyond each end (F
between nodes is interpolated linearly in φ, so F between an end and the node beyond it says
whether the set reaches past the end): a node further out moves neither the estimate nor its
interval. So a later round, whose power laws moved a little, replays a cell whose memory is
identified (`fitted`) only at its `deciding` nodes,

    D = {m : φ(lo95) ≤ φ(m) ≤ φ(hi95)} ∪ {the next node below lo95 and above hi95}
        ∪ {the nodes bracketing τ_c} ∪ {RELAXED, ∞ where the relaxed history is the memory or
        in its set},

and carries every other node m along from its last replay by the change the nearest replayed
node m* saw (`merged`):

    f_m ← f_m^old + (f_m* − f_m*^old),   the same for each wait's modelled force,

(φ distance; RELAXED's nearest is ∞, τ_c = 0 is the identity and never moves). A node so carried
is stale: the reading replays every stale node the final memory needs at the final laws before
it moves on (`protocol_reading`), so the memory and its interval always rest on replays at the
laws they are read with. Pooled and assumed cells (their own set holds 0 and ∞) are replayed at
every node: the population's profile sums all of them.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import replace
from typing import TypeVar

import numpy as np

from analysis.afm.memory_fit import RELAXED, MemoryFit, Node, carried
from analysis.afm.wait_relaxation import Waits

V = TypeVar("V")      # a node's entry: its factors (an array) or why not (a string); a wait's force


def _phi(m: Node) -> float:
    """φ of a node; RELAXED at φ = 1, beside ∞."""
    return 1.0 if m == RELAXED else float(carried(m))


def deciding(fit: MemoryFit, nodes: Sequence[Node]) -> tuple[Node, ...]:
    """The nodes of `nodes` that decide an identified memory `fit` and its 95 % interval (module
    docstring); all of them where it is not identified."""
    if not fit.identified:
        return tuple(nodes)
    carried_nodes = sorted((m for m in nodes if m != RELAXED), key=_phi)
    want: set[Node] = {0.0}
    if fit.relaxed or fit.relaxed_in_set:
        want |= {RELAXED, math.inf}
    if not fit.relaxed:             # the two nodes its factors are interpolated from
        x = _phi(fit.memory_s)
        want |= set([m for m in carried_nodes if _phi(m) <= x + 1e-9][-1:]
                    + [m for m in carried_nodes if _phi(m) >= x - 1e-9][:1])
    if not (math.isnan(fit.lo95_s) or math.isnan(fit.hi95_s)):
        lo, hi = _phi(fit.lo95_s), _phi(fit.hi95_s)
        inside = [k for k, m in enumerate(carried_nodes) if lo - 1e-9 <= _phi(m) <= hi + 1e-9]
        if inside:      # and one node beyond each end: F between it and the end decides the end
            want |= set(carried_nodes[max(inside[0] - 1, 0): inside[-1] + 2])
    return tuple(m for m in nodes if m in want)


def _nearest(m: Node, fresh: Sequence[Node]) -> Node | None:
    """The node of `fresh` nearest to `m` in φ (RELAXED: ∞ if there), None if none is."""
    if m == RELAXED:
        return math.inf if math.inf in fresh else None
    candidates = [n for n in fresh if n != RELAXED and n != 0]
    return min(candidates, key=lambda n: abs(_phi(n) - _phi(m))) if candidates else None


def _moved(old: Mapping[Node, object], new: Mapping[Node, object], m: Node) -> np.ndarray | None:
    """new[m] - old[m] where both are arrays of one shape, else None."""
    a, b = old.get(m), new.get(m)
    if isinstance(a, np.ndarray) and isinstance(b, np.ndarray) and a.shape == b.shape:
        return b - a
    return None


def _carried_along(old: Mapping[Node, V], new: Mapping[Node, V]) -> dict[Node, V]:
    """`old`'s nodes that `new` lacks, each moved by its nearest replayed node's change."""
    out: dict[Node, V] = {}
    fresh = [n for n, v in new.items() if isinstance(v, np.ndarray)]      # a node that failed moves none
    for m, value in old.items():
        if m in new:
            continue
        near = _nearest(m, fresh) if m != 0 else None
        d = None if near is None else _moved(old, new, near)
        out[m] = value + d if isinstance(value, np.ndarray) and d is not None and d.shape == value.shape else value
    return out


def merged(old: Mapping[Node, V], new: Mapping[Node, V]) -> dict[Node, V]:
    """A cell's grid after a replay at the nodes of `new`: those replayed, the others carried
    along from `old` (module docstring)."""
    return {**_carried_along(old, new), **new}


def merged_waits(old: Waits | None, new: Waits | None) -> Waits | None:
    """A cell's waits after a replay at some nodes: each wait's force at the nodes not replayed
    carried along as `merged` carries the factors."""
    if old is None or new is None:
        return new if new is not None else old
    return replace(new, model={**_carried_along(old.model, new.model), **new.model})
