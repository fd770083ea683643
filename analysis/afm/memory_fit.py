"""The cortex's memory τ_c decided by a cell's recording: the drift of its mean tension across
heights (SPEC 10, 12; docs/viscoelastic.md).

A cortex K(t) = K(1 s) t^-β e^(-t/τ_c) keeps part of every earlier height step's stress; how much
a segment j still carries is the replay's tension shift Δγ_j(τ_c) (`analysis.afm.replayed`). γ_a is
constant (SPEC 10), so at the right memory the corrected mean tensions

    T_j(τ_c) = <γ_eff>_j - Δγ_j(τ_c)

are one number plus noise, and the wrong memory leaves a drift with depth. Per cell, with the
replay at the nodes of MEMORY_GRID_S (0: the relaxed state, Δγ = 0, nothing kept; inf: the pure
power law) and Δγ_j interpolated linearly between them in the carried coordinate
φ = τ_c / (τ_c + T_REF_S) (0 → 0, ∞ → 1),

    S(φ) = Σ_j (T_j - mean_j T_j)²,   s² = min S / (n - 2),   F(φ) = (S(φ) - min S) / s²,

the estimate is the φ of least S and the 95 % interval {F ≤ F_0.95(1, n - 2)}, the noise s² taken
from the best fit's own residual (n segments, 2 parameters: γ_a and τ_c). A node whose correction
is impossible (a corrected tension ≤ 0, or no equilibrium in the replay) is left out of the fit.
The memory is `identified` when the interval does not hold both ends (0 and ∞).

Pooled (`pooled`): where a cell cannot tell, the cells' F summed over the population, its least
sum the estimate and {ΣF - min ≤ χ²_0.95(1)} the interval; if that holds both ends too, the data
do not decide the memory and UNDECIDED_S (the pure power law) is assumed and said.

Where this stops being true: a γ_a that drifts on its own (blebbing, a cortex that stiffens with
depth) reads as memory; a cell at one height has no drift to read (its memory is pooled); and the
power laws are fitted from the segments as if the memory did not bend K*(f) (for τ_c ≥ 10 s at
f ≥ 0.1 Hz it moves |K*| by < 1 %).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.stats import chi2, f as fisher

MEMORY_GRID_S = (0.0, 3.0, 10.0, 30.0, 100.0, 300.0, math.inf)
T_REF_S = 30.0            # s: the carried coordinate's scale φ = τ_c / (τ_c + T_REF_S)
UNDECIDED_S = math.inf    # s: the memory assumed where neither the cell nor the population decides it
LEVEL = 0.95
_FINE = 401               # points in φ over [0, 1] where F is evaluated


@dataclass(frozen=True)
class MemoryFit:
    """A memory τ_c (s) with its 95 % interval; `identified`: the interval does not hold both 0 and ∞;
    `excess` F(φ) on `PHI` (the profile, for pooling; None where the cell has < 3 usable segments)."""

    memory_s: float
    lo95_s: float
    hi95_s: float
    identified: bool
    excess: npt.NDArray[np.float64] | None


PHI = np.linspace(0.0, 1.0, _FINE)


def carried(memory_s: float | npt.ArrayLike) -> npt.NDArray[np.float64]:
    """φ = τ_c / (τ_c + T_REF_S): 0 for τ_c = 0, 1 for ∞."""
    tau = np.asarray(memory_s, float)
    with np.errstate(invalid="ignore"):
        return np.where(np.isinf(tau), 1.0, tau / (tau + T_REF_S))


def seconds(phi: float) -> float:
    """τ_c (s) of the carried coordinate φ (inverse of `carried`)."""
    return math.inf if phi >= 1.0 else T_REF_S * phi / (1.0 - phi)


def _shifts_on_phi(shifts: Mapping[float, npt.NDArray[np.float64]]) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """(φ nodes, Δγ at the nodes (nodes, n)) interpolated linearly onto PHI where both neighbours exist."""
    nodes = sorted(shifts)
    phi = carried(nodes)
    table = np.array([shifts[t] for t in nodes])
    return phi, np.array([np.interp(PHI, phi, table[:, j], left=np.nan, right=np.nan) for j in range(table.shape[1])]).T


def profile(tension_mN_per_m: npt.ArrayLike, shifts: Mapping[float, npt.NDArray[np.float64]]) -> MemoryFit:
    """The memory of one cell from its segments' mean tensions and the replay's tension shifts
    Δγ_j(τ_c) at the grid's usable nodes (`shifts`: τ_c (s) → (n,) mN/m; module docstring)."""
    t = np.asarray(tension_mN_per_m, float)
    n = t.size
    if n < 3 or len(shifts) < 2:
        return MemoryFit(UNDECIDED_S, 0.0, math.inf, False, None)
    phi_nodes, dg = _shifts_on_phi(shifts)
    corrected = t[None, :] - dg
    s = np.sum((corrected - corrected.mean(axis=1, keepdims=True)) ** 2, axis=1)
    best = int(np.nanargmin(s))
    noise = max(s[best] / (n - 2), 1e-12 * float(np.mean(t ** 2)))
    excess = (s - s[best]) / noise
    excess[np.isnan(excess)] = np.inf
    return _fit(excess, fisher.ppf(LEVEL, 1, n - 2), phi_nodes)


def _fit(excess: npt.NDArray[np.float64], threshold: float, phi_nodes: npt.NDArray[np.float64]) -> MemoryFit:
    """The estimate and interval of a profile `excess` on PHI against `threshold`."""
    best = int(np.argmin(excess))
    inside = np.flatnonzero(excess <= threshold)
    lo, hi = PHI[inside.min()], PHI[inside.max()]
    both_ends = lo <= phi_nodes.min() and hi >= phi_nodes.max()
    return MemoryFit(seconds(PHI[best]), seconds(lo), seconds(hi), not both_ends, excess)


def pooled(fits: Sequence[MemoryFit]) -> MemoryFit:
    """The population's memory: the cells' profiles summed (module docstring); undecided where
    no cell has one or the sum's interval holds both ends."""
    profiles = [f.excess for f in fits if f.excess is not None]
    if not profiles:
        return MemoryFit(UNDECIDED_S, 0.0, math.inf, False, None)
    total = np.sum(profiles, axis=0)
    usable = np.isfinite(total)
    if not usable.any():
        return MemoryFit(UNDECIDED_S, 0.0, math.inf, False, None)
    fit = _fit(total - total[usable].min(), chi2.ppf(LEVEL, 1), PHI[usable][[0, -1]])
    return fit if fit.identified else MemoryFit(UNDECIDED_S, fit.lo95_s, fit.hi95_s, False, fit.excess)
