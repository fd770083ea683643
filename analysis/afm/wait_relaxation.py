"""The cortex's memory read from how the force relaxes in a recording's waits (SPEC 10, 12;
docs/memory.md): the second witness beside the drift of the mean tension across heights
(`analysis.afm.memory_fit`).

After a height step the plate is held for the wait T_w and the force relaxes as the cortex does:
K(t) = K(1 s) t^-β e^(-t/τ_c) relaxes a short memory's stress within a few τ_c and a long one's
slowly through the whole wait. The replay of the cell's protocol at each candidate memory m
(`analysis.afm.replayed`) steps every wait from 1 s (`solver.protocol_simulation.LINEARISED`) and
gives μ_k(t; m), the force in wait k, interpolated linearly in ln t between its steps. The
recorded force F_ki at the samples t_ki of wait k (1 s ≤ t - t_k,0 ≤ T_w, waits of at least
MIN_WAIT_S) is fitted by

    F_ki = a_k + b_k μ_k(t_ki; m) + d (t_ki - t̄) + ε,     S_w(m) = min over a, b, d of Σ ε²,

an offset a_k and a scale b_k per wait (the fitted laws' and the recorded geometry's errors move
the force's level and the relaxation's size, not its shape) and one force drift d for the cell
(the instrument's, linear in time). Only the shape of each wait's relaxation reads m. On the
grid of `memory_fit.PHI` (μ linear in φ between the usable carried nodes, as Δγ is) and RELAXED
last:

    excess_w = (S_w - min S_w) / s_w²,   s_w² = min S_w / dof_w,   dof_w = n - 2K - 2,

which `memory_fit.profile` adds to the drift's excess.

Where this stops being true: a wait shorter than MIN_WAIT_S or sampled at fewer than
MIN_SAMPLES points (a JPK pause of 0.5 s) says nothing and is left out; a cell whose γ_a or
volume changes within a wait (a bleb) reads as memory; and within a wait of T_w a memory much
longer than T_w relaxes like the pure power law, so τ_c ≫ T_w is told apart from ∞ only by the
drift.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from analysis.afm.cell import Cell
from analysis.afm.memory_fit import Node, excess_over_best, interpolated_on_grid

Array = npt.NDArray[np.float64]
MIN_WAIT_S = 10.0       # s: a shorter wait is left out
FIRST_S = 1.0           # s: samples this soon after a wait's start are left out (the replay's first step)
MIN_SAMPLES = 5         # a wait with fewer samples is left out
Steps = list[tuple[Array, Array]]    # per wait of a replay: its steps' end times (s) and forces (nN)


@dataclass(frozen=True)
class Waits:
    """A cell's recorded waits: per sample its time (s), force (nN) and wait (index), which of a
    replay's long waits each wait is (`used`), and per memory the replay's force (nN) at the
    samples (`model`)."""

    time_s: Array
    force_nN: Array
    wait: npt.NDArray[np.int64]
    used: tuple[int, ...]
    model: Mapping[Node, Array]

    @property
    def count(self) -> int:
        return len(self.used)


def _long(steps: Steps) -> Steps:
    """The waits of a replay that can read the memory: at least MIN_WAIT_S long."""
    return [w for w in steps if w[0][-1] - w[0][0] >= MIN_WAIT_S]


def recorded(cell: Cell, steps: Steps) -> Waits | None:
    """The samples of `cell` in the replay's waits (`steps`, any memory's: they share the
    protocol's times) that read the memory (module docstring); None where no wait does."""
    t, f = np.asarray(cell.time_s, float), np.asarray(cell.force_nN, float)
    used: list[tuple[int, npt.NDArray[np.int64]]] = []
    for k, (ts, _) in enumerate(_long(steps)):
        at = np.flatnonzero((t >= ts[0] + FIRST_S) & (t <= ts[-1]) & np.isfinite(f))
        if at.size >= MIN_SAMPLES:
            used.append((k, at))
    if not used:
        return None
    at = np.concatenate([a for _, a in used])
    which = np.concatenate([np.full(a.size, i) for i, (_, a) in enumerate(used)])
    return Waits(t[at], f[at], which, tuple(k for k, _ in used), {})


def modelled(waits: Waits, steps: Steps) -> Array:
    """The replay's force (nN) at the samples of `waits` (`steps`: that replay's waits), linear
    in ln t between its steps."""
    long = _long(steps)
    out = np.empty(waits.time_s.size)
    for k, i in enumerate(waits.used):
        ts, fs = long[i]
        at = waits.wait == k
        out[at] = np.interp(np.log(waits.time_s[at] - ts[0]), np.log(ts[1:] - ts[0]), fs[1:])
    return out


def excess(waits: Waits) -> tuple[Array, int] | None:
    """The waits' excess on `memory_fit.PHI` and RELAXED last (module docstring; inf where no
    usable replay) and dof_w; None where the waits cannot be fitted."""
    K, n = waits.count, waits.time_s.size
    dof = n - 2 * K - 2
    if dof < 1 or len(waits.model) < 2:
        return None
    mu = interpolated_on_grid(waits.model, n)[0]
    onehot = (waits.wait[:, None] == np.arange(K)[None, :]).astype(float)
    drift = (waits.time_s - waits.time_s.mean()) / max(float(np.ptp(waits.time_s)), 1.0)
    s = np.full(mu.shape[0], np.inf)
    for i, m in enumerate(mu):
        if np.all(np.isfinite(m)):
            X = np.column_stack([onehot, onehot * m[:, None], drift])
            coef = np.linalg.lstsq(X, waits.force_nN, rcond=None)[0]
            s[i] = float(np.sum((waits.force_nN - X @ coef) ** 2))
    if not np.isfinite(np.min(s)):
        return None
    return excess_over_best(s, dof, float(np.mean(waits.force_nN ** 2))), dof
