"""Relaxation moduli as Prony series (sums of Maxwell elements), and their fit to power laws.

SPEC section 12. A linear viscoelastic modulus is given by its relaxation function

    K(t) = K_∞ + Σ_j K_j e^{-t/τ_j}        (K_∞, K_j ≥ 0; mN/m, τ_j in s),

a spring K_∞ beside Maxwell elements (spring K_j in series with a dashpot K_j τ_j). Its
complex modulus (the correspondence principle's K(iω), ω = 2π f) is

    K*(ω) = K_∞ + Σ_j K_j iωτ_j / (1 + iωτ_j).

Time stepping (`step_factors`). Element j's stress h_j(t) = ∫ K_j e^{-(t-t')/τ_j} dε(t')
follows, for a strain ε that is linear over a step Δt (the exact exponential integrator),

    h_j(t+Δt) = d_j h_j(t) + K_j g_j (ε(t+Δt) - ε(t)),   d_j = e^{-Δt/τ_j},   g_j = (1 - d_j)/(Δt/τ_j),

so the stress at the step's end is K_Δt ε(t+Δt) + σ_hist with the step's effective modulus
K_Δt = K_∞ + Σ_j K_j g_j and the history σ_hist = Σ_j (d_j h_j(t) - K_j g_j ε(t)).

Power laws (`fit_power_law`). K(t) = K_0 (t/t_0)^-β over t in [t_min, t_max] (0.01-1000 s):
τ_j log-spaced from t_min/10 to 10 t_max, `per_decade` a decade, and the weights (K_∞ among
them) by non-negative least squares on the relative error at log-spaced times (8 a decade);
elements of zero weight are dropped. β = 0 is the constant K_0 (no Maxwell element).

Memory (`Prony.forgetting`, `fit_power_law`'s `memory_s`). A cortex that turns over in τ_c
forgets: K(t) = K_0 (t/t_0)^-β e^{-t/τ_c}. Multiplying a Prony series by e^{-t/τ_c} is exact,
term by term,

    K_j e^{-t/τ_j} e^{-t/τ_c} = K_j e^{-t/τ'_j},   1/τ'_j = 1/τ_j + 1/τ_c,

and the spring K_∞ becomes a Maxwell element K_∞ e^{-t/τ_c}: the series stays a Prony series
(no K_∞ left), with the same relative error against the cut-off power law as the uncut fit has
against the power law. τ_c = ∞ is the series unchanged (today's pure power law); τ_c → 0 the
relaxed state (every element relaxed within any step: K_Δt = Σ_j K_j g_j → 0).
"""

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import numpy.typing as npt
from scipy.optimize import nnls

from common.errors import InputError

FIT_RANGE_S = (0.01, 1000.0)      # the times over which a power law is fitted
SAMPLES_PER_DECADE = 8


@dataclass(frozen=True)
class Prony:
    """K(t) = K_∞ + Σ_j K_j e^{-t/τ_j}: `infinity` K_∞ (mN/m), `weights` K_j (mN/m), `times_s` τ_j (s)."""

    infinity: float
    weights: tuple[float, ...] = ()
    times_s: tuple[float, ...] = ()

    def __post_init__(self) -> None:
        if len(self.weights) != len(self.times_s):
            raise InputError("a Prony series needs one relaxation time per weight")
        values = (self.infinity, *self.weights)
        if not all(np.isfinite(values)) or min(values) < 0:
            raise InputError("Prony weights must be finite and >= 0 mN/m")
        if any(not (np.isfinite(t) and t > 0) for t in self.times_s):
            raise InputError("Prony relaxation times must be finite and > 0 s")

    def relaxation(self, t_s: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """K(t) (mN/m) at the times t (s)."""
        t = np.asarray(t_s, float)[..., None]
        return self.infinity + (np.asarray(self.weights) * np.exp(-t / np.asarray(self.times_s))).sum(-1)

    def complex_modulus(self, frequency_hz: float) -> complex:
        """K*(ω) = K_∞ + Σ_j K_j iωτ_j / (1 + iωτ_j) (mN/m)."""
        iwt = 2j * np.pi * frequency_hz * np.asarray(self.times_s)
        return complex(self.infinity + (np.asarray(self.weights) * iwt / (1.0 + iwt)).sum())

    def step_factors(self, dt_s: float) -> tuple[float, npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """(K_Δt, d_j, g_j) of one step Δt (module docstring); read-only arrays, remembered
        per (series, Δt): a protocol repeats its steps' Δt thousands of times."""
        return _step_factors(self, float(dt_s))

    def forgetting(self, memory_s: float) -> "Prony":
        """The series times e^{-t/τ_c}, τ_c = `memory_s` (s; inf: unchanged): every τ_j to
        1/(1/τ_j + 1/τ_c), K_∞ to a Maxwell element of time τ_c (module docstring)."""
        if not memory_s > 0:
            raise InputError(f"the cortex's memory tau_c must be > 0 s, or inf (got {memory_s:g})")
        if np.isinf(memory_s):
            return self
        times = tuple(1.0 / (1.0 / t + 1.0 / memory_s) for t in self.times_s)
        if self.infinity > 0:
            return Prony(0.0, (*self.weights, self.infinity), (*times, float(memory_s)))
        return Prony(0.0, self.weights, times)

    def scaled(self, factor: float) -> "Prony":
        """The same relaxation shape with every weight times `factor`."""
        return Prony(self.infinity * factor, tuple(w * factor for w in self.weights), self.times_s)


@lru_cache(maxsize=256)
def _step_factors(prony: Prony, dt_s: float) -> tuple[float, npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    x = dt_s / np.asarray(prony.times_s, float)
    d = np.exp(-x)
    g = -np.expm1(-x) / x
    d.flags.writeable = g.flags.writeable = False
    return float(prony.infinity + (np.asarray(prony.weights) * g).sum()), d, g


@dataclass(frozen=True)
class PowerLawFit:
    """A Prony series fitted to K_0 (t/t_0)^-β, and how close it is over the fit's range."""

    prony: Prony
    exponent: float
    elements: int                  # Maxwell elements kept (nonzero weight)
    max_relative_error: float      # max |K_prony/K - 1| over the fit's range


def fit_power_law(exponent: float, modulus_mN_per_m: float = 1.0, t0_s: float = 1.0,
                  range_s: tuple[float, float] = FIT_RANGE_S, per_decade: int = 2,
                  memory_s: float = np.inf) -> PowerLawFit:
    """The Prony series closest (relative error, NNLS) to K_0 (t/t_0)^-β over `range_s`, cut off
    by the memory τ_c = `memory_s` (s; `Prony.forgetting`: the same relative error against
    K_0 (t/t_0)^-β e^{-t/τ_c}; inf, the default, is the pure power law)."""
    if not memory_s > 0:
        raise InputError(f"the cortex's memory tau_c must be > 0 s, or inf (got {memory_s:g})")
    if not (np.isfinite(exponent) and 0.0 <= exponent < 1.0):
        raise InputError(f"a power-law exponent must be in [0, 1) (got {exponent:g})")
    lo, hi = range_s
    t = np.logspace(np.log10(lo), np.log10(hi), int(SAMPLES_PER_DECADE * np.log10(hi / lo)) + 1)
    target = modulus_mN_per_m * (t / t0_s) ** -exponent
    if exponent == 0.0:
        constant = Prony(float(modulus_mN_per_m)).forgetting(memory_s)
        return PowerLawFit(constant, 0.0, len(constant.weights), 0.0)
    decades = np.log10(hi / lo) + 2
    tau = np.logspace(np.log10(lo) - 1, np.log10(hi) + 1, int(round(per_decade * decades)) + 1)
    A = np.column_stack([np.ones_like(t), np.exp(-t[:, None] / tau)]) / target[:, None]
    w, _ = nnls(A, np.ones_like(t))
    keep = w[1:] > 0
    prony = Prony(float(w[0]), tuple(map(float, w[1:][keep])), tuple(map(float, tau[keep])))
    error = float(np.abs(prony.relaxation(t) / target - 1.0).max())
    cut = prony.forgetting(memory_s)
    return PowerLawFit(cut, float(exponent), len(cut.weights), error)
