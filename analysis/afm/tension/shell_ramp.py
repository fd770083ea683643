"""The shell ramp model: the force of an elastic cortex (SPEC 2) pressed from its
free sphere, interpolated from a table of the solver (`shell_table`).

A cell of radius R, active tension γ_a, moduli K_B and K_S = K̃_S K_B, at
deformation δ of its free sphere (δ ≥ 0; 0 above the contact):

    F(δ) = γ_a R ĝ(δ/R) + K_B R e(δ/R, γ̃_a, K̃_S, R),   γ̃_a = γ_a / K_B,
    e = f - γ̃_a ĝ,

with ĝ the droplet's unit force (`solver.droplet_table`: the tension alone,
exact) and f = F/(K_B R) the table's. e, the elastic stress's share, is 0 at the
free sphere (D0 = 0: the shell is stress-free there) and grows like
(δ/R - D0)²: it is interpolated as q = e / (δ/R - D0)² by cubic splines in
(δ/R, ln γ̃_a, ln K̃_S, ln R) (scipy RegularGridInterpolator; R for the
bending's weight, `shell_table`), once per (K̃_S, R) onto the table's
(δ/R, ln γ̃_a) grid, which a bicubic spline (RectBivariateSpline) then reads at
every sample (a fit varies γ̃_a at fixed K̃_S and R); e is 0 above the
contact, and q is held at the table's first depth (δ/R = 0.0013) below it.
γ̃_a, K̃_S and R are held at the table's edges outside it: a cell stiffer than the
table (γ̃_a < 0.003) is read with the table's stiffest shape, a softer one
(γ̃_a > 0.5, nearly tension-only) with its softest; deeper than the table
(δ/R > `max_depth`) is refused by the fit's window, never extrapolated.

The shipped table is `analysis/calibration/data/shell_ramp_table.json` (standard bending).
"""

from dataclasses import dataclass, field
from functools import lru_cache
from importlib import resources
from pathlib import Path

import numpy as np
import numpy.typing as npt
from scipy.interpolate import RectBivariateSpline, RegularGridInterpolator

from common.errors import InputError
from solver.droplet_table import DEPTH_MAX, unit_force_per_tension

SHIPPED_NAME = "shell_ramp_table.json"


@dataclass(frozen=True)
class ShellTable:
    """The interpolated table: its axes and the spline of q (module doc)."""

    d0: float
    depths: np.ndarray
    gammas: np.ndarray
    shears: np.ndarray
    radii: np.ndarray
    spline: RegularGridInterpolator
    bending: str
    slices: dict = field(default_factory=dict, compare=False, repr=False)

    @property
    def max_depth(self) -> float:
        """The deepest δ/R of the table."""
        return float(self.depths[-1])

    def slice(self, shear_tilde: float, radius_um: float) -> RectBivariateSpline:
        """q on the (δ/R, ln γ̃_a) grid at one (K̃_S, R) as a bicubic spline (kept)."""
        key = (round(float(shear_tilde), 12), round(float(radius_um), 12))
        if key not in self.slices:
            s = np.clip(np.log(shear_tilde), *np.log(self.shears[[0, -1]]))
            r = np.clip(np.log(radius_um), *np.log(self.radii[[0, -1]]))
            lg = np.log(self.gammas)
            dd, gg = np.meshgrid(self.depths, lg, indexing="ij")
            pts = np.stack([dd.ravel(), gg.ravel(), np.full(dd.size, s), np.full(dd.size, r)], axis=1)
            q = self.spline(pts).reshape(dd.shape)
            if len(self.slices) > 256:
                self.slices.clear()
            self.slices[key] = RectBivariateSpline(self.depths, lg, q)
        return self.slices[key]

    def elastic(self, depth_over_radius: npt.ArrayLike, gamma_tilde: float, shear_tilde: float,
                radius_um: float) -> np.ndarray:
        """e (module doc) at deformations δ/R for one cell."""
        d = np.asarray(depth_over_radius, float)
        g = np.clip(np.log(gamma_tilde) if gamma_tilde > 0 else -np.inf, *np.log(self.gammas[[0, -1]]))
        dc = np.clip(d, self.d0, self.max_depth)
        dq = np.clip(dc, self.depths[0], None)
        q = self.slice(shear_tilde, radius_um)(dq.ravel(), np.full(dq.size, g), grid=False).reshape(d.shape)
        return np.where(d > self.d0, q * (dc - self.d0) ** 2, 0.0)


def force_nN(depth_um: npt.ArrayLike, radius_um: float, tension_mN_per_m: float, bulk_mN_per_m: float,
             shear_tilde: float, table: "ShellTable | None" = None) -> np.ndarray:
    """F (nN) of the shell (module doc) at deformations δ (µm; ≤ 0: no contact)."""
    t = shipped() if table is None else table
    d = np.clip(np.asarray(depth_um, float), 0.0, None) / radius_um
    out = tension_mN_per_m * radius_um * unit_force_per_tension(np.minimum(d, DEPTH_MAX))   # as `ramp`
    if bulk_mN_per_m > 0:
        out = out + bulk_mN_per_m * radius_um * t.elastic(d, tension_mN_per_m / bulk_mN_per_m, shear_tilde,
                                                               radius_um)
    return out


def from_document(doc: dict, where: str = "shell ramp table") -> ShellTable:
    """A `ShellTable` from the table's JSON dict (`shell_table.from_store`); InputError if it has holes."""
    depths, gammas, shears, radii = (np.asarray(doc[k], float)
                                     for k in ("depth_over_radius", "gamma_tilde", "shear_tilde", "radius_um"))
    f = np.asarray(doc["force_over_kb_r"], float)
    if not np.all(np.isfinite(f)) or f.shape != (depths.size, gammas.size, shears.size, radii.size):
        raise InputError(f"{where}: the forces do not fill the table's axes")
    d0 = float(doc["d0"])
    e = f - gammas[None, :, None, None] * unit_force_per_tension(depths)[:, None, None, None]
    q = e / ((depths - d0) ** 2)[:, None, None, None]
    spline = RegularGridInterpolator((depths, np.log(gammas), np.log(shears), np.log(radii)), q, method="cubic")
    return ShellTable(d0, depths, gammas, shears, radii, spline, str(doc.get("bending", "standard")))


def read(path: str | Path) -> ShellTable:
    """The table in a JSON file."""
    import json
    try:
        doc = json.loads(Path(path).read_text())
    except (OSError, ValueError) as err:
        raise InputError(f"{path}: cannot read the shell ramp table ({err})") from None
    return from_document(doc, str(path))


@lru_cache(maxsize=1)
def shipped() -> ShellTable:
    """The table shipped in the package (read once)."""
    return read(Path(str(resources.files("analysis.calibration") / "data" / SHIPPED_NAME)))
