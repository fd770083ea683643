"""Reconstruction check (SPEC section 4, Figure 2d of the method): the Poisson
ratio recovered from every simulated K(h̃) curve against the true one.

Each (K_B, K_S, γ_a) curve of a bending variant is inverted exactly as a
measured cell (`analysis.invert.inversion.invert_curves`: heights 0.5 ≤ h̃ ≤ 0.75,
K_B and α fitted with λ fixed, the filters) with γ_a KNOWN (the simulation's
active tension), so the error measures the calibration law plus the
free-K_B fit on the measured-cell height window, not tension estimation.
Beside it, `nu_law` inverts the step-2 α (K_B known, all heights): the error
of the log law and the cubics alone.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from analysis.invert.inversion import invert_curves, to_curves
from analysis.calibration.law import Calibration
from solver.elasticity import poisson_of_ratio

KEYS = ["bending", "bulk_mN_per_m", "shear_mN_per_m", "tension_mN_per_m"]


def reconstruct(results: pd.DataFrame, calibration: Calibration, fits: pd.DataFrame | None = None) -> pd.DataFrame:
    """One row per simulated curve: its parameters, `nu_true`, the inverted
    `nu` with the fit and `excluded_reason`, `nu_error` = nu - nu_true, and
    (if the calibration's per-curve `fits` are given) `nu_law`, `nu_law_error`."""
    df = results.dropna(subset=["h_tilde", "modulus_mN_per_m"])
    keys, arr = to_curves(df, KEYS)
    parts = []
    for bending, idx in keys.groupby("bending").groups.items():
        idx = np.asarray(idx)
        inv = invert_curves(arr["h_tilde"][idx], arr["modulus_mN_per_m"][idx],
                            keys.loc[idx, "tension_mN_per_m"].to_numpy(), calibration, bending)
        inv = inv.rename(columns={"bulk_mN_per_m": "bulk_fit_mN_per_m"})
        parts.append(pd.concat([keys.loc[idx].reset_index(drop=True), inv], axis=1))
    out = pd.concat(parts, ignore_index=True).drop(columns="n_rows")
    out["nu_true"] = poisson_of_ratio(out["shear_mN_per_m"] / out["bulk_mN_per_m"])
    out["nu_error"] = out["nu"] - out["nu_true"]
    if fits is not None:
        law = fits[KEYS + ["nu_law"]]
        out = out.merge(law, on=KEYS, how="left")
        out["nu_law_error"] = out["nu_law"] - out["nu_true"]
    return out


def summarise(recon: pd.DataFrame) -> list[dict[str, Any]]:
    """Per bending variant: curves, excluded, the largest |ν error| of the
    included curves (and of `nu_law`), as a list of dicts."""
    rows = []
    for bending, g in recon.groupby("bending", sort=False):
        ok = g[g["excluded_reason"].isna()]
        worst = ok.loc[ok["nu_error"].abs().idxmax()] if len(ok) else None
        rows.append({
            "bending": bending, "n_curves": int(len(g)), "n_excluded": int(len(g) - len(ok)),
            "max_abs_nu_error": float(ok["nu_error"].abs().max()) if len(ok) else float("nan"),
            "rms_nu_error": float(np.sqrt(np.mean(ok["nu_error"] ** 2))) if len(ok) else float("nan"),
            "worst_at": (None if worst is None else
                         {"shear_mN_per_m": float(worst["shear_mN_per_m"]),
                          "tension_mN_per_m": float(worst["tension_mN_per_m"])}),
            "max_abs_nu_law_error": (float(g["nu_law_error"].abs().max())
                                     if "nu_law_error" in g else float("nan")),
            "excluded_reasons": sorted(set(g["excluded_reason"].dropna())),
        })
    return rows
