"""The exponents' 95 % intervals of a fixed point: what the correction's feedback adds (SPEC 10,
12; docs/viscoelastic.md).

The protocol-aware reading's power laws are a fixed point θ* = g(θ*; y) of the point fit g of a
cell's segments y corrected with the laws θ (K_B(1 s), K_S(1 s), β_B, β_S, γ_a;
`analysis.afm.law_rounds`, in its settled units z). The point fit's interval holds the correction
fixed: it is the spread of g(θ*; y) over the data's errors δy. The fixed point moves with the
data further, since the correction moves with θ:

    δθ* = M (∂g/∂y) δy,   M = (I − J)⁻¹,   J = ∂g/∂θ at θ*.

J is a finite difference (`jacobian`) over the exponents β_B and β_S (MOVED): per exponent k, the
cell's segments corrected with the replay at θ* and at θ* with that exponent moved by STEP units
(`shifted`; the linearised replay at the cell's memory both times, their difference added to the
reading's own correction) and refitted, column k = Δz(g) / Δz_k over the exponents' rows. An
exponent's interval is widened about its point estimate by M_ββ (`widening`), clipped to
[1, MAX_WIDENING] (the rounds' own bound on a rate of contraction, `law_rounds.MAX_EXTRAPOLATION`,
is 1 − 1/MAX_WIDENING): the spread of β* were the data's error all in β's own fit, carried
through both exponents' feedback.

Where it stops being true: the feedback through K(1 s) and γ_a is left out (on a 40-cell
time-domain set read at its true memory, the full 5 × 5 J and β_S's own feedback alone widened
β_S's intervals by a median 1.16 and 1.24, with the same coverage, 24 of 25); the data's errors in
the other laws' fits also move β* and are left out; J is a slope over STEP, not at a point; a
widening below 1 (a correction that pulls β back) would narrow the interval: it is taken as 1.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import pandas as pd

from analysis.afm.law_rounds import MAX_EXTRAPOLATION, SETTLED, Laws, in_units, of_units
from analysis.afm.memory_span import EXPONENTS

LAWS = tuple(SETTLED)                               # the order of z
EXPONENT_LAWS = dict(zip(EXPONENTS, ("bulk_beta", "shear_beta")))   # rheology.csv's exponent: its law
MOVED = tuple(EXPONENT_LAWS.values())               # the laws J is taken over
WIDENING_COLUMNS = {name: f"{name}_widening" for name in EXPONENTS}
STEP = 2.0                                          # settled units: β by 0.02, K(1 s) and γ_a by 4 %
MAX_WIDENING = 1.0 + MAX_EXTRAPOLATION              # 5


def shifted(laws: Laws, law: str) -> Laws:
    """`laws` with `law` moved up by STEP settled units (down where β would pass its range)."""
    z, k = in_units(laws), LAWS.index(law)
    up = z.copy()
    up[k] += STEP
    moved = of_units(up, laws)
    if abs(in_units(moved)[k] - z[k] - STEP) > 1e-9:        # clipped to EXPONENT_RANGE
        z[k] -= STEP
        moved = of_units(z, laws)
    return moved


def jacobian(laws: Laws, found: Laws, moved: Sequence[Laws], found_moved: Sequence[Laws]) -> np.ndarray:
    """J over MOVED (settled units): column k the refit's move over the move of law MOVED[k]
    (`moved[k]`, found `found_moved[k]`) from `laws` (found `found`)."""
    rows = [LAWS.index(law) for law in MOVED]
    z0, g0 = in_units(laws), in_units(found)
    return np.column_stack([(in_units(g)[rows] - g0[rows]) / (in_units(m)[k] - z0[k])
                            for k, m, g in zip(rows, moved, found_moved)])


def widening(J: np.ndarray) -> dict[str, float]:
    """Per exponent M_ββ of M = (I − J)⁻¹ (J over MOVED), clipped to [1, MAX_WIDENING]; 1 where M is
    not finite."""
    try:
        M = np.linalg.inv(np.eye(len(J)) - J)
    except np.linalg.LinAlgError:
        M = np.full_like(J, np.nan)
    out = {}
    for name, law in EXPONENT_LAWS.items():
        m = M[MOVED.index(law), MOVED.index(law)]
        out[name] = float(np.clip(m, 1.0, MAX_WIDENING)) if np.isfinite(m) else 1.0
    return out


def widened(rheology: pd.DataFrame, widenings: Mapping[str, Mapping[str, float]]) -> pd.DataFrame:
    """`rheology` (one row per cell_id) with each exponent's interval widened about its estimate by
    the cell's factor (`widenings`: per cell, per exponent; a cell not in it: 1), the factor in
    WIDENING_COLUMNS."""
    out = rheology.copy()
    for name, column in WIDENING_COLUMNS.items():
        factor = out["cell_id"].map(lambda c: widenings.get(c, {}).get(name, 1.0)).to_numpy(float)
        x = out[name].to_numpy(float)
        for end in (f"{name}_lo95", f"{name}_hi95"):
            out[end] = x + factor * (out[end].to_numpy(float) - x)
        out[column] = factor
    return out
