"""The active tension γ_a and bulk modulus K_B of one approach ramp by the shell
model (`shell_ramp`: the cortex of SPEC 2 pressed from its free sphere).

The model of the window's samples (x_i, F_i), δ_i = max(x0 - x_i, 0):

    F_i = F_b + s (x_i - x0) + F_shell(δ_i; R, γ_a, K_B, K̃_S),

fitted by least squares in θ = (x0, F_b, γ_a, K_B, s) (scipy least_squares, γ_a > 0,
K_B ≥ 0: K_B = 0 is the tension-only droplet), K̃_S fixed (`Fixed.shear_tilde`,
default 1/3: ν = 0.5, SPEC 2; unknown: `shell_shear` profiles it), and K_B too where a
lab knows it from the same cell's oscillations (`Fixed.bulk_mN_per_m`). The
baseline is a line: F_b the free deflection's force at the contact and s (nN/µm)
its slope against the wedge height x, the tilt a deflection signal keeps where
it was not levelled (a NanoScope file against its NanoScope Analysis export:
0.1 nN/µm on the shared one). The window holds as much baseline above the
contact as compression below it, which pins s; a tilt left out mimics (s < 0) or
hides (s > 0) force that grows with depth, and moves γ_a by tens of per cent.

Window: the droplet fit's (`ramp.fit_ramp`) with its depth capped at the
table's deepest δ/R (and at `cap_um`); its contact and baseline start the fit.
Starts: for each γ̃_a of a log grid (and K_B = 0) the model is linear in
(F_b, s, K_B) at a given contact, which a Brent search finds near the droplet's;
the fit runs from each local minimum of their SSE over γ̃_a (at most STARTS)
and keeps the best.

Errors: σ² = SSE / (n - p) from the residuals, Cov θ = σ² (JᵀJ)⁻¹ (J the
Jacobian at the optimum); `sd` holds the SDs of γ_a, K_B and s and `correlation`
that of γ_a with K_B. At the bound K_B = 0 the Jacobian's SDs do not hold (a ramp
that cannot tell γ_a from K_B often lands there): the fit is redone at
K_B = γ_a · PROFILE (the profile over K_B), the edges of its 95 % set
(Δχ² ≤ CHI2_95) bisected, and the SDs widened to the span of the accepted
ones (`_bound_sds`). `shell_interval`: the 95 % intervals with the volume error.

Elastic term (K_B free only): the droplet (K_B = 0) is nested in the shell, so
on the same window Λ = (SSE_0 - SSE_1) / σ² (σ² the shell's) tests K_B = 0.
K_B = 0 sits on the boundary of K_B ≥ 0, so under the droplet Λ follows the
50:50 mixture of χ²_0 and χ²_1 (Self & Liang 1987), whose 5 % threshold is the
χ²_1 0.90 quantile, LR_THRESHOLD = 2.71. The contact x0 is not a regular
parameter (the force has a kink there), and a droplet's ramp often finds a
second valley (x0 a few nm deeper, K_B > 0, γ_a lower): on tension-only ramps
Λ exceeded 2.71 in 3 of 24 (up to 7.6). The term is therefore tested at the
BIC's threshold ln n (n the window's samples; ≈ 8 for a few thousand, a
false-alarm rate under 0.3 % by the mixture), and never below 2.71. Below it
the elastic term is "not significant" and the fit returned is the droplet's (γ_a its tension, K_B = 0),
with intervals that still cover the shell's: the SD of γ_a such that
γ_0 ± Z95 sd holds γ_1 ± Z95 sd_1, and K_B's upper 95 % bound that of the
shell (its profile where it sits at the bound), so the selection never makes
an interval narrower than the shell's (`_select`). Both valleys lie in the 95 %
set when Λ ≤ CHI2_95 and the shell's optimum is another valley (K_B > 0, its γ_a
beyond its own Z95 · sd of the droplet's): `bimodal`, the ramp cannot choose.

Priors (`Fixed.prior`, `priors`): where the same recording's oscillations give K_B and K̃_S
at the ramp's time scale, their Gaussian priors are two more rows of the residual vector,
σ (K_B - K̄_B)/sd_K and σ ln(K̃_S/K̄_S)/sd_lnS (σ the ramp's noise), so SSE/σ² is -2 ln of the
posterior: the Jacobian's covariance, Λ, the profiles over K_B and K̃_S and the intervals all
read it (σ² is taken from that SSE: the rows add about 2 to a χ² of n).
"""

from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np
import numpy.typing as npt
from scipy.optimize import least_squares, minimize_scalar

from analysis.afm.tension import shell_ramp
from analysis.afm.tension.pause import TENSION_ERRORS, Z95
from analysis.afm.tension.priors import Prior
from analysis.invert.measurement_errors import MeasurementErrors
from analysis.afm.tension.ramp import fit_ramp
from analysis.calibration.ramp_table import ShellTable
from common.errors import InputError
from solver.geometry import cell_radius

SHEAR_TILDE = 1.0 / 3.0          # K_S/K_B of an isotropic sheet with ν = 0.5 (SPEC 2)
START_GAMMAS = np.geomspace(0.002, 1.0, 13)
STARTS = 3
BOUND = 1e-6            # K_B below this share of γ_a: the fit is at the droplet's bound
PROFILE = 2.0 ** np.arange(-2, 7)   # K_B / γ_a of the bound's profile (1/4 to 64)
EDGE = 3                 # bisections of each edge of its 95 % set
FAR = 30.0               # the profile stops once Δχ² passes this, rising
TOL = 1e-12              # least_squares' xtol and ftol of a fit
PROFILE_TOL = 1e-8       # and of the profile over K̃_S (`shell_shear`): Δχ² to 1e-3
BOUND_TOL = 1e-6         # and of the profile over K_B at the bound: Δχ² to about 0.01, against its 3.84
SPAN = 0.1               # the starts' contacts within this share of the window of the droplet's
LR_THRESHOLD = 2.71      # Λ of the elastic term at least this: χ²_1 at 0.90, the 5 % level of ½χ²_0 + ½χ²_1,
                         # and at least ln n (BIC; module doc)
CHI2_95 = 3.84           # χ²_1 at 0.95: the 95 % set of a profile likelihood
SIGNIFICANT, NOT_SIGNIFICANT, GIVEN = "significant", "not significant", "K_B given"


@dataclass(frozen=True)
class Fixed:
    """What the fit does not fit: K̃_S, and K_B (mN/m) when known (None: fitted); what it
    knows beforehand: the Gaussian priors of the same cell's oscillations (`priors.Prior`, None:
    none), rows of the residual vector in every fit that uses this `Fixed` (module doc); and the
    shell ramp table of its model (None: the shipped one, `shell_ramp.resolve`)."""

    shear_tilde: float = SHEAR_TILDE
    bulk_mN_per_m: float | None = None
    prior: Prior | None = None
    table: ShellTable | None = field(default=None, compare=False, repr=False)


@dataclass(frozen=True)
class ShellFit:
    """The fitted shell: γ_a, K_B (mN/m) with their SDs and correlation, contact x0
    (µm), baseline F_b (nN), R² and noise SD (nN) on the window (the droplet fit's,
    `window`), the deepest deformation in it (µm), K̃_S used; `elastic_term` whether the
    droplet was chosen (module doc: SIGNIFICANT, NOT_SIGNIFICANT or GIVEN) and Λ; `sse_nN2`
    the residual sum of squares (nN²). The bands are the statistical 95 % ends of γ_a,
    K_B and K̃_S where they are not value ± Z95 · sd (K̃_S profiled: `shell_shear`); None
    otherwise (K̃_S fixed). `droplet_tension_mN_per_m`: the droplet's T on the window. `table`:
    the shell ramp table of the fit (`Fixed.table`).
    `baseline_slope_nN_per_um` s and its SD: the baseline's slope against x (module doc).
    `bimodal`: the droplet's valley (K_B = 0) and the shell's (K_B > 0) both in the 95 % set."""

    tension_mN_per_m: float
    bulk_mN_per_m: float
    tension_sd_mN_per_m: float
    bulk_sd_mN_per_m: float
    correlation: float
    contact_um: float
    baseline_nN: float
    r2: float
    noise_nN: float
    window_lo_um: float
    window_hi_um: float
    window: npt.NDArray[np.bool_]
    depth_um: float
    shear_tilde: float
    model: str = "shell"
    elastic_term: str = GIVEN
    elastic_lr: float = float("nan")
    sse_nN2: float = float("nan")
    tension_band_mN_per_m: tuple[float, float] | None = None
    bulk_band_mN_per_m: tuple[float, float] | None = None
    shear_band: tuple[float, float] | None = None
    droplet_tension_mN_per_m: float = float("nan")
    baseline_slope_nN_per_um: float = 0.0
    baseline_slope_sd_nN_per_um: float = 0.0
    bimodal: bool = False
    table: ShellTable | None = field(default=None, compare=False, repr=False)

    def baseline_at(self, x_um: npt.ArrayLike) -> np.ndarray:
        """The fitted baseline F_b + s (x - x0) at wedge heights x (µm)."""
        return self.baseline_nN + self.baseline_slope_nN_per_um * (np.asarray(x_um, float) - self.contact_um)

    def force_nN(self, x_um: npt.ArrayLike, radius_um: float) -> np.ndarray:
        """The fitted force at wedge heights x (µm)."""
        return self.baseline_at(x_um) + shell_ramp.force_nN(self.contact_um - np.asarray(x_um, float), radius_um,
                                                            self.tension_mN_per_m, self.bulk_mN_per_m,
                                                            self.shear_tilde, self.table)

    def theta(self) -> tuple[float, float, float, float, float]:
        """θ = (x0, F_b, γ_a, K_B, s): a start for another fit of the same ramp."""
        return (self.contact_um, self.baseline_nN, self.tension_mN_per_m, self.bulk_mN_per_m,
                self.baseline_slope_nN_per_um)


def _linear(x: np.ndarray, f: np.ndarray, x0: float, radius: float, fixed: Fixed, gt: float
            ) -> tuple[float, float, float, float, float]:
    """(SSE, F_b, γ_a, K_B, s) of the fit linear in (F_b, s, K_B) at contact x0 and γ̃_a = gt (∞: K_B = 0),
    K̃_S and the table `fixed`'s."""
    b = shell_ramp.force_nN(np.clip(x0 - x, 0.0, None), radius, 1.0, 0.0 if np.isinf(gt) else 1.0 / gt,
                            fixed.shear_tilde, fixed.table)
    a = np.stack([np.ones_like(b), x - x0, b], axis=1)
    coef, *_ = np.linalg.lstsq(a, f, rcond=None)
    sse = float(np.sum((f - a @ coef) ** 2)) if coef[2] > 0 else np.inf
    return sse, float(coef[0]), float(coef[2]), 0.0 if np.isinf(gt) else float(coef[2] / gt), float(coef[1])


def _starts(x: np.ndarray, f: np.ndarray, x0: float, span: float, radius: float, fixed: Fixed
            ) -> list[tuple[float, ...]]:
    """[(x0, F_b, γ_a, K_B, s)]: for each γ̃_a of START_GAMMAS and K_B = 0 the best contact
    within `span` of x0 (Brent; the rest linear), the local minima of their SSE
    over γ̃_a, best first, at most STARTS."""
    found = []
    for gt in np.append(START_GAMMAS, np.inf):
        res = minimize_scalar(lambda c: _linear(x, f, c, radius, fixed, gt)[0], bounds=(x0 - span, x0 + span),
                              method="bounded", options={"xatol": 1e-3 * span})
        found.append((float(res.x),) + _linear(x, f, float(res.x), radius, fixed, gt))
    sse = np.array([s[1] for s in found])
    if not np.any(np.isfinite(sse)):
        raise InputError("approach ramp: no rise the shell model can fit")
    padded = np.concatenate([[np.inf], sse, [np.inf]])
    minima = [i for i in range(sse.size) if np.isfinite(sse[i]) and sse[i] <= padded[i] and sse[i] <= padded[i + 2]]
    return [(found[i][0],) + found[i][2:] for i in sorted(minima, key=lambda i: sse[i])[:STARTS]]


def _solve(x: np.ndarray, f: np.ndarray, radius: float, fixed: Fixed, theta0: Sequence[float] | np.ndarray,
           tol: float = TOL) -> tuple[np.ndarray, float, np.ndarray]:
    """least_squares from θ0 = (x0, F_b, γ_a, K_B, s) to `tol` (relative, in θ and SSE); K_B fixed when
    `fixed` says so, the prior's rows appended to the residuals where it has one (the SSE then
    includes them). (θ, SSE, Jacobian): the Jacobian's columns those of the free parameters in θ's
    order (x0, F_b, γ_a, [K_B], s), its rows the samples' and the prior's."""
    free_k = fixed.bulk_mN_per_m is None
    kb = 0.0 if fixed.bulk_mN_per_m is None else fixed.bulk_mN_per_m
    t0 = np.asarray(theta0, float)

    def model(p: np.ndarray) -> np.ndarray:
        k = p[3] if free_k else kb
        return p[1] + p[-1] * (x - p[0]) + shell_ramp.force_nN(p[0] - x, radius, p[2], k, fixed.shear_tilde,
                                                               fixed.table)

    def residuals(p: np.ndarray) -> np.ndarray:
        r = model(p) - f
        if fixed.prior is None:
            return r
        return np.append(r, fixed.prior.penalty(p[3] if free_k else kb, fixed.shear_tilde))

    p0 = np.append(t0[:4] if free_k else t0[:3], t0[4] if t0.size > 4 else 0.0)
    p0[2] = max(p0[2], 1e-6)
    lo = [-np.inf, -np.inf, 1e-9] + ([0.0] if free_k else []) + [-np.inf]
    scale = [0.01, 0.01, max(p0[2], 1e-3)] + ([max(p0[3], p0[2], 1e-3)] if free_k else []) + [0.01]
    res = least_squares(residuals, np.maximum(p0, lo), bounds=(lo, np.inf), x_scale=scale,
                        diff_step=1e-6, xtol=tol, ftol=tol)
    p = res.x if free_k else np.insert(res.x, 3, kb)
    return p, float(2.0 * res.cost), res.jac


def _errors(sse: float, jac: np.ndarray, n: int) -> tuple[float, float, float, float, float]:
    """(σ, SD of γ_a, SD of K_B, their correlation, SD of s) from the Jacobian (module doc;
    its columns as `_solve` returns them: four where K_B is fixed)."""
    p = jac.shape[1]
    sigma2 = sse / max(n - p, 1)
    cov = sigma2 * np.linalg.pinv(jac.T @ jac)
    sd = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    if p < 5:
        return float(np.sqrt(sigma2)), float(sd[2]), 0.0, float("nan"), float(sd[-1])
    corr = cov[2, 3] / (sd[2] * sd[3]) if sd[2] > 0 and sd[3] > 0 else float("nan")
    return float(np.sqrt(sigma2)), float(sd[2]), float(sd[3]), float(corr), float(sd[-1])


def _bound_sds(x: np.ndarray, f: np.ndarray, radius: float, fixed: Fixed, p: np.ndarray, sse: float, sigma: float,
               sd_g: float, sd_k: float) -> tuple[float, float]:
    """SDs of γ_a and K_B for a fit at K_B = 0, where the Jacobian's do not hold: the
    accepted K_B of `bound_profile`, and their γ_a, span 95 % (each SD that span / Z95 if wider)."""
    lo_g, hi_g, hi_k, _ = bound_profile(x, f, radius, fixed.shear_tilde, p, sse, sigma, fixed.prior, fixed.table)
    return max(sd_g, (hi_g - lo_g) / Z95), max(sd_k, hi_k / Z95)


def bound_profile(x: np.ndarray, f: np.ndarray, radius: float, shear: float, p: Sequence[float] | np.ndarray,
                  sse: float, sigma: float, prior: Prior | None = None, table: ShellTable | None = None
                  ) -> tuple[float, float, float, bool]:
    """(lowest γ_a, highest γ_a, highest K_B, split) of the 95 % set {K_B : SSE ≤ sse + CHI2_95 σ²}
    of the profile over K_B from a fit θ = `p` (SSE `sse`, noise σ) at K_B = 0 on the window (x, f),
    K̃_S = `shear`: refits at K_B = γ_a · PROFILE, each from its neighbour, each edge found by EDGE
    bisections between an accepted and a rejected K_B (from 0 arithmetic, else geometric). The grid
    is walked until Δχ² passes FAR and still rises: the SSE may have two valleys (`split`: the set
    is not one interval from K_B = 0). `prior`, `table`: the fits' (`Fixed`)."""
    limit, far, last_s = sse + CHI2_95 * sigma ** 2, sse + FAR * sigma ** 2, sse

    def at(k: float, near: np.ndarray) -> tuple[np.ndarray, bool, float]:
        theta, s, _ = _solve(x, f, radius, Fixed(shear, float(k), prior, table), near, BOUND_TOL)
        return theta, s <= limit, s

    lo_g, hi_g, hi_k, runs = p[2], p[2], 0.0, 1
    last_k, last_theta, last_ok = 0.0, np.asarray(p, float), True
    for k in p[2] * PROFILE:
        theta, ok, s = at(k, last_theta)
        runs += int(ok and not last_ok)
        if ok != last_ok:                          # an edge of the set between last_k and k: bisect it
            a, b, near = (last_k, k, last_theta) if last_ok else (k, last_k, theta)
            for _ in range(EDGE):
                mid = 0.5 * (a + b) if min(a, b) == 0 else float(np.sqrt(a * b))
                t_mid, ok_mid, _ = at(mid, near)
                if ok_mid:
                    a, near = mid, t_mid
                    lo_g, hi_g, hi_k = min(lo_g, t_mid[2]), max(hi_g, t_mid[2]), max(hi_k, mid)
                else:
                    b = mid
        if ok:
            lo_g, hi_g, hi_k = min(lo_g, theta[2]), max(hi_g, theta[2]), max(hi_k, float(k))
        if s > far and s > last_s:
            break
        last_k, last_theta, last_ok, last_s = float(k), theta, ok, s
    return float(lo_g), float(hi_g), float(hi_k), runs > 1


@dataclass(frozen=True)
class _Selected:
    """What `_select` returns: θ, SSE, the SDs of γ_a, K_B and s, the correlation, the elastic
    term, Λ and whether both valleys are in the 95 % set."""

    theta: np.ndarray
    sse: float
    sd_g: float
    sd_k: float
    sd_s: float
    corr: float
    term: str
    lr: float
    bimodal: bool


def _select(x: np.ndarray, f: np.ndarray, radius: float, fixed: Fixed, p: np.ndarray, sse: float, sigma: float,
            sds: tuple[float, float, float], corr: float, starts: list[tuple[float, ...]]) -> _Selected:
    """The shell's fit or, where its elastic term is not significant, the droplet's (the best from
    the shell's optimum and each start) with the widened SDs (module doc); `sds` the shell's SDs of
    γ_a, K_B and s. Bimodal: the shell's optimum inside K_B > 0, Λ ≤ CHI2_95 (the droplet inside
    the 95 % set) and the two γ_a further apart than the shell's own Z95 · sd (two valleys, not
    one long one)."""
    sd_g, sd_k, sd_s = sds
    drop = replace(fixed, bulk_mN_per_m=0.0)
    p0, sse0, jac0 = min((_solve(x, f, radius, drop, t) for t in [p] + starts), key=lambda t: t[1])
    lr = max(sse0 - sse, 0.0) / sigma ** 2
    bimodal = bool(p[3] > BOUND * p[2] and lr <= CHI2_95 and abs(p[2] - p0[2]) > Z95 * sd_g)
    if lr > max(LR_THRESHOLD, float(np.log(x.size))):
        return _Selected(p, sse, sd_g, sd_k, sd_s, corr, SIGNIFICANT, float(lr), bimodal)
    _, sd_g0, _, _, sd_s0 = _errors(sse0, jac0, x.size)
    wide_g = max(sd_g0, (abs(p[2] - p0[2]) + Z95 * sd_g) / Z95)
    wide_k = max(sd_k, (p[3] + Z95 * sd_k) / Z95)
    wide_s = max(sd_s0, (abs(p[4] - p0[4]) + Z95 * sd_s) / Z95)
    return _Selected(p0, sse0, wide_g, wide_k, wide_s, float("nan"), NOT_SIGNIFICANT, float(lr), bimodal)


def fit_shell(x_um: npt.ArrayLike, force_nN: npt.ArrayLike, radius_um: float, fixed: Fixed = Fixed(),
              cap_um: float | None = None, near: "ShellFit | None" = None) -> ShellFit:
    """γ_a and K_B of one approach ramp (module doc); `near` a fit of the same ramp
    to start from instead of the starts' grid (a nested window). InputError for a
    ramp without contact or a window too short."""
    x, f = np.asarray(x_um, float), np.asarray(force_nN, float)
    cap = shell_ramp.resolve(fixed.table).max_depth * radius_um
    cap = cap if cap_um is None else min(cap, cap_um)
    drop = fit_ramp(x, f, radius_um, "droplet", cap_um=cap)
    xs, fs = x[drop.window], f[drop.window]
    span = SPAN * (drop.window_hi_um - drop.window_lo_um)
    starts = [near.theta()] if near else _starts(xs, fs, drop.contact_um, span, radius_um, fixed)
    kb = fixed.bulk_mN_per_m
    tries = [_solve(xs, fs, radius_um, fixed, (t[0], t[1], t[2], t[3] if kb is None else kb, t[4])) for t in starts]
    p, sse, jac = min(tries, key=lambda t: t[1])
    sigma, sd_g, sd_k, corr, sd_s = _errors(sse, jac, xs.size)
    if kb is None and p[3] < BOUND * p[2]:
        sd_g, sd_k = _bound_sds(xs, fs, radius_um, fixed, p, sse, sigma, sd_g, sd_k)
    chosen = _Selected(p, sse, sd_g, sd_k, sd_s, corr, GIVEN, float("nan"), False)
    if kb is None:
        droplet_start = (drop.contact_um, drop.baseline_nN, drop.tension_mN_per_m, 0.0, 0.0)
        chosen = _select(xs, fs, radius_um, fixed, p, sse, sigma, (sd_g, sd_k, sd_s), corr,
                         [droplet_start] + list(starts))
    p, sse = chosen.theta, chosen.sse
    sst = float(np.sum((fs - fs.mean()) ** 2))
    return ShellFit(tension_mN_per_m=float(p[2]), bulk_mN_per_m=float(p[3]), tension_sd_mN_per_m=chosen.sd_g,
                    bulk_sd_mN_per_m=chosen.sd_k, correlation=chosen.corr, contact_um=float(p[0]),
                    baseline_nN=float(p[1]), r2=1.0 - sse / sst if sst > 0 else float("nan"), noise_nN=float(sigma),
                    window_lo_um=drop.window_lo_um, window_hi_um=drop.window_hi_um, window=drop.window,
                    depth_um=float(max(p[0] - xs.min(), 0.0)), shear_tilde=fixed.shear_tilde,
                    elastic_term=chosen.term, elastic_lr=chosen.lr, sse_nN2=sse,
                    droplet_tension_mN_per_m=drop.tension_mN_per_m, baseline_slope_nN_per_um=float(p[4]),
                    baseline_slope_sd_nN_per_um=chosen.sd_s, bimodal=chosen.bimodal, table=fixed.table)


def refit_shell(fit: ShellFit, x_um: npt.ArrayLike, force_nN: npt.ArrayLike, radius_um: float,
                fixed: Fixed, tol: float = TOL) -> ShellFit:
    """`fit` refitted on its own window for another radius or another fixed K̃_S / K_B
    (least squares to `tol`)."""
    xs, fs = np.asarray(x_um, float)[fit.window], np.asarray(force_nN, float)[fit.window]
    kb = fit.bulk_mN_per_m if fixed.bulk_mN_per_m is None else fixed.bulk_mN_per_m
    start = (fit.contact_um, fit.baseline_nN, fit.tension_mN_per_m, kb, fit.baseline_slope_nN_per_um)
    p, sse, jac = _solve(xs, fs, radius_um, fixed, start, tol)
    sigma, sd_g, sd_k, corr, sd_s = _errors(sse, jac, xs.size)
    sst = float(np.sum((fs - fs.mean()) ** 2))
    return replace(fit, tension_mN_per_m=float(p[2]), bulk_mN_per_m=float(p[3]), tension_sd_mN_per_m=sd_g,
                   bulk_sd_mN_per_m=sd_k, correlation=corr, contact_um=float(p[0]), baseline_nN=float(p[1]),
                   baseline_slope_nN_per_um=float(p[4]), baseline_slope_sd_nN_per_um=sd_s,
                   r2=1.0 - sse / sst if sst > 0 else float("nan"), noise_nN=float(sigma),
                   depth_um=float(max(p[0] - xs.min(), 0.0)), shear_tilde=fixed.shear_tilde, sse_nN2=sse,
                   tension_band_mN_per_m=None, bulk_band_mN_per_m=None, shear_band=None, table=fixed.table)


def shell_interval(fit: ShellFit, x_um: npt.ArrayLike, force_nN: npt.ArrayLike, volume_um3: float,
                   fixed: Fixed, errors: MeasurementErrors = TENSION_ERRORS) -> tuple[float, float, float, float]:
    """(γ_lo, γ_hi, K_B lo, K_B hi): 95 % intervals of γ_a and K_B, the statistical
    half-width (Z95 · sd, or the distance to the fit's band where it has one: K̃_S
    profiled) and the volume error's shift (refits at V (1 ± Z95 σ_V) on the same
    window with `fixed`, as `pause.ramp_interval`) added in quadrature on each side;
    the refits of a fit that chose the droplet keep K_B = 0."""
    if fit.elastic_term == NOT_SIGNIFICANT and fixed.bulk_mN_per_m is None:
        fixed = replace(fixed, bulk_mN_per_m=0.0)
    shifted = [refit_shell(fit, x_um, force_nN, float(cell_radius(volume_um3 * (1.0 + s * Z95 * errors.volume_rel_sd))),
                           fixed) for s in (-1.0, 1.0)]
    out = []
    for value, sd, band, ends in ((fit.tension_mN_per_m, fit.tension_sd_mN_per_m, fit.tension_band_mN_per_m,
                                   [g.tension_mN_per_m for g in shifted]),
                                  (fit.bulk_mN_per_m, fit.bulk_sd_mN_per_m, fit.bulk_band_mN_per_m,
                                   [g.bulk_mN_per_m for g in shifted])):
        below, above = (Z95 * sd, Z95 * sd) if band is None else (value - band[0], band[1] - value)
        down, up = max(value - min(ends), 0.0), max(max(ends) - value, 0.0)
        out += [max(value - float(np.hypot(below, down)), 0.0), value + float(np.hypot(above, up))]
    return out[0], out[1], out[2], out[3]
