"""The cortex's memory decided by a cell's recording: the drift of its mean tension across
heights (SPEC 10, 12; docs/memory.md).

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
candidate

    S = Σ_j (T_j - mean_{f_j} T)²,   s² = min S / (n - m - 1),   F = (S - min S) / s²,

with one mean per frequency f (m frequencies): only the change with depth reads the memory, not a
pattern across the frequencies at one height (the linearised replay's mean tension is the state's
at h_m, not the oscillation's mean, and differs by about 2 % at 0.1 Hz). The estimate is the
candidate of least S, the 95 % set {F ≤ F_0.95(1, n - m - 1)} (n segments; m + 1 parameters), the
noise s² the best fit's own residual. A node whose correction is impossible (a corrected tension
≤ 0, or no equilibrium in the replay) is left out. The memory is `identified` when its set does
not hold both ends of the carried family (0 and ∞).

Pooled (`pooled`): where a cell cannot tell, the cells' F summed over the population, its least
sum the estimate and {ΣF - min ≤ χ²_0.95(1)} the set; if that holds both ends too, the data do
not decide the memory and UNDECIDED_S (the pure power law, carried) is assumed and said.

Where this stops being true: a γ_a that drifts on its own (blebbing, a cortex that stiffens with
depth) reads as memory; a cell at one height has no drift to read (its memory is pooled); the
power laws' own errors move the estimate (the rounds fit both); and the power laws are fitted from
the segments as if the memory did not bend K*(f).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.stats import chi2, f as fisher

MEMORY_GRID_S = (0.0, 3.0, 10.0, 30.0, 100.0, 300.0, math.inf)
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
    """τ_c (s) of the carried coordinate φ (inverse of `carried`)."""
    return math.inf if phi >= 1.0 else T_REF_S * phi / (1.0 - phi)


def _candidates(shifts: Mapping[Node, npt.NDArray[np.float64]], n: int) -> tuple[npt.NDArray[np.float64], tuple[float, float]]:
    """Δγ (len(PHI) + 1, n): the carried nodes interpolated onto PHI (NaN outside the usable nodes)
    and RELAXED last (NaN if not usable); the usable carried nodes' φ range."""
    nodes = sorted(m for m in shifts if m != RELAXED)
    out = np.full((PHI.size + 1, n), np.nan)
    if nodes:
        phi = carried(nodes)
        table = np.array([shifts[m] for m in nodes])
        for j in range(n):
            out[:-1, j] = np.interp(PHI, phi, table[:, j], left=np.nan, right=np.nan)
    if RELAXED in shifts:
        out[-1] = shifts[RELAXED]
    ends = (float(carried(nodes[0])), float(carried(nodes[-1]))) if nodes else (math.nan, math.nan)
    return out, ends


def profile(tension_mN_per_m: npt.ArrayLike, shifts: Mapping[Node, npt.NDArray[np.float64]],
            frequency_hz: npt.ArrayLike | None = None) -> MemoryFit:
    """The memory of one cell from its segments' mean tensions, their frequencies (None: one) and
    the replays' tension shifts Δγ_j at the usable candidates (`shifts`: τ_c (s) of the carried
    history, or RELAXED → (n,) mN/m; module docstring)."""
    t = np.asarray(tension_mN_per_m, float)
    groups = np.unique(np.zeros(t.size) if frequency_hz is None else np.asarray(frequency_hz, float),
                       return_inverse=True)[1]
    dof = t.size - groups.max() - 2
    if dof < 1 or len(shifts) < 2:
        return UNDECIDED
    dg, ends = _candidates(shifts, t.size)
    corrected = t[None, :] - dg
    means = np.stack([corrected[:, groups == g].mean(axis=1) for g in range(groups.max() + 1)], axis=1)
    s = np.sum((corrected - means[:, groups]) ** 2, axis=1)
    best = float(np.nanmin(s))
    excess = (s - best) / max(best / dof, 1e-12 * float(np.mean(t ** 2)))
    return _fit(np.where(np.isnan(excess), np.inf, excess), fisher.ppf(LEVEL, 1, dof), ends)


def _fit(excess: npt.NDArray[np.float64], threshold: float, ends: tuple[float, float]) -> MemoryFit:
    """The estimate and set of a profile `excess` (PHI, then RELAXED) against `threshold`; `ends`
    the φ range of the usable carried nodes."""
    best = int(np.argmin(excess))
    inside = np.flatnonzero(excess[:-1] <= threshold)
    lo, hi = (PHI[inside.min()], PHI[inside.max()]) if inside.size else (math.nan, math.nan)
    identified = not (inside.size and lo <= ends[0] and hi >= ends[1])
    relaxed = best == PHI.size
    return MemoryFit(math.inf if relaxed else seconds(PHI[best]), seconds(lo) if inside.size else math.nan,
                     seconds(hi) if inside.size else math.nan, identified, excess, relaxed,
                     bool(excess[-1] <= threshold))


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
    ends = (PHI[usable[0]], PHI[usable[-1]]) if usable.size else (math.nan, math.nan)
    fit = _fit(total - np.min(total), chi2.ppf(LEVEL, 1), ends)
    return fit if fit.identified else UNDECIDED
