"""The power laws' 95 % intervals over the memory's own (SPEC 10; docs/memory.md).

The protocol-aware reading corrects each cell at its memory τ̂_c (`analysis.afm.memory_fit`);
the exponents' intervals of that reading (`analysis.afm.rheology`) hold τ_c at τ̂_c. A memory
the data bound only to an interval moves the exponents too, most at the ∞ end of the carried
history, where noise can pull τ̂_c down and nothing pulls it back. So each exponent's interval is
the union over the memory's 95 % set:

    [β_lo, β_hi] = [min_m β_lo(m), max_m β_hi(m)],   m ∈ {τ̂_c, its interval's ends, the other
                                                         history where it is in the set}

each β_lo(m), β_hi(m) the interval of the reading corrected at m (`Factors.ends`). The point
estimate stays the one at τ̂_c. Where this stops being true: the ends are the nodes next outside
the set (`memory_fit._fit`), so the union is the wider for it; and a memory outside the set is
not looked at.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd

EXPONENTS = ("bulk_exponent", "shear_exponent")


def spanned(rheology: pd.DataFrame, ends: Sequence[pd.DataFrame]) -> pd.DataFrame:
    """`rheology` (one row per cell_id) with each exponent's interval widened to hold the intervals
    of `ends` (the readings at the memory's ends) for the same cell; NaN ends change nothing."""
    out = rheology.copy()
    for end in ends:
        at = end.set_index("cell_id").reindex(out["cell_id"])
        for name in EXPONENTS:
            lo, hi = f"{name}_lo95", f"{name}_hi95"
            out[lo] = np.fmin(out[lo].to_numpy(float), at[lo].to_numpy(float))
            out[hi] = np.fmax(out[hi].to_numpy(float), at[hi].to_numpy(float))
    return out
