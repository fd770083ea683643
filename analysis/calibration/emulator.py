"""The emulator (SPEC 9): the solver's K/K_B as a smooth function, per bending variant.

Dimensional analysis: with lengths scaled by R_cell and moduli by K_B,

    K / K_B = f(h̃, K̃_S, γ̃_a; t_c/R_cell, Δh/R_cell),   K̃_S = K_S/K_B,  γ̃_a = γ_a/K_B,

(for the `standard` variant B/(K_B R²) = (t_c/R)² (1 + K̃_S)/24, so B adds no
parameter). With t_c = 0.2 µm and Δh = 0.5 µm fixed (the protocol's peak to
peak), the cell size enters through V alone. The campaign `campaigns/emulator.toml`
tabulates f on a regular grid in (V, h̃, K̃_S, γ̃_a); this module interpolates

    y = ln(K/K_B - 1 + s),   s = 0.05

by a tensor-product spline in (ln V, h̃, ln K̃_S, ln γ̃_a): quadratic in ln V
(three volumes), cubic (not-a-knot) in the other three, built axis by axis
with `scipy.interpolate.make_interp_spline` and evaluated, with its partial
derivatives, by `scipy.interpolate.NdBSpline`. In these coordinates K - K_B
is close to exp(h̃/λ) times a smooth function, so y is nearly linear in h̃;
the offset s keeps y smooth where K dips just below K_B (K/K_B ≥ 0.989 on
the grid, at h̃ = 0.43 and K̃_S ≤ 0.08). Leaving one grid line out (twice
the spacing there) the spline is off by at most 0.4 % of K; at the
midpoints of the full grid by far less (`bench/emulator.py` measures it
against solver runs).

`Emulator.ratio(h̃, K̃_S, γ̃_a, V)` is K/K_B; `Emulator.modulus(h̃, K_B, K̃_S,
γ_a, V)` is K = K_B f(h̃, K̃_S, γ_a/K_B; V) in mN/m; `grad_log` gives
∂ ln(K/K_B)/∂(ln K̃_S, ln γ̃_a) for the fits. `domain` is the tabulated box;
`inside` says whether a point lies in it (outside, the spline extrapolates).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt
import pandas as pd
from scipy.interpolate import BSpline, NdBSpline, make_interp_spline

from common.errors import InputError

AXES = ("volume_um3", "h_tilde", "ks_tilde", "gamma_tilde")
LOG_AXES = (True, False, True, True)       # which axes are interpolated in their logarithm
DEGREES = (2, 3, 3, 3)                     # spline degree per axis (at most n - 1 points)
OFFSET = 0.05                              # s in y = ln(K/K_B - 1 + s)
REFILL_FACTOR = 1.1                        # a failed grid point is solved again on this finer mesh


def _tensor_spline(coords: list[Any], values: npt.ArrayLike, degrees: tuple[int, ...]) -> NdBSpline:
    """Interpolating tensor-product B-spline of `values` on the grid `coords`."""
    c, knots, ks = np.asarray(values, float), [], []
    for axis, x in enumerate(coords):
        k = min(degrees[axis], len(x) - 1)
        spl = make_interp_spline(x, np.moveaxis(c, axis, 0), k=k)
        c = np.moveaxis(spl.c, 0, axis)
        knots.append(spl.t)
        ks.append(k)
    return NdBSpline(tuple(knots), c, tuple(ks))


tensor_spline = _tensor_spline       # public: `analysis.calibration.viscoelastic_table` splines its coefficients alike


def evaluate(spline: NdBSpline, x: npt.NDArray[np.float64], where: Any = None,
             nu: tuple[int, ...] | None = None) -> Any:
    """`spline(x, nu)` at the points (rows of x) `where` selects (a mask of the points'
    shape; None: all), NaN at the others: each point's value is its own, so a fit that
    masks points out need not pay for them."""
    nu = nu or (0,) * x.shape[-1]
    if where is None:
        return spline(x, nu=nu)
    where = np.asarray(where, bool).ravel()
    out = np.full((len(x),) + spline.c.shape[len(spline.k):], np.nan)
    out[where] = spline(x[where], nu=nu)
    return out


@dataclass
class Table:
    """One bending variant's grid of K/K_B (shape: len of each axis in AXES order)."""

    bending: str
    axes: dict[str, list[float]]    # name -> sorted values (AXES)
    ratio: npt.NDArray[np.float64]  # K/K_B on the grid
    dh_um: float = 0.5
    thickness_um: float = 0.2
    info: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.ratio = np.asarray(self.ratio, float)
        shape = tuple(len(self.axes[a]) for a in AXES)
        if self.ratio.shape != shape:
            raise InputError(f"emulator '{self.bending}': table shape {self.ratio.shape} does not match "
                             f"its axes {shape}")
        if not np.all(np.isfinite(self.ratio)) or np.any(self.ratio <= 1.0 - OFFSET):
            raise InputError(f"emulator '{self.bending}': K/K_B must be finite and > {1 - OFFSET:g} "
                             "at every grid point")
        coords = [np.log(self.axes[a]) if log else np.asarray(self.axes[a], float)
                  for a, log in zip(AXES, LOG_AXES)]
        self._spline = _tensor_spline(coords, np.log(self.ratio - 1.0 + OFFSET), DEGREES)

    def _points(self, h_tilde: npt.ArrayLike, ks_tilde: npt.ArrayLike, gamma_tilde: npt.ArrayLike,
                volume_um3: npt.ArrayLike) -> Any:
        arrays = np.broadcast_arrays(*(np.asarray(x, float) for x in
                                       (volume_um3, h_tilde, ks_tilde, gamma_tilde)))
        with np.errstate(divide="ignore", invalid="ignore"):
            cols = [np.log(a) if log else a for a, log in zip(arrays, LOG_AXES)]
        return np.stack(cols, axis=-1), arrays[0].shape

    def log_excess(self, h_tilde: npt.ArrayLike, ks_tilde: npt.ArrayLike, gamma_tilde: npt.ArrayLike,
                   volume_um3: npt.ArrayLike,
                   nu: tuple[int, int, int, int] = (0, 0, 0, 0), where: Any = None) -> Any:
        """y = ln(K/K_B - 1 + s) (or its partial derivative `nu` in the spline's coordinates);
        `where`: the points wanted (`evaluate`; NaN at the others)."""
        x, shape = self._points(h_tilde, ks_tilde, gamma_tilde, volume_um3)
        return evaluate(self._spline, x.reshape(-1, 4), where, nu).reshape(shape)

    def at_volume(self, volume_um3: float) -> VolumeSlice:
        """The spline at one volume: a 3-D `NdBSpline` in (h̃, ln K̃_S, ln γ̃_a) (the V
        axis's basis contracted out; a third of the work per evaluation)."""
        s = self._spline
        basis = BSpline.design_matrix([np.log(volume_um3)], s.t[0], s.k[0], extrapolate=True).toarray()[0]
        return VolumeSlice(NdBSpline(s.t[1:], np.tensordot(basis, s.c, axes=(0, 0)), s.k[1:]))

    def to_json(self) -> dict[str, Any]:
        return {"axes": {a: [float(v) for v in self.axes[a]] for a in AXES},
                "k_over_kb": self.ratio.tolist(), "dh_um": self.dh_um, "thickness_um": self.thickness_um,
                **self.info}

    @classmethod
    def from_json(cls, bending: str, doc: dict[str, Any], where: str = "emulator") -> Table:
        try:
            axes = {a: [float(v) for v in doc["axes"][a]] for a in AXES}
            ratio = np.asarray(doc["k_over_kb"], float)
            dh, thickness = float(doc["dh_um"]), float(doc["thickness_um"])
        except (KeyError, TypeError, ValueError) as err:
            raise InputError(f"{where}: emulator variant '{bending}' is malformed ({err!r})") from None
        info = {k: v for k, v in doc.items() if k not in ("axes", "k_over_kb", "dh_um", "thickness_um")}
        return cls(bending=bending, axes=axes, ratio=ratio, dh_um=dh, thickness_um=thickness, info=info)


@dataclass
class VolumeSlice:
    """One table at one volume (`Table.at_volume`)."""

    spline: NdBSpline

    def grad_log(self, h_tilde: npt.ArrayLike, ks_tilde: npt.ArrayLike, gamma_tilde: npt.ArrayLike,
                 values_only: bool = False, where: Any = None) -> Any:
        """ln(K/K_B) and (unless `values_only`) its derivatives by ln K̃_S and ln γ̃_a;
        `where`: the points wanted (`evaluate`; NaN at the others)."""
        h, ks, g = np.broadcast_arrays(*(np.asarray(x, float) for x in (h_tilde, ks_tilde, gamma_tilde)))
        with np.errstate(divide="ignore", invalid="ignore"):
            x = np.stack([h.ravel(), np.log(ks).ravel(), np.log(g).ravel()], axis=-1)
        ey = np.exp(evaluate(self.spline, x, where)).reshape(h.shape)
        ratio = 1.0 - OFFSET + ey
        if values_only:
            return np.log(ratio)
        share = ey / ratio
        return (np.log(ratio), share * evaluate(self.spline, x, where, (0, 1, 0)).reshape(h.shape),
                share * evaluate(self.spline, x, where, (0, 0, 1)).reshape(h.shape))


@dataclass
class Emulator:
    """Tables by bending variant; K/K_B anywhere by interpolation."""

    tables: dict[str, Table]

    def __getitem__(self, bending: str) -> Table:
        if bending not in self.tables:
            raise InputError(f"the emulator has no '{bending}' bending variant "
                             f"(it has: {', '.join(self.tables) or 'none'})")
        return self.tables[bending]

    def ratio(self, h_tilde: npt.ArrayLike, ks_tilde: npt.ArrayLike, gamma_tilde: npt.ArrayLike,
              volume_um3: npt.ArrayLike,
              bending: str = "standard", where: Any = None) -> Any:
        """K/K_B = 1 - s + exp(y) at the given points (arrays broadcast; `where`: the points
        wanted, NaN at the others)."""
        return 1.0 - OFFSET + np.exp(self[bending].log_excess(h_tilde, ks_tilde, gamma_tilde, volume_um3,
                                                              where=where))

    def modulus(self, h_tilde: npt.ArrayLike, bulk: npt.ArrayLike, ks_tilde: npt.ArrayLike, tension: npt.ArrayLike,
                volume_um3: npt.ArrayLike,
                bending: str = "standard") -> Any:
        """K = K_B f(h̃, K̃_S, γ_a/K_B; V) in mN/m (K_B and γ_a in mN/m)."""
        bulk = np.asarray(bulk, float)
        return bulk * self.ratio(h_tilde, ks_tilde, np.asarray(tension, float) / bulk, volume_um3, bending)

    def grad_log(self, h_tilde: npt.ArrayLike, ks_tilde: npt.ArrayLike, gamma_tilde: npt.ArrayLike,
                 volume_um3: npt.ArrayLike,
                 bending: str = "standard") -> tuple[Any, Any, Any]:
        """(ln(K/K_B), ∂ ln(K/K_B)/∂ ln K̃_S, ∂ ln(K/K_B)/∂ ln γ̃_a) at the points."""
        t = self[bending]
        args = (h_tilde, ks_tilde, gamma_tilde, volume_um3)
        ey = np.exp(t.log_excess(*args))
        ratio = 1.0 - OFFSET + ey
        share = ey / ratio                               # d ln(K/K_B) / dy
        return (np.log(ratio), share * t.log_excess(*args, nu=(0, 0, 1, 0)),
                share * t.log_excess(*args, nu=(0, 0, 0, 1)))

    def domain(self, bending: str = "standard") -> dict[str, tuple[float, float]]:
        """{axis: (low, high)} of the tabulated grid."""
        return {a: (min(v), max(v)) for a, v in self[bending].axes.items()}

    def inside(self, h_tilde: npt.ArrayLike, ks_tilde: npt.ArrayLike, gamma_tilde: npt.ArrayLike,
               volume_um3: npt.ArrayLike,
               bending: str = "standard") -> Any:
        """True where every coordinate lies within the tabulated grid."""
        box = self.domain(bending)
        ok: Any = True
        for a, x in zip(AXES, (volume_um3, h_tilde, ks_tilde, gamma_tilde)):
            lo, hi = box[a]
            ok = ok & (np.asarray(x) >= lo * (1 - 1e-9)) & (np.asarray(x) <= hi * (1 + 1e-9))
        return ok

    def to_json(self) -> dict[str, Any]:
        return {name: t.to_json() for name, t in self.tables.items()}

    @classmethod
    def from_json(cls, doc: dict[str, Any], where: str = "emulator") -> Emulator:
        if not isinstance(doc, dict) or not doc:
            raise InputError(f"{where}: 'emulator' must be a non-empty object of bending variants")
        return cls({name: Table.from_json(name, v, where) for name, v in doc.items()})


def from_results(results: pd.DataFrame, progress: Callable[[str], None] | None = None,
                 resolution: float = 1.0) -> Emulator:
    """Build the emulator from a store's rows (`campaign.store.reader.read_results`) of an
    emulator campaign: a full grid over (V, h̃, K̃_S, γ̃_a) per bending variant with one
    Δh and t_c. A task that is not finished is refused (InputError, one line); a task
    that failed (the fast solver's Newton search can stall on one particular mesh) is
    solved again here on a mesh REFILL_FACTOR finer, and listed in the table's
    `refilled` (a mesh 10 % finer or coarser moves K by under 0.03 %)."""
    unfinished = results[~results["state"].isin(("done", "failed"))]
    if len(unfinished):
        raise InputError(f"{len(unfinished)} emulator task(s) not finished (first: "
                         f"{unfinished['task_id'].iloc[0]}, {unfinished['state'].iloc[0]}); "
                         "finish the campaign first (rerun it)")
    done, refilled = _refill(results, resolution, progress)
    for key in ("dh_um", "thickness_um"):
        if done[key].nunique() != 1:
            raise InputError(f"an emulator campaign needs one {key} (got {sorted(done[key].unique())})")
    frame = done.assign(ks_tilde=(done["shear_mN_per_m"] / done["bulk_mN_per_m"]).round(10),
                        gamma_tilde=(done["tension_mN_per_m"] / done["bulk_mN_per_m"]).round(10),
                        h_tilde=done["h_tilde"].round(9),
                        ratio=done["modulus_mN_per_m"] / done["bulk_mN_per_m"])
    tables = {}
    for bending, g in frame.groupby("bending", sort=False):
        if progress:
            progress(f"emulator table for bending variant '{bending}' ({len(g)} compressions)")
        mean = g.groupby(list(AXES))["ratio"].mean()        # several K_B: K/K_B agrees (dimensionless)
        axes = {a: sorted(mean.index.get_level_values(a).unique()) for a in AXES}
        full = mean.reindex(_product_index(axes))
        if full.isna().any():
            raise InputError(f"emulator '{bending}': the results are not a full grid over "
                             f"{', '.join(AXES)} ({int(full.isna().sum())} points missing)")
        ratio = full.to_numpy().reshape([len(axes[a]) for a in AXES])
        tables[bending] = Table(bending=bending, axes=axes, ratio=ratio, dh_um=float(g["dh_um"].iloc[0]),
                                thickness_um=float(g["thickness_um"].iloc[0]),
                                info={"n_compressions": int(len(g)),
                                      "refilled": [r for r in refilled if r["bending"] == bending],
                                      "bulk_mN_per_m": sorted(float(b) for b in g["bulk_mN_per_m"].unique())})
    return Emulator(tables)


def _refill(results: pd.DataFrame, resolution: float, progress: Callable[[str], None] | None
            ) -> tuple[pd.DataFrame, list[Any]]:
    """(results with every failed row solved again on a finer mesh, the list of those rows)."""
    from solver.compression import compress
    from common.errors import SolverError
    from solver.model import Shell
    frame = results.copy()
    refilled = []
    for i in frame.index[frame["state"] == "failed"]:
        row = frame.loc[i]
        params = {k: float(row[k]) for k in ("volume_um3", "h0_um", "dh_um", "bulk_mN_per_m",
                                             "shear_mN_per_m", "tension_mN_per_m", "thickness_um")}
        finer = resolution * REFILL_FACTOR
        if progress:
            progress(f"task {row['task_id']} failed in the campaign; solving it at resolution {finer:g}")
        try:
            out = compress(Shell(bending=row["bending"], resolution=finer, **params)).to_dict()
        except SolverError as err:
            raise InputError(f"emulator task {row['task_id']} failed in the campaign and again at "
                             f"resolution {finer:g} ({err}); the table needs every grid point") from None
        for key in ("modulus_mN_per_m", "h_tilde"):
            frame.at[i, key] = out[key]
        frame.at[i, "state"] = "done"
        refilled.append({"task_id": row["task_id"], "bending": row["bending"], **params,
                         "resolution": finer, "campaign_error": row.get("error", ""),
                         "modulus_mN_per_m": out["modulus_mN_per_m"]})
    return frame, refilled


def _product_index(axes: dict[str, Any]) -> Any:
    import pandas as pd
    return pd.MultiIndex.from_product([axes[a] for a in AXES], names=list(AXES))
