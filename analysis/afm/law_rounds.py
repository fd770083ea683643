"""What the protocol-aware reading replays next: each cell's power laws for its next replay, and
whether it has settled (the policy of `analysis.afm.protocol_reading`'s rounds; SPEC 12).

The rounds look for a fixed point θ* = g(θ*), where g(θ) is the point fit of a cell's segments
corrected with the power laws θ (K_B(1 s), K_S(1 s), β_B, β_S and γ_a). In the coordinates

    z = (ln K_B / 0.02, ln K_S / 0.02, β_B / 0.01, β_S / 0.01, ln γ_a / 0.02)

(SETTLED's tolerances are one unit each) the plain iteration θ_{k+1} = g(θ_k) creeps where g
contracts slowly: a cell read at one frequency moves its β_B by 0.090, 0.037, 0.019, 0.015, 0.012,
0.012, 0.0097 in successive rounds and stops, below the tolerance, 0.04 short of where it is
heading. So the next laws z_{k+1} are Anderson's mixing of the cell's last DEPTH + 1 rounds in z
(`analysis.mixing.mixed`; f_k = g(θ_k) − θ_k), exact in one round for a linear g in one dimension
(the secant); its move from g_k at most
MAX_EXTRAPOLATION |f_k| (a rate of contraction up to 0.8), β clipped to EXPONENT_RANGE. A cell has
settled when its next laws differ from the laws it was last replayed with by less than SETTLED
(β by the difference, moduli and γ_a by the log ratio): the extrapolated distance to the fixed
point, not the last step, which a slow contraction makes small long before it arrives.
"""

from __future__ import annotations

import math

import numpy as np

from analysis.afm.rheology import EXPONENT_RANGE
from analysis.mixing import mixed

Laws = dict[str, float]
SETTLED = {"bulk_beta": 0.01, "shear_beta": 0.01, "bulk_1s": 0.02, "shear_1s": 0.02, "tension": 0.02}
LOGS = ("bulk_1s", "shear_1s", "tension")
DEPTH = 2                   # rounds mixed beyond the last
MAX_EXTRAPOLATION = 4.0     # |z_{k+1} - g_k| ≤ this × |f_k|


def in_units(laws: Laws) -> np.ndarray:
    """The laws in the settled units (module docstring)."""
    return np.array([(math.log(laws[k]) if k in LOGS else laws[k]) / tol for k, tol in SETTLED.items()])


def of_units(z: np.ndarray, like: Laws) -> Laws:
    """`like` with the laws of `z`, β clipped to EXPONENT_RANGE."""
    out = dict(like)
    for (k, tol), v in zip(SETTLED.items(), z):
        out[k] = math.exp(v * tol) if k in LOGS else float(np.clip(v * tol, *EXPONENT_RANGE))
    return out


def next_laws(rounds: list[tuple[Laws, Laws]]) -> Laws:
    """A cell's laws for its next replay from its rounds, each (θ_k replayed, g(θ_k) found), oldest
    first (module docstring); one round: its g."""
    if len(rounds) < 2:
        return dict(rounds[-1][1])
    tried, found = (np.array([in_units(r[i]) for r in rounds]) for i in (0, 1))
    move = mixed(tried, found, DEPTH) - found[-1]
    limit = MAX_EXTRAPOLATION * float(np.linalg.norm(found[-1] - tried[-1]))
    size = float(np.linalg.norm(move))
    if size > limit:
        move *= limit / size
    return of_units(found[-1] + move, rounds[-1][1])


def moved(old: Laws | None, new: Laws) -> bool:
    """Whether `new` differs from `old` (None: never replayed) by more than SETTLED."""
    return old is None or any(abs(new[k] - old[k]) > tol if k.endswith("beta") else
                              abs(math.log(new[k] / old[k])) > tol for k, tol in SETTLED.items())
