"""The shell ramp table read: the elastic share of the force of the cortex (SPEC 2)
pressed from its free sphere, interpolated (`ShellTable`), for the shell ramp model
(`analysis.afm.tension.shell_ramp`).

The table (built by `analysis.afm.tension.shell_table`) holds f = F/(K_B R) of the
solver (two meshes, Richardson-extrapolated) at depths δ/R and nodes (γ̃_a = γ_a/K_B, K̃_S = K_S/K_B, R). With ĝ the
droplet's unit force (`solver.droplet_table`: the tension alone, exact),

    e = f - γ̃_a ĝ(δ/R),          q = e / (δ/R - D0),

e the elastic stress's share, 0 at the free sphere (D0 = 0: the shell is
stress-free there). As δ → 0, e grows linearly: the shell's bending-stretching
response at each pole (Reissner), F ≈ 4 sqrt(B Y) δ / R for the two poles in
series, Y = 4 K_B K_S/(K_B + K_S) (the table at γ̃_a = 0.003: 0.96-1.11 of it over
K̃_S 0.1-2, R 5-12 µm, the tension stiffening the larger, softer cells), and faster
only deeper, so q is finite and smooth down to the sphere (not e/δ², which grows
like 1/δ there and which a spline between the first depths misses by up to 10 %).
q is interpolated by cubic splines in (δ/R, ln γ̃_a, ln K̃_S, ln R) (scipy
RegularGridInterpolator; R for the bending's weight), once per (K̃_S, R) onto the
table's (δ/R, ln γ̃_a) grid, which a bicubic spline (RectBivariateSpline) then
reads at every sample (a fit varies γ̃_a at fixed K̃_S and R); e is 0 above the
contact, and q is held at the table's first depth below it (e ∝ δ: the
asymptote). γ̃_a, K̃_S and R are held at the table's edges outside it; deeper
than the table (δ/R > `max_depth`) is the caller's to refuse, never extrapolated.

The shipped table is `data/shell_ramp_table.json` (`NAME`, standard bending), read
through the calibration file (`analysis.calibration.file.CalibrationFile.shell_ramp`).
"""

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
from scipy.interpolate import BSpline, RectBivariateSpline, RegularGridInterpolator, splev

from common.errors import InputError
from solver.droplet_table import unit_force_per_tension

NAME = "shell_ramp_table.json"


def elastic_scale(depth_over_radius: npt.ArrayLike, d0: float = 0.0) -> np.ndarray:
    """The scale δ/R - D0 of the elastic share, q = e / (δ/R - D0) (module doc)."""
    return np.asarray(depth_over_radius, float) - d0


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
        out = np.zeros(d.shape)
        touching = d > self.d0                        # the spline read only where it is needed
        dc = np.clip(d[touching], self.d0, self.max_depth)
        dq = np.clip(dc, self.depths[0], None)
        if dq.size:
            out[touching] = at_second(self.slice(shear_tilde, radius_um), g, dq) * elastic_scale(dc, self.d0)
        return out


def at_second(spline: RectBivariateSpline, y: float, x: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """spline(x, y) at one y and many x: the coefficients C_ij contracted with the B-splines in y,
    c_i = Σ_j C_ij B_j(y), read as one spline in x, Σ_i c_i B_i(x) (the same numbers as
    spline(x, y, grid=False), in half its time: a fit reads a whole ramp at one γ̃_a)."""
    tx, ty, c = spline.tck
    kx, ky = spline.degrees
    in_y = BSpline.construct_fast(ty, c.reshape(tx.size - kx - 1, ty.size - ky - 1).T, ky)
    return np.asarray(splev(x, (tx, in_y(y), kx)), float)


def from_document(doc: dict[str, Any], where: str = "shell ramp table") -> ShellTable:
    """A `ShellTable` from the table's JSON dict (`shell_table.from_store`); InputError (one line) if
    a key is missing, an axis is not increasing and positive, or the forces have holes."""
    keys = ("depth_over_radius", "gamma_tilde", "shear_tilde", "radius_um", "force_over_kb_r", "d0")
    missing = [k for k in keys if k not in doc]
    if missing:
        raise InputError(f"{where}: not a shell ramp table (no {', '.join(missing)}; rebuild: make ramp-table)")
    try:
        depths, gammas, shears, radii, f = (np.asarray(doc[k], float) for k in keys[:5])
        d0 = float(doc["d0"])
    except (TypeError, ValueError):
        raise InputError(f"{where}: the shell ramp table's axes and forces must be numbers") from None
    axes = (depths, gammas, shears, radii)
    if any(a.ndim != 1 or a.size < 4 or not np.all(np.diff(a) > 0) for a in axes) or min(a[0] for a in axes[1:]) <= 0:
        raise InputError(f"{where}: the shell ramp table's axes must be increasing (at least 4 points each), "
                         "gamma_tilde, shear_tilde and radius_um positive")
    if not np.all(np.isfinite(f)) or f.shape != (depths.size, gammas.size, shears.size, radii.size):
        raise InputError(f"{where}: the forces do not fill the table's axes")
    e = f - gammas[None, :, None, None] * unit_force_per_tension(depths)[:, None, None, None]
    q = e / elastic_scale(depths, d0)[:, None, None, None]
    spline = RegularGridInterpolator((depths, np.log(gammas), np.log(shears), np.log(radii)), q, method="cubic")
    return ShellTable(d0, depths, gammas, shears, radii, spline, str(doc.get("bending", "standard")))


def read(path: str | Path) -> ShellTable:
    """The table in a JSON file; InputError (one line) if it is missing or unreadable."""
    try:
        doc = json.loads(Path(path).read_text())
    except (OSError, ValueError) as err:
        raise InputError(f"{path}: cannot read the shell ramp table ({err}; rebuild: make ramp-table)") from None
    return from_document(doc, str(path))
