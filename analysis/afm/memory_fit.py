"""The cortex's memory decided by a cell's recording: the drift of its mean tension across
heights and the relaxation in its waits (SPEC 10, 12; docs/memory.md).

A cortex K(t) = K(1 s) t^-β e^(-t/τ_c) keeps part of every earlier height step's stress; how much
a segment j still carries is the replay's tension shift Δγ_j (`analysis.afm.replayed`). γ_a is
constant (SPEC 10), so under the right memory the corrected mean tensions

    T_j = <γ_eff>_j - Δγ_j

are one number per frequency plus noise, and a wrong memory leaves a drift with depth. The
candidates: the history carried through every height with τ_c on the nodes of MEMORY_GRID_S (0:
nothing kept, Δγ = 0, the relaxed-state reading; inf: the pure power law), Δγ_j interpolated
linearly between them in the carried coordinate φ = τ_c / (τ_c + T_REF_S) (0 → 0, ∞ → 1); and
RELAXED, the history relaxed at every height (each height from its own relaxed droplet one step
above, τ_c = ∞ within it: a cortex that forgets the earlier heights but not its last step). Per
candidate the drift's

    S = Σ_j (T_j - mean_{f_j} T)²,   s² = min S / (n - m - 1),   F = (S - min S) / s²,

with one mean per frequency f (m frequencies): only the change with depth reads the memory, not a
pattern across the frequencies at one height (the linearised replay's mean tension is the state's
at h_m, not the oscillation's mean, and differs by about 2 % at 0.1 Hz). The waits' witness
(`analysis.afm.wait_relaxation`: the shape of the force's relaxation in every wait of at least
10 s) adds its own F_w; the estimate is the candidate of least F + F_w, the 95 % set
{F + F_w - min(F + F_w) ≤ F_0.95(1, d)} (d the smaller of the two witnesses' dof; n segments and m + 1
parameters for the drift), each noise its best fit's own residual. The set rests on the
interpolation between the nodes, so the interval is no finer than them: its ends are the nearest
nodes outside the set. A node whose correction is impossible (a corrected tension ≤ 0, or no
equilibrium in the replay) is left out. The memory is `identified` when its set does not hold
both ends of the carried family (0 and ∞).

Pooled (`pooled`): where a cell cannot tell, the cells' F summed over the population, its least
sum the estimate and {ΣF - min ≤ χ²_0.95(1)} the set; if that holds both ends too, the data do
not decide the memory and UNDECIDED_S (the pure power law, carried) is assumed and said.

Where this stops being true: a γ_a that drifts on its own (blebbing, a cortex that stiffens with
depth) reads as memory, and so do the recorded geometry's errors (a height offset or a volume
error drifts F / (2 H A_c) with depth: the drift's interval is then too narrow, docs/memory.md);
a cell at one height without waits has nothing to read (its memory is pooled); the power laws'
own errors move the estimate (the rounds fit both); and the power laws are fitted from the
segments as if the memory did not bend K*(f).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.stats import chi2, f as fisher

MEMORY_GRID_S = (0.0, 3.0, 10.0, 30.0, 100.0, 300.0, 1000.0, 3000.0, math.inf)
RELAXED = "relaxed"       # the candidate whose history is relaxed at every height
T_REF_S = 30.0            # s: the carried coordinate's scale φ = τ_c / (τ_c + T_REF_S)
UNDECIDED_S = math.inf    # s: the memory assumed where neither the cell nor the population decides it
LEVEL = 0.95
PHI = np.linspace(0.0, 1.0, 401)      # where the carried family's F is evaluated; RELAXED after them
Node = float | str


@dataclass(frozen=True)
class MemoryFit:
    """A memory: τ_c (s) of the carried history, or the relaxed history (`relaxed`, τ_c = ∞
    within a height); the 95 % interval of τ_c over the carried candidates in the set (NaN: none),
    whether RELAXED is in it; `identified`: the set does not hold both 0 and ∞; `excess` F on PHI
    and RELAXED last (for pooling; None where the cell cannot be profiled)."""

    memory_s: float
    lo95_s: float
    hi95_s: float
    identified: bool
    excess: npt.NDArray[np.float64] | None = None
    relaxed: bool = False
    relaxed_in_set: bool = False


UNDECIDED = MemoryFit(UNDECIDED_S, 0.0, math.inf, False)


def carried(memory_s: float | npt.ArrayLike) -> npt.NDArray[np.float64]:
    """φ = τ_c / (τ_c + T_REF_S): 0 for τ_c = 0, 1 for ∞."""
    tau = np.asarray(memory_s, float)
    with np.errstate(invalid="ignore"):
        return np.where(np.isinf(tau), 1.0, tau / (tau + T_REF_S))


def seconds(phi: float) -> float:
    """τ_c (s) of the carried coordinate φ (inverse of `carried`, to 12 digits: a node's φ gives
    the node back)."""
    return math.inf if phi >= 1.0 else float(f"{T_REF_S * phi / (1.0 - phi):.12g}")


def interpolated_on_grid(shifts: Mapping[Node, npt.NDArray[np.float64]], n: int) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """Per node an (n,) quantity (Δγ, a wait's force) → (len(PHI) + 1, n): the carried nodes
    interpolated linearly in φ onto PHI (NaN outside the usable nodes) and RELAXED last (NaN if not
    usable); φ of the usable carried nodes."""
    nodes = sorted(m for m in shifts if m != RELAXED)
    out = np.full((PHI.size + 1, n), np.nan)
    if nodes:
        phi = carried(nodes)
        table = np.array([shifts[m] for m in nodes])
        for j in range(n):
            out[:-1, j] = np.interp(PHI, phi, table[:, j], left=np.nan, right=np.nan)
    if RELAXED in shifts:
        out[-1] = shifts[RELAXED]
    return out, _nodes(shifts)


def _nodes(shifts: Mapping[Node, object]) -> npt.NDArray[np.float64]:
    """φ of the usable carried nodes, ascending."""
    return carried(sorted(m for m in shifts if m != RELAXED)) if any(m != RELAXED for m in shifts) else np.zeros(0)


def profile(tension_mN_per_m: npt.ArrayLike, shifts: Mapping[Node, npt.NDArray[np.float64]],
            frequency_hz: npt.ArrayLike | None = None,
            waits: tuple[npt.NDArray[np.float64], int] | None = None) -> MemoryFit:
    """The memory of one cell from its segments' mean tensions, their frequencies (None: one) and
    the replays' tension shifts Δγ_j at the usable candidates (`shifts`: τ_c (s) of the carried
    history, or RELAXED → (n,) mN/m; module docstring), and the waits' witness (its excess on PHI
    and RELAXED, and its dof: `analysis.afm.wait_relaxation.excess`) added where there is one."""
    if len(shifts) < 2:
        return UNDECIDED
    parts = [p for p in (_drift(tension_mN_per_m, shifts, frequency_hz), waits) if p is not None]
    if not parts:
        return UNDECIDED
    total = np.sum([np.where(np.isnan(e), np.inf, e) for e, _ in parts], axis=0)
    return _fit(total - np.min(total), fisher.ppf(LEVEL, 1, min(d for _, d in parts)), _nodes(shifts))


def _drift(tension_mN_per_m: npt.ArrayLike, shifts: Mapping[Node, npt.NDArray[np.float64]],
           frequency_hz: npt.ArrayLike | None) -> tuple[npt.NDArray[np.float64], int] | None:
    """The drift's excess F on PHI and RELAXED (NaN: no usable replay) and its dof (module
    docstring); None where the segments leave no dof."""
    t = np.asarray(tension_mN_per_m, float)
    groups = np.unique(np.zeros(t.size) if frequency_hz is None else np.asarray(frequency_hz, float),
                       return_inverse=True)[1]
    dof = t.size - groups.max() - 2
    if dof < 1:
        return None
    dg = interpolated_on_grid(shifts, t.size)[0]
    corrected = t[None, :] - dg
    means = np.stack([corrected[:, groups == g].mean(axis=1) for g in range(groups.max() + 1)], axis=1)
    s = np.sum((corrected - means[:, groups]) ** 2, axis=1)
    return excess_over_best(s, int(dof), float(np.mean(t ** 2))), int(dof)


def excess_over_best(s: npt.NDArray[np.float64], dof: int, scale: float) -> npt.NDArray[np.float64]:
    """F = (S - min S) / s², s² = min S / dof the best fit's own residual (floored at 1e-12 of
    `scale`, the data's mean square, for a fit without residual); NaN where S is."""
    best = float(np.nanmin(s))
    return (s - best) / max(best / dof, 1e-12 * scale)


def _fit(excess: npt.NDArray[np.float64], threshold: float, nodes: npt.NDArray[np.float64]) -> MemoryFit:
    """The estimate and set of a profile `excess` (PHI, then RELAXED) against `threshold`; `nodes`
    φ of the usable carried nodes. The interval is no finer than the nodes: its ends are the
    nearest nodes outside the set (the set itself rests on the interpolation between them)."""
    best = int(np.argmin(excess))
    inside = np.flatnonzero(excess[:-1] <= threshold)
    relaxed = best == PHI.size
    if not inside.size or not nodes.size:
        return MemoryFit(math.inf if relaxed else seconds(PHI[best]), math.nan, math.nan, True, excess, relaxed,
                         bool(excess[-1] <= threshold))
    lo, hi = PHI[inside.min()], PHI[inside.max()]
    identified = not (lo <= nodes[0] and hi >= nodes[-1])
    lo = max((p for p in nodes if p < lo - 1e-9), default=lo)
    hi = min((p for p in nodes if p > hi + 1e-9), default=hi)
    return MemoryFit(math.inf if relaxed else seconds(PHI[best]), seconds(lo), seconds(hi), identified, excess,
                     relaxed, bool(excess[-1] <= threshold))


def pooled(fits: Sequence[MemoryFit]) -> MemoryFit:
    """The population's memory: the cells' profiles summed (module docstring); UNDECIDED where
    no cell has one or the sum's set holds both ends."""
    profiles = [f.excess for f in fits if f.excess is not None]
    if not profiles:
        return UNDECIDED
    total = np.sum(profiles, axis=0)
    usable = np.flatnonzero(np.isfinite(total[:-1]))
    if not usable.size and not np.isfinite(total[-1]):
        return UNDECIDED
    grid = carried(MEMORY_GRID_S)
    nodes = grid[(grid >= PHI[usable[0]] - 1e-9) & (grid <= PHI[usable[-1]] + 1e-9)] if usable.size else np.zeros(0)
    fit = _fit(total - np.min(total), chi2.ppf(LEVEL, 1), nodes)
    return fit if fit.identified else UNDECIDED
