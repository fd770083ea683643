"""Each ramp model's tension against the depth of the fit window (nested windows),
and whether the active tension still moves with it.

For window depths D_j = FRACTIONS_j · D (D the full window's deepest deformation)
every model is fitted again on deformations up to D_j: the shell (`shell_fit`:
γ_a, K_B, started from the full window's fit) and the two tension-only readings (`ramp.fit_ramp`: their apparent
tension T). A model that describes the ramp gives the same γ_a at every depth;
the tension-only readings of an elastic cell climb with D (the elastic stress
grows like δ²). The windows are nested: the shallower's samples are the deeper's
too, so their fits are not independent. Where the deeper fit is the efficient one
(the model holds), Var(γ_j - γ) = sd_j² - sd² (Hausman 1978), not their sum; it is
floored at FLOOR sd_j² (the SDs are the Jacobian's, approximate where they come
close). The recording is flagged (MOVES) when a shallower window's γ_a differs
from the full window's by more than Z95 · sd_diff; it is NOT_TESTABLE when it does
not and no shallower window could tell a change of γ_a by its whole value
(Z95 · sd_diff ≥ |γ_a| for each: the shallow windows carry no information);
otherwise the tension HOLDS. The volume error moves every window alike and is left
out.
"""

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from analysis.afm.tension.pause import Z95
from analysis.afm.tension.ramp import fit_ramp
from analysis.afm.tension.shell_fit import Fixed, ShellFit, fit_shell
from common.errors import InputError

FRACTIONS = (0.4, 0.6, 0.8, 1.0)
FLOOR = 0.1              # Var(γ_j - γ) at least this share of sd_j²
HOLDS, MOVES, NOT_TESTABLE = "holds", "moves", "not testable"


@dataclass(frozen=True)
class DepthRow:
    """One window: its depth (µm), the shell's γ_a, its SD and K_B, and the apparent
    tensions of the droplet and small-deformation readings (mN/m; NaN where a fit failed)."""

    depth_um: float
    tension_mN_per_m: float
    tension_sd_mN_per_m: float
    bulk_mN_per_m: float
    droplet_tension_mN_per_m: float
    small_deformation_tension_mN_per_m: float


def _apparent(x: npt.ArrayLike, f: npt.ArrayLike, radius: float, model: str, cap: float) -> float:
    """The apparent tension of a tension-only `model` on deformations up to `cap` (NaN if it fails)."""
    try:
        return fit_ramp(x, f, radius, model, cap_um=cap).tension_mN_per_m
    except InputError:
        return float("nan")


def depth_rows(x_um: npt.ArrayLike, force_nN: npt.ArrayLike, radius_um: float, fit: ShellFit,
               fixed: Fixed) -> list[DepthRow]:
    """The nested windows of `fit` (module doc), the full one (the fit itself) last."""
    rows = []
    for frac in FRACTIONS:
        cap = frac * fit.depth_um
        try:
            s = fit if frac == 1.0 else fit_shell(x_um, force_nN, radius_um, fixed, cap_um=cap, near=fit)
            g, sd, k = s.tension_mN_per_m, s.tension_sd_mN_per_m, s.bulk_mN_per_m
            droplet = s.droplet_tension_mN_per_m if frac < 1.0 else float("nan")   # the same fit as _apparent's
        except InputError:
            g = sd = k = droplet = float("nan")
        if not np.isfinite(droplet):
            droplet = _apparent(x_um, force_nN, radius_um, "droplet", cap)
        rows.append(DepthRow(cap, g, sd, k, droplet, _apparent(x_um, force_nN, radius_um, "small-deformation", cap)))
    return rows


def _difference_sd(row: DepthRow, full: DepthRow) -> float:
    """SD of γ_j - γ of a shallower window and the full one (module doc)."""
    var_j, var = row.tension_sd_mN_per_m ** 2, full.tension_sd_mN_per_m ** 2
    return float(np.sqrt(max(var_j - var, FLOOR * var_j)))


def depth_test(rows: list[DepthRow]) -> tuple[str, str]:
    """(HOLDS, MOVES or NOT_TESTABLE, why: '' where it holds) of the nested windows (module doc)."""
    full = rows[-1]
    usable = [r for r in rows[:-1] if np.isfinite(r.tension_mN_per_m) and np.isfinite(r.tension_sd_mN_per_m)]
    moved = [r for r in usable if abs(r.tension_mN_per_m - full.tension_mN_per_m) > Z95 * _difference_sd(r, full)]
    if moved:
        worst = max(moved, key=lambda r: abs(r.tension_mN_per_m - full.tension_mN_per_m))
        return MOVES, (f"active tension moves with the window's depth: {worst.tension_mN_per_m:.3g} mN/m to "
                       f"{worst.depth_um:.2g} um against {full.tension_mN_per_m:.3g} mN/m to {full.depth_um:.2g} um, "
                       f"beyond the 95 % of their difference (±{Z95 * _difference_sd(worst, full):.2g}; the shell "
                       "with this K_S/K_B does not describe the ramp: relaxation during the ramp, a cell that is "
                       "not a free sphere, or a different K_S/K_B)")
    if not any(Z95 * _difference_sd(r, full) < abs(full.tension_mN_per_m) for r in usable):
        half = min((Z95 * _difference_sd(r, full) for r in usable), default=float("nan"))
        return NOT_TESTABLE, (f"not testable: the shallower windows carry no information on the active tension "
                              f"(the 95 % of their difference from the full window, ±{half:.2g} mN/m at best, "
                              f"exceeds γ_a = {full.tension_mN_per_m:.3g} mN/m)")
    return HOLDS, ""


def depth_flag(rows: list[DepthRow]) -> str:
    """Why the active tension moves with the window's depth ('' when it does not, or cannot be told)."""
    verdict, why = depth_test(rows)
    return why if verdict == MOVES else ""
