"""Synthetic viscoelastic cells (SPEC 10): power-law moduli and the complex forward model.

Per cell (drawn in order, reproducibly from the experiment's seed):

    β_B = median_B + SPREAD ε_B,   β_S = median_S + SPREAD ε_S   (ε ~ N(0, 1), clipped to [0, 0.6]),
    |K_B*|(f) = K_B,1Hz (f / 1 Hz)^β_B,   |K_S*|(f) = K̃_S,1Hz K_B,1Hz (f / 1 Hz)^β_S,
    δ_B = β_B π/2,   δ_S = β_S π/2          (a power-law, structural-damping material),

K_B,1Hz and γ_a as for elastic cells (`analysis.afm.synth.cells`), K̃_S,1Hz = exp(μ + σ z) with the
published 1 Hz population (μ, σ) = (-0.70, 0.82). The recording at each mean height is made
with K*(h̃) = K_sec · C (`solver.viscoelastic`): |K*| sets the tension's amplitude, arg K*
its lead over the area. Forward models: `solver` (the fast solver's compression for K_sec,
its linear response for C; ~0.2 s a height and frequency) or `emulator` (the shipped
emulator and complex-modulus table, the calibration file's `ComplexModel`; what the long round
trips in bench/ use).
"""

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from analysis.afm.synth.cells import POPULATIONS
from solver.elasticity import poisson_of_ratio

if TYPE_CHECKING:
    from analysis.calibration.file import ComplexModel

SPREAD = 0.03                     # per-cell SD of both exponents around their medians
EXPONENT_RANGE = (0.0, 0.6)


ComplexForward = Callable[[float, npt.NDArray[np.float64], float, float, float, float, float], np.ndarray]
"""forward(V, mean heights, K_B, K_S, γ_a, δ_B, δ_S) -> K* (complex, mN/m) at each height."""


def solver_complex(bending: str = "standard") -> ComplexForward:
    """K*(V, mean heights, K_B, K_S, γ_a, δ_B, δ_S) from the solver."""
    from solver.compression import compress
    from solver.model import Shell
    from solver.viscoelastic import correction, hessian_parts

    def forward(volume: float, heights: npt.NDArray[np.float64], bulk: float, shear: float, tension: float,
                db: float, ds: float) -> np.ndarray:
        out = []
        for h in heights:
            shell = Shell(volume_um3=float(volume), h0_um=float(h) + 0.25, dh_um=0.5, bulk_mN_per_m=float(bulk),
                          shear_mN_per_m=float(shear), tension_mN_per_m=float(tension), bending=bending)
            K = compress(shell).to_dict()["modulus_mN_per_m"]
            out.append(K * correction(hessian_parts(shell), db, ds, 1.0))
        return np.array(out)
    return forward


def emulator_complex(model: "ComplexModel", bending: str = "standard") -> ComplexForward:
    """K*(V, mean heights, K_B, K_S, γ_a, δ_B, δ_S) from the emulator and complex-modulus table
    of `model` (`CalibrationFile.viscoelastic`)."""
    from solver.geometry import cell_radius
    emulator, table = model.emulator, model.table

    def forward(volume: float, heights: npt.NDArray[np.float64], bulk: float, shear: float, tension: float,
                db: float, ds: float) -> np.ndarray:
        h = np.asarray(heights, float) / (2.0 * float(cell_radius(volume)))
        K = emulator.modulus(h, bulk, shear / bulk, tension, volume, bending)
        return K * np.exp(table.log_factor(h, shear / bulk, tension / bulk, db, ds, volume))
    return forward


def draw_exponents(rng: np.random.Generator, medians: tuple[float, float]) -> npt.NDArray[np.float64]:
    """A cell's (β_B, β_S): the medians plus SPREAD ε, clipped to EXPONENT_RANGE."""
    return np.clip(np.array(medians) + SPREAD * rng.standard_normal(2), *EXPONENT_RANGE)


def describe(medians: tuple[float, float]) -> dict[str, Any]:
    """truth.json's account of the exponents' population."""
    return {"viscoelastic": {"bulk_exponent_median": medians[0], "shear_exponent_median": medians[1],
                             "exponent_spread_sd": SPREAD, "exponent_range": list(EXPONENT_RANGE),
                             "shear_ratio_1hz_population": list(POPULATIONS[1.0])}}


class ViscoelasticForward:
    """The synthetic experiment's forward model for viscoelastic cells (`analysis.afm.synth.cells`)."""

    viscoelastic = True

    def __init__(self, bulk_exponent: float, shear_exponent: float, complex_forward: ComplexForward,
                 seed: int = 0) -> None:
        self.medians = (float(bulk_exponent), float(shear_exponent))
        self.forward = complex_forward
        self.rng = np.random.default_rng([seed, 10])

    def moduli(self, p: dict[str, Any], freqs: tuple[float, ...], truth: dict[str, Any]) -> dict[float, np.ndarray]:
        """K* (complex, mN/m) at every mean height per frequency; the truth gets the exponents
        and per frequency the moduli, loss angles and complex moduli."""
        beta = draw_exponents(self.rng, self.medians)
        mu, sigma = POPULATIONS[1.0]
        ks1 = float(np.exp(mu + sigma * p["z"]))
        truth["bulk_exponent"], truth["shear_exponent"] = float(beta[0]), float(beta[1])
        K = {}
        for f in freqs:
            bulk, shear = p["bulk1"] * f ** beta[0], ks1 * p["bulk1"] * f ** beta[1]
            db, ds = beta * np.pi / 2
            K[f] = self.forward(p["V"], p["h_means"], bulk, shear, p["tension"], db, ds)
            ks = shear / bulk
            truth["frequencies"][f] = {
                "nu": float(poisson_of_ratio(ks)), "ks_tilde": float(ks), "bulk_mN_per_m": float(bulk),
                "shear_mN_per_m": float(shear), "bulk_loss_angle_rad": float(db), "shear_loss_angle_rad": float(ds),
                "bulk_complex_mN_per_m": [float(bulk * np.cos(db)), float(bulk * np.sin(db))],
                "shear_complex_mN_per_m": [float(shear * np.cos(ds)), float(shear * np.sin(ds))]}
        return K

    def describe(self) -> dict[str, Any]:
        return describe(self.medians)
