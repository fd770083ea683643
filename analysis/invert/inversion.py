"""The per-cell inversion (SPEC section 6), shared by the reconstruction check,
the Monte-Carlo study and the measured (AFM) cells.

One cell: moduli K at normalised heights h̃ and its active tension γ_a.

1. Keep the heights with 0.5 ≤ h̃ ≤ 0.75 (finite K only).
2. Filters on the curve: at least four heights; the highest h̃ > 0.68.
3. Fit K(h̃) = K_B (1 + α exp(h̃/λ)), λ from the calibration, K_B and α free:
   linear least squares in K_B and K_B·α (`analysis.calibration.law_fits.fit_bulk_alpha`).
4. γ̃_a = γ_a / K_B; K̃_S = exp((α - D(γ̃_a)) / C(γ̃_a)); ν = (1 - K̃_S)/(1 + K̃_S).
5. Filter on the fit: R² > 0.5, unless ν > 0.7 (a nearly flat K(h̃) cannot
   beat its mean). A fit with K_B ≤ 0 or a non-finite ν is excluded too.

`invert_cell` does one cell and returns a `CellInversion`; `invert_curves`
does many at once (rows of 2-D arrays, NaN-padded) with the same code and
returns a DataFrame. `excluded_reason` is None for a cell that passes, else a
short text; ν and the fit are reported even for excluded cells where they
could be computed.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
import pandas as pd

from analysis.calibration.law import Calibration, Law
from analysis.calibration.law_fits import fit_bulk_alpha
from solver.elasticity import poisson_of_ratio

H_TILDE_MIN, H_TILDE_MAX = 0.5, 0.75   # heights used
MIN_HEIGHTS = 4                         # at least this many of them
H_TILDE_TOP = 0.68                      # the highest must lie above this
R2_MIN = 0.5                            # fit quality, unless ν > NU_FLAT
NU_FLAT = 0.7


@dataclass
class CellInversion:
    """The result for one cell. `excluded_reason` is None if the cell passes."""

    nu: float
    ks_tilde: float            # K_S / K_B
    bulk_mN_per_m: float       # fitted K_B
    alpha: float
    r2: float
    gamma_tilde: float         # γ_a / K_B
    n_heights: int             # heights inside 0.5 ≤ h̃ ≤ 0.75
    h_tilde_max: float         # the highest of them
    excluded_reason: str | None

    @property
    def excluded(self) -> bool:
        return self.excluded_reason is not None

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def _law(calibration: Calibration | Law, bending: str) -> Law:
    return calibration[bending] if isinstance(calibration, Calibration) else calibration


def used_heights(h: npt.NDArray[np.float64], k: npt.NDArray[np.float64]) -> tuple[Any, Any, Any]:
    """Mask of the heights an inversion uses (finite, H_TILDE_MIN ≤ h̃ ≤ H_TILDE_MAX),
    their count and the highest of them (-inf where none), per row."""
    use = np.isfinite(h) & np.isfinite(k) & (h >= H_TILDE_MIN) & (h <= H_TILDE_MAX)
    return use, use.sum(axis=1), np.where(use, h, -np.inf).max(axis=1)


def pass_height_filters(h: npt.NDArray[np.float64], k: npt.NDArray[np.float64]) -> npt.NDArray[np.bool_]:
    """Per row, whether the curve passes the published filters on its heights: at least
    MIN_HEIGHTS used heights (`used_heights`), the highest above H_TILDE_TOP."""
    _, n, top = used_heights(h, k)
    return (n >= MIN_HEIGHTS) & (top > H_TILDE_TOP)


def exclusions(n: npt.NDArray[Any], top: npt.NDArray[Any], *, bulk: npt.NDArray[Any], tension: npt.NDArray[Any],
               nu: npt.NDArray[Any], r2: npt.NDArray[Any],
               extra: Iterable[tuple[Any, Callable[[int], str]]] = ()) -> npt.NDArray[np.object_]:
    """The published filters (module docstring) as one reason per cell (None: passes),
    the first that applies; `extra`: (mask, reason(i)) checks of the method,
    applied before the R² filter."""
    reasons = np.full(len(n), None, dtype=object)

    def exclude(where: Any, text: Callable[[Any], str]) -> None:
        for i in np.flatnonzero(where & (reasons == None)):  # noqa: E711 (elementwise)
            reasons[i] = text(i)

    exclude(n < MIN_HEIGHTS, lambda i: f"only {n[i]} height(s) with {H_TILDE_MIN} <= h~ <= "
                                       f"{H_TILDE_MAX} (need {MIN_HEIGHTS})")
    exclude(top <= H_TILDE_TOP, lambda i: f"highest h~ = {top[i]:.3f} is not above {H_TILDE_TOP}")
    exclude(~(bulk > 0), lambda i: f"fitted K_B = {bulk[i]:.3g} mN/m is not positive")
    exclude(~(tension > 0), lambda i: f"active tension {tension[i]:.3g} mN/m is not positive")
    for where, text in extra:
        exclude(where, text)
    exclude(~(r2 > R2_MIN) & ~(nu > NU_FLAT),
            lambda i: f"R^2 = {r2[i]:.2f} is not above {R2_MIN} (and nu = {nu[i]:.2f} <= {NU_FLAT})")
    return reasons


def invert_curves(h_tilde: npt.ArrayLike, modulus: npt.ArrayLike, tension: npt.ArrayLike,
                  calibration: Calibration | Law,
                  bending: str = "standard") -> pd.DataFrame:
    """Invert many cells: `h_tilde`, `modulus` (mN/m) of shape (cells, heights),
    NaN where a cell has no value; `tension` γ_a (mN/m) of shape (cells,).
    `calibration`: a `Calibration` (then `bending` picks the variant) or one
    variant's `Law`. Returns a DataFrame with the fields of `CellInversion`."""
    law = _law(calibration, bending)
    h = np.atleast_2d(np.asarray(h_tilde, float))
    k = np.atleast_2d(np.asarray(modulus, float))
    tension = np.broadcast_to(np.asarray(tension, float), h.shape[:1])
    use, n, top = used_heights(h, k)
    bulk, alpha, r2 = fit_bulk_alpha(h, k, law.lam, mask=use)
    with np.errstate(divide="ignore", invalid="ignore"):
        gamma_tilde = tension / bulk
        ks = law.invert(alpha, gamma_tilde)
        nu = poisson_of_ratio(ks)

    not_inverted = (~np.isfinite(nu), lambda i: "the calibration cannot be inverted here "
                    f"(alpha = {alpha[i]:.3g}, gamma_a/K_B = {gamma_tilde[i]:.3g})")
    reasons = exclusions(n, top, bulk=bulk, tension=tension, nu=nu, r2=r2, extra=[not_inverted])
    return pd.DataFrame({"nu": nu, "ks_tilde": ks, "bulk_mN_per_m": bulk, "alpha": alpha, "r2": r2,
                         "gamma_tilde": gamma_tilde, "n_heights": n,
                         "h_tilde_max": np.where(n > 0, top, np.nan),
                         "excluded_reason": pd.Series(reasons, dtype=object)})


def invert_cell(h_tilde: npt.ArrayLike, modulus: npt.ArrayLike, tension: float, calibration: Calibration | Law,
                bending: str = "standard") -> CellInversion:
    """Invert one cell: moduli K (mN/m) at heights h̃, active tension γ_a (mN/m).

    Returns a `CellInversion` (ν, K̃_S, K_B, α, R², ..., excluded_reason)."""
    h = np.asarray(h_tilde, float).ravel()
    k = np.asarray(modulus, float).ravel()
    if h.shape != k.shape:
        raise ValueError(f"h_tilde and modulus differ in length ({h.size} vs {k.size})")
    row = invert_curves(h[None], k[None], [float(tension)], calibration, bending).iloc[0]
    return CellInversion(nu=float(row.nu), ks_tilde=float(row.ks_tilde),
                         bulk_mN_per_m=float(row.bulk_mN_per_m), alpha=float(row.alpha),
                         r2=float(row.r2), gamma_tilde=float(row.gamma_tilde),
                         n_heights=int(row.n_heights), h_tilde_max=float(row.h_tilde_max),
                         excluded_reason=None if pd.isna(row.excluded_reason) else str(row.excluded_reason))


def to_curves(frame: pd.DataFrame, by: Sequence[str], columns: Sequence[str] = ("h_tilde", "modulus_mN_per_m")
              ) -> tuple[pd.DataFrame, dict[str, npt.NDArray[np.float64]]]:
    """Long rows (one per height) to curves: returns (keys, arrays) where `keys`
    is a DataFrame with one row per distinct `by` (sorted) and `arrays[col]`
    has shape (len(keys), most heights), rows sorted by h̃, NaN-padded."""
    by = list(by)
    frame = frame.sort_values(by + ["h_tilde"], kind="stable")
    groups = frame.groupby(by, sort=True)
    row = groups.ngroup().to_numpy()
    pos = groups.cumcount().to_numpy()
    keys = groups.size().reset_index(name="n_rows")
    shape = (len(keys), int(pos.max()) + 1 if len(pos) else 0)
    arrays = {}
    for col in columns:
        a = np.full(shape, np.nan)
        a[row, pos] = frame[col].to_numpy(float)
        arrays[col] = a
    return keys, arrays
