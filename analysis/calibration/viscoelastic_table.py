"""The complex forward model fast: the correspondence factor C tabulated (SPEC 10).

The measured complex modulus of a viscoelastic cell (`solver.viscoelastic`) is

    K*(h̃) = K_sec(h̃; K_B, K_S, γ_a) · C(h̃, K̃_S, γ̃_a, δ_B, δ_S),

K_sec the elastic modulus the emulator gives (`analysis.calibration.emulator`, K_B f(h̃, K̃_S, γ̃_a; V)),
C = K*_lin(δ_B, δ_S)/K*_lin(0, 0) the linear response's complex factor (no viscosity).
C is dimensionless; with lengths scaled by R_cell and moduli by |K_B*| it depends on
(h̃, K̃_S = |K_S*|/|K_B*|, γ̃_a = γ_a/|K_B*|, δ_B, δ_S), weakly on t_c/R and not on Δh.

Why a table, and this one: the inversion evaluates the forward model ~10⁶ times per
experiment (Gauss-Newton steps × bootstrap draws × heights), and one solver call is
~10 ms after a ~0.1 s linearisation. At one (h̃, K̃_S, γ̃_a) the linearisation is done
once and every (δ_B, δ_S) is one dense complex solve (the Hessian is linear in the
moduli: `solver.viscoelastic.hessian_parts`), so each grid node costs a linearisation
and a 7 × 7 grid of loss angles in [0, 1] rad. ln C is smooth and analytic in the
angles: per node a polynomial of total degree DEGREE in (δ_B, δ_S) without constant
term (C = 1 at zero angles) fits the 49 solves to ~2e-5; its complex coefficients are
splined like the emulator (quadratic in ln V over three volumes, cubic in h̃, ln K̃_S,
ln γ̃_a, on the emulator's grid: C moves by ~3e-3 rad in phase between V = 4300 and
6200 µm³, through the bending stiffness's (t_c/R)²). `bench/viscoelastic.py` measures the table against the solver at random
points between the nodes.

Only the `standard` bending variant is tabulated (the factor C changes with B by far
less than with the angles: B/(K_B R²) ~ 1e-5).

The table is built by the campaign engine: `campaigns/viscoelastic.toml` (`[campaign]
task = "analysis.calibration.viscoelastic_table:viscoelastic_table"`, the kind `KIND`) runs one
task per node (`node_results`, any number of ranks, resumable), and `from_store` (`cortex analysis build-viscoelastic-table`) makes
the table's document from the finished store.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt
from scipy.interpolate import BSpline, NdBSpline

from analysis.calibration.emulator import evaluate, tensor_spline
from campaign.kinds import Kind, register
from common.errors import InputError

if TYPE_CHECKING:
    from solver.model import Shell
ANGLES = tuple(np.linspace(0.0, 1.0, 7))
BULK_MN_PER_M = 25.0        # K_B of `node_coefficients`'s shells (C depends on the ratios only)
TASK = "viscoelastic_table"        # the task kind (`campaign.kinds`, `KIND`) that computes a node
# a node's results, the store's columns: the complex coefficients of ln C's polynomial in the loss
# angles, the real and the imaginary part of the term δ_B^i δ_S^j (0 < i + j <= DEGREE) as
# ln_c_re_b{i}_s{j} and ln_c_im_b{i}_s{j} (dimensionless)
DEGREE = 4
TERMS = tuple((i, j) for i in range(DEGREE + 1) for j in range(DEGREE + 1 - i) if i + j > 0)
TABLE_RESULTS = tuple(f"ln_c_{part}_b{i}_s{j}" for part in ("re", "im") for i, j in TERMS)


def _monomials(db: npt.ArrayLike, ds: npt.ArrayLike) -> tuple[Any, Any, Any]:
    """(..., len(TERMS)) monomials δ_B^i δ_S^j and their derivatives by δ_B and δ_S."""
    db, ds = np.asarray(db, float)[..., None], np.asarray(ds, float)[..., None]
    i = np.array([t[0] for t in TERMS])
    j = np.array([t[1] for t in TERMS])
    pow_ = lambda x, k: np.where(k >= 0, x ** np.maximum(k, 0), 0.0)  # noqa: E731
    m = pow_(db, i) * pow_(ds, j)
    return m, i * pow_(db, i - 1) * pow_(ds, j), j * pow_(db, i) * pow_(ds, j - 1)


def node_coefficients(volume_um3: float, h_tilde: float, ks_tilde: float, gamma_tilde: float,
                      bending: str = "standard") -> npt.NDArray[np.complex128]:
    """Complex coefficients (len(TERMS),) of ln C at one grid node (`shell_coefficients`
    of its shell, made as the campaign's grid makes it: h0 = 2 R_cell h̃ + Δh/2)."""
    from solver.geometry import cell_radius
    from solver.model import Shell
    h_m = h_tilde * 2.0 * float(cell_radius(volume_um3))
    shell = Shell(volume_um3=volume_um3, h0_um=h_m + 0.25, bulk_mN_per_m=BULK_MN_PER_M,
                  shear_mN_per_m=BULK_MN_PER_M * ks_tilde, tension_mN_per_m=BULK_MN_PER_M * gamma_tilde,
                  bending=bending)
    return shell_coefficients(shell)


def shell_coefficients(shell: Shell) -> npt.NDArray[np.complex128]:
    """Complex coefficients (len(TERMS),) of ln C for `shell`:
    linearise the solver once at h_m = h0 - Δh/2, solve every (δ_B, δ_S) of ANGLES²,
    least squares in the monomials."""
    from solver.viscoelastic import correction, hessian_parts
    parts = hessian_parts(shell)
    db, ds = (a.ravel() for a in np.meshgrid(ANGLES, ANGLES, indexing="ij"))
    lnc = np.array([np.log(correction(parts, a, b, 1.0)) for a, b in zip(db, ds)])
    coef, *_ = np.linalg.lstsq(_monomials(db, ds)[0], lnc, rcond=None)
    return coef


def node_results(shell: Shell) -> dict[str, float]:
    """One campaign task: `shell_coefficients` as the store's result columns
    (TABLE_RESULTS: the real parts, then the imaginary parts, in TERMS order)."""
    coef = shell_coefficients(shell)
    return dict(zip(TABLE_RESULTS, map(float, np.concatenate([coef.real, coef.imag]))))


def table_document(volumes: Sequence[float], h_tilde: Sequence[float], ks_tilde: Sequence[float],
                   gamma_tilde: Sequence[float], coef: npt.NDArray[np.complex128]) -> dict[str, Any]:
    """The table's JSON document (`ComplexTable.from_json`) from its axes and the
    coefficients `coef` of shape (V, h̃, K̃_S, γ̃_a, len(TERMS))."""
    return {"volume_um3": [float(v) for v in volumes], "h_tilde": [float(v) for v in h_tilde],
            "ks_tilde": [float(v) for v in ks_tilde], "gamma_tilde": [float(v) for v in gamma_tilde],
            "angles_rad": [float(a) for a in ANGLES], "degree": DEGREE,
            "bending": "standard", "terms": [list(t) for t in TERMS],
            "ln_c_real": coef.real.tolist(), "ln_c_imag": coef.imag.tolist()}


def from_store(path: str | os.PathLike[str]) -> dict[str, Any]:
    """The table's document from a finished viscoelastic-table campaign store
    (`campaigns/viscoelastic.toml`): its axes from the campaign file the store
    keeps, each node's coefficients from its row (rows in grid order: V, h̃, K̃_S,
    γ̃_a, the last fastest). InputError unless every node is done."""
    import tomllib

    from campaign.config import DEFAULTS
    from campaign.store.reader import read_provenance, read_results
    text = read_provenance(path).get("config_text", "")        # the campaign file, as run
    doc = tomllib.loads(text) if text else {}
    grid = {**DEFAULTS, **doc.get("grid", {})}
    keys = ("volume_um3", "h_tilde", "ks_tilde", "gamma_tilde")
    task = str(doc.get("campaign", {}).get("task", "")).rpartition(":")[2]      # MODULE:NAME, or a bare name
    if task != TASK or grid["bending"] != "standard" or not set(keys) <= set(grid):
        raise InputError(f"{path}: not a store of a viscoelastic-table campaign over h_tilde, ks_tilde and "
                         "gamma_tilde, standard bending ([campaign] task = "
                         f"\"analysis.calibration.viscoelastic_table:{TASK}\": campaigns/viscoelastic.toml)")
    axes = [np.atleast_1d(np.asarray(grid[k], float)) for k in keys]
    rows = read_results(path)
    undone = int((rows["state"] != "done").sum())
    if undone:
        raise InputError(f"{path}: {undone} of {len(rows)} nodes not done; finish the campaign "
                         "(run it again: it resumes)")
    shape = tuple(len(a) for a in axes)
    values = rows[list(TABLE_RESULTS)].to_numpy()
    n = len(TERMS)
    coef = (values[:, :n] + 1j * values[:, n:]).reshape(shape + (n,))
    return table_document(axes[0].tolist(), axes[1].tolist(), axes[2].tolist(), axes[3].tolist(), coef)


@dataclass
class ComplexTable:
    """ln C(h̃, K̃_S, γ̃_a, δ_B, δ_S) and its derivatives, from the tabulated coefficients."""

    spline: NdBSpline
    has_volume: bool = True

    def at_volume(self, volume_um3: float) -> ComplexTable:
        """The table at one volume (the V axis's basis contracted out: a third of the work
        per evaluation), whose `log_factor` ignores its volume argument."""
        s = self.spline
        basis = BSpline.design_matrix([np.log(volume_um3)], s.t[0], s.k[0], extrapolate=True).toarray()[0]
        return ComplexTable(NdBSpline(s.t[1:], np.tensordot(basis, s.c, axes=(0, 0)), s.k[1:]), has_volume=False)

    @classmethod
    def from_json(cls, doc: dict[str, Any], where: str = "viscoelastic table") -> ComplexTable:
        try:
            axes = [np.asarray(doc[k], float) for k in ("volume_um3", "h_tilde", "ks_tilde", "gamma_tilde")]
            coef = np.asarray(doc["ln_c_real"], float) + 1j * np.asarray(doc["ln_c_imag"], float)
            if [tuple(t) for t in doc["terms"]] != list(TERMS):
                raise ValueError("terms differ from this version's")
        except (KeyError, TypeError, ValueError) as err:
            raise InputError(f"{where}: malformed ({err})") from None
        values = np.concatenate([coef.real, coef.imag], axis=-1)
        coords = [np.log(axes[0]), axes[1], np.log(axes[2]), np.log(axes[3])]
        return cls(tensor_spline(coords, values, (2, 3, 3, 3)))

    def log_factor(self, h_tilde: npt.ArrayLike, ks_tilde: npt.ArrayLike, gamma_tilde: npt.ArrayLike,
                   db: npt.ArrayLike, ds: npt.ArrayLike, volume_um3: npt.ArrayLike,
                   derivatives: bool = False, where: Any = None) -> Any:
        """ln C at the points (arrays broadcast); with `derivatives` also its derivatives by
        ln K̃_S, ln γ̃_a, δ_B and δ_S (each complex, same shape); `where`: the points wanted
        (`analysis.calibration.emulator.evaluate`; NaN at the others)."""
        h, ks, g, db, ds, v = np.broadcast_arrays(*(np.asarray(x, float) for x in (h_tilde, ks_tilde, gamma_tilde,
                                                                                  db, ds, volume_um3)))
        with np.errstate(divide="ignore", invalid="ignore"):
            x = np.stack(([np.log(v).ravel()] if self.has_volume else []) + [h.ravel(), np.log(ks).ravel(),
                                                                               np.log(g).ravel()], axis=-1)
        lead = (0,) if self.has_volume else ()
        n = len(TERMS)
        m, mb, ms = (a.reshape(-1, n) for a in _monomials(db.ravel(), ds.ravel()))

        def contract(c: Any, weights: Any) -> list[Any]:
            c = c[:, :n] + 1j * c[:, n:]
            return [np.sum(c * w, axis=1).reshape(h.shape) for w in weights]

        c0 = evaluate(self.spline, x, where)
        if not derivatives:
            return contract(c0, (m,))[0]
        value, d_b, d_s = contract(c0, (m, mb, ms))
        d_ks = contract(evaluate(self.spline, x, where, lead + (0, 1, 0)), (m,))[0]
        d_g = contract(evaluate(self.spline, x, where, lead + (0, 0, 1)), (m,))[0]
        return value, d_ks, d_g, d_b, d_s


def main() -> None:
    """The table is built by the campaign engine, not here: say how."""
    import sys
    print("the viscoelastic table is built by the campaign engine:\n"
          "  mpiexec -n N cortex campaign run campaigns/viscoelastic.toml --store results/viscoelastic.h5\n"
          "  cortex analysis build-viscoelastic-table results/viscoelastic.h5 --out DIR\n"
          "(or make viscoelastic-table)", file=sys.stderr)
    sys.exit(2)


if __name__ == "__main__":
    main()


KIND = register(Kind(TASK, 1, dict.fromkeys(TABLE_RESULTS, "1"), node_results,
                     doc="one node of the complex correspondence table: ln C's coefficients (SPEC 10)"))
