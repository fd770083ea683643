"""The force relaxation of one pause and the relaxed force F_∞ (SPEC 11).

After the ramp stops the cortex relaxes (it is viscoelastic): the force of a
constant-height pause falls towards the force of the active tension alone,
F_∞, which is the force γ_a belongs to. With t the time since the pause
started, two models of F(t) are fitted by least squares:

    exponential   F(t) = F_∞ + A e^{−t/τ}                (one Maxwell element)
    power law     F(t) = F_∞ + A (1 + t/τ)^{−β}          (a cortex with power-law
                                                           relaxation, SPEC 12)

The power law is written with 1 + t/τ, not (t/t_1)^{−β}: it is finite at t = 0
(F(0) = F_∞ + A, the force when the ramp stopped, as the exponential's), where
the pure power law diverges and would hang the fit on the first sample; τ is
its onset (the ramp's own duration smooths the start), and for t ≫ τ it is the
pure power law A (t/τ)^{−β}. Both are linear in (F_∞, A); τ and β are fitted
as ln τ and ln β (positive), started from the best point of a grid on which
(F_∞, A) are solved in closed form, then refined together with
`scipy.optimize.least_squares` (analytic Jacobian).

Choice. With n samples, k parameters and RSS the residual sum of squares,
BIC = n_e ln(RSS/n) + k ln n_e, with n_e = n (1 − ρ)/(1 + ρ) the effective
number of samples of residuals whose lag-1 autocorrelation is ρ ≥ 0 (an AR(1)
noise: samples closer than the noise's memory are not independent; n_e = n
for white noise). A constant F(t) = F_∞ (k = 1, no relaxation above the
noise) competes too; the lowest BIC wins. BIC rather than AIC: its penalty
grows with n, so at 10³-10⁴ samples a flat pause is seldom given a spurious
relaxation (of 200 flat 3 s pauses of 3000 samples, BIC gave 1 one, AIC 38).

Time scales. The relaxing part A φ(t) falls to 1/e of A at the relaxation time
(`time_s`): τ for the exponential, τ (e^{1/β} − 1) for the power law; and to
10 % of A at t_90 (`t90_s`): τ ln 10, and τ (10^{1/β} − 1).

F_∞'s 95 % interval: F_∞ ± z σ, z the normal quantile, σ² the (1, 1) element of
s² (JᵀJ)⁻¹ (J the Jacobian at the optimum, s² = RSS/(n − k)) times
(1 + ρ)/(1 − ρ), the AR(1) variance inflation.

A pause is flagged (`flag`, a reason; empty when none) when it cannot give
F_∞: too few samples to fit; too short to relax (t_90 longer than the pause:
F_∞ is an extrapolation beyond what the pause shows); or F_∞ poorly
determined (not positive, or its 95 % half-width above `POOR` of it).
"""

from dataclasses import dataclass, replace

import numpy as np
import numpy.typing as npt
from scipy.optimize import least_squares

from analysis.afm.tension.pause import Z95

EXPONENTIAL, POWER, NONE = "exponential", "power law", "none"
MODELS = (EXPONENTIAL, POWER)
MIN_SAMPLES = 20          # fewer samples than this: no relaxation fitted
POOR = 0.1                # F_∞'s 95 % half-width above this share of F_∞: poorly determined
BETA_RANGE = (0.05, 20.0)  # the power law's exponents tried (β → ∞ at fixed τ/β is the exponential)
GRID_SAMPLES = 400        # the start grid works on at most this many block means of the pause


def shape(model: str, t_s: npt.ArrayLike, tau_s: npt.ArrayLike, beta: npt.ArrayLike = float("nan")) -> np.ndarray:
    """φ(t) of the relaxing part A φ: e^{−t/τ} or (1 + t/τ)^{−β}; 1 at t = 0 (broadcast)."""
    t, tau = np.asarray(t_s, float), np.asarray(tau_s, float)
    return np.exp(-t / tau) if model == EXPONENTIAL else (1.0 + t / tau) ** -np.asarray(beta, float)


def time_to_s(model: str, share: float, tau_s: float, beta: float = float("nan")) -> float:
    """The time the relaxing part takes to fall to `share` of A (1/e: τ for the exponential)."""
    return float(-tau_s * np.log(share)) if model == EXPONENTIAL else float(tau_s * (share ** (-1.0 / beta) - 1.0))


@dataclass(frozen=True)
class Relaxation:
    """One pause's relaxation: the preferred model, F_∞ (nN) with its SD and 95 %
    interval, A (nN), the 1/e and 90 % times (s), β, every model's BIC, the flag."""

    model: str
    relaxed_force_nN: float
    relaxed_force_sd_nN: float
    relaxed_force_lo95_nN: float
    relaxed_force_hi95_nN: float
    amplitude_nN: float
    time_s: float
    t90_s: float
    exponent: float
    tau_s: float
    pause_s: float
    bic: dict[str, float]
    flag: str

    def force_nN(self, t_s: npt.ArrayLike) -> np.ndarray:
        """The fitted F(t) at times since the pause started."""
        t = np.asarray(t_s, float)
        if self.model == NONE:
            return np.full(t.shape, self.relaxed_force_nN)
        return self.relaxed_force_nN + self.amplitude_nN * shape(self.model, t, self.tau_s, self.exponent)

    @property
    def bic_margin(self) -> float:
        """BIC of the runner-up less the preferred model's (≥ 0; NaN without a fit)."""
        values = sorted(v for v in self.bic.values() if np.isfinite(v))
        return values[1] - values[0] if len(values) > 1 else float("nan")


def _linear(phi: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(F_∞, A, RSS) of F = F_∞ + A φ_j for every column φ_j of `phi`, in closed form."""
    pc = phi - phi.mean(axis=0)
    fc = f - f.mean()
    var = np.einsum("ij,ij->j", pc, pc)
    cov = pc.T @ fc
    amp = np.where(var > 0, cov / np.where(var > 0, var, 1.0), 0.0)
    return f.mean() - amp * phi.mean(axis=0), amp, fc @ fc - amp * cov


def _blocks(t: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Block means of (t, F): at most GRID_SAMPLES points for the start grid."""
    size = max(1, int(np.ceil(t.size / GRID_SAMPLES)))
    m = t.size // size * size
    return t[:m].reshape(-1, size).mean(axis=1), f[:m].reshape(-1, size).mean(axis=1)


def _bounds(model: str, step: float, span: float) -> tuple[np.ndarray, np.ndarray]:
    """Bounds of (F_∞, A, ln τ[, ln β]): τ from a quarter sampling step to 100 pauses."""
    lo = [-np.inf, -np.inf, np.log(step / 4.0)] + ([] if model == EXPONENTIAL else [np.log(BETA_RANGE[0])])
    hi = [np.inf, np.inf, np.log(100.0 * span)] + ([] if model == EXPONENTIAL else [np.log(BETA_RANGE[1])])
    return np.array(lo), np.array(hi)


def _start(model: str, t: np.ndarray, f: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """(F_∞, A, ln τ[, ln β]) of the best point of a grid within the bounds."""
    tb, fb = _blocks(t, f)
    taus = np.exp(np.linspace(lo[2], hi[2], 32))
    if model == EXPONENTIAL:
        tau, beta = taus, np.full(taus.size, np.nan)
    else:
        tau, beta = (a.ravel() for a in np.meshgrid(taus, np.exp(np.linspace(lo[3], hi[3], 16))))
    phi = shape(model, tb[:, None], tau[None, :], beta[None, :])
    f_inf, amp, rss = _linear(phi, fb)
    j = int(np.argmin(rss))
    return np.array([f_inf[j], amp[j], np.log(tau[j])] + ([] if model == EXPONENTIAL else [np.log(beta[j])]))


def _residuals(p: np.ndarray, model: str, t: np.ndarray, f: np.ndarray) -> np.ndarray:
    tau = np.exp(p[2])
    return p[0] + p[1] * shape(model, t, tau, np.exp(p[3]) if model == POWER else np.nan) - f


def _jacobian(p: np.ndarray, model: str, t: np.ndarray, f: np.ndarray) -> np.ndarray:
    tau = np.exp(p[2])
    if model == EXPONENTIAL:
        phi = shape(model, t, tau)
        return np.column_stack([np.ones_like(t), phi, p[1] * phi * t / tau])
    beta = np.exp(p[3])
    phi = shape(model, t, tau, beta)
    x = t / tau
    return np.column_stack([np.ones_like(t), phi, p[1] * phi * beta * x / (1.0 + x),
                            -p[1] * phi * beta * np.log1p(x)])


def _fit(model: str, t: np.ndarray, f: np.ndarray, step: float,
         span: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Least-squares parameters, residuals and the unscaled covariance (JᵀJ)⁻¹."""
    lo, hi = _bounds(model, step, span)
    p0 = np.clip(_start(model, t, f, lo, hi), lo + 1e-9, hi - 1e-9)
    res = least_squares(_residuals, p0, jac=_jacobian, bounds=(lo, hi), args=(model, t, f), x_scale="jac",
                        method="trf")
    jac = res.jac
    return res.x, res.fun, np.linalg.pinv(jac.T @ jac)


def _lag1(r: np.ndarray) -> float:
    """The residuals' lag-1 autocorrelation, clipped to [0, 0.99]."""
    r = r - r.mean()
    denom = float(r @ r)
    return float(np.clip((r[1:] @ r[:-1]) / denom, 0.0, 0.99)) if denom > 0 else 0.0


def _bic(rss: float, n: int, k: int, rho: float) -> float:
    n_e = n * (1.0 - rho) / (1.0 + rho)
    return float(n_e * np.log(max(rss, 1e-300) / n) + k * np.log(n_e))


def fit_relaxation(t_s: npt.ArrayLike, force_nN: npt.ArrayLike) -> Relaxation:
    """The relaxation of one pause, F (nN) at times t (s; the pause starts at t[0]):
    every model fitted, the lowest BIC preferred, F_∞ with its 95 % interval, the flag."""
    t = np.asarray(t_s, float)
    f = np.asarray(force_nN, float)
    t = t - t[0]
    n = f.size
    step = float(np.median(np.diff(t))) if n > 1 else 0.0
    span = float(t[-1]) + step if n else 0.0         # the pause's duration: n sampling steps
    if n < MIN_SAMPLES or not step > 0:
        return _constant(f, span, 0.0, {NONE: float("nan")},
                         f"too few samples ({n}) to fit a relaxation: the pause's mean force is used")
    fits = {m: _fit(m, t, f, step, span) for m in MODELS}
    rho = _lag1(fits[POWER][1])
    rss = {m: float(r @ r) for m, (_, r, _) in fits.items()}
    rss[NONE] = float(((f - f.mean()) ** 2).sum())
    k = {EXPONENTIAL: 3, POWER: 4, NONE: 1}
    bic = {m: _bic(rss[m], n, k[m], rho) for m in (NONE, *MODELS)}
    best = min(bic, key=lambda m: bic[m])
    if best == NONE:
        return _flagged(_constant(f, span, rho, bic, ""))
    p, _, cov = fits[best]
    sd = float(np.sqrt(rss[best] / (n - k[best]) * cov[0, 0] * (1.0 + rho) / (1.0 - rho)))
    tau, beta = float(np.exp(p[2])), float(np.exp(p[3])) if best == POWER else float("nan")
    out = Relaxation(best, float(p[0]), sd, float(p[0] - Z95 * sd), float(p[0] + Z95 * sd), float(p[1]),
                     time_to_s(best, np.exp(-1.0), tau, beta), time_to_s(best, 0.1, tau, beta), beta, tau, span,
                     bic, "")
    return _flagged(out)


def _constant(f: np.ndarray, span: float, rho: float, bic: dict[str, float], flag: str) -> Relaxation:
    """No relaxation: F_∞ the pause's mean force, its SD σ_F/√n_e."""
    mean = float(np.mean(f)) if f.size else float("nan")
    n_e = f.size * (1.0 - rho) / (1.0 + rho)
    sd = float(np.std(f, ddof=1) / np.sqrt(n_e)) if f.size > 1 else float("nan")
    nan = float("nan")
    return Relaxation(NONE, mean, sd, mean - Z95 * sd, mean + Z95 * sd, 0.0, nan, nan, nan, nan, span, bic, flag)


def flag_reason(r: Relaxation) -> str:
    """Why this relaxation cannot give the relaxed force (policy), or ''."""
    if r.model != NONE and r.t90_s > r.pause_s:
        return (f"too short to relax: the {r.model} sheds 90 % of its relaxing force in {r.t90_s:.3g} s, "
                f"longer than the {r.pause_s:.3g} s pause (F_inf is an extrapolation)")
    half = (r.relaxed_force_hi95_nN - r.relaxed_force_lo95_nN) / 2.0
    if not r.relaxed_force_nN > 0 or not half <= POOR * r.relaxed_force_nN:
        return (f"relaxed force poorly determined: F_inf = {r.relaxed_force_nN:.3g} nN, 95 % "
                f"[{r.relaxed_force_lo95_nN:.3g}, {r.relaxed_force_hi95_nN:.3g}] nN")
    return ""


def _flagged(r: Relaxation) -> Relaxation:
    return replace(r, flag=flag_reason(r))


COLUMNS = ("pause_duration_s", "relaxation_model", "relaxation_time_s", "relaxation_t90_s", "relaxation_exponent",
           "relaxation_bic_margin", "relaxed_force_nN", "relaxed_force_lo95_nN", "relaxed_force_hi95_nN",
           "relaxation_flag")


def relaxation_columns(r: Relaxation) -> dict[str, object]:
    """A relaxation as the columns of a pause's row (`COLUMNS`, units in the names)."""
    return dict(zip(COLUMNS, (r.pause_s, r.model, r.time_s, r.t90_s, r.exponent, r.bic_margin, r.relaxed_force_nN,
                              r.relaxed_force_lo95_nN, r.relaxed_force_hi95_nN, r.flag)))
