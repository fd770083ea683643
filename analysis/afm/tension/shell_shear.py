"""The shell's K̃_S = K_S/K_B unknown (no `--shear-ratio`): fitted by its profile
likelihood over the ramp table's range, and γ_a's and K_B's intervals widened by
what K̃_S leaves open.

The fit at the reference K̃_S (1/3, or the prior's where the recording's oscillations
give one, `priors`: every fit then reads the posterior; `shell_fit.fit_shell`) tests the
elastic term. Where it is not significant the row is the droplet's (K_B = 0, where the
force does not depend on K̃_S: K̃_S is not identified). Otherwise the fit is redone
at each K̃_S of NODES log-spaced nodes over the table's range [K̃_lo, K̃_hi]
(0.08-2.5), each started from its neighbour's optimum, then by Brent's method in
ln K̃_S between the best node's neighbours (to XATOL): the profile SSE(K̃_S),
each point with its conditional fit θ(K̃_S) = (x0, F_b, γ_a, K_B) and their SDs
(`shell_fit`: the Jacobian's). With σ² = SSE_min / (n − p − 1) (p the conditional
fit's parameters, K̃_S the extra one),

    Δχ²(K̃_S) = (SSE(K̃_S) − SSE_min) / σ²,

read between the profile's points (on FINE points over the range) by its root
√Δχ² linearly in ln K̃_S: exact where the profile is a parabola in ln K̃_S. The point estimate is the fit at the best K̃_S (all its columns). The
95 % interval of K̃_S is the profile likelihood's, {K̃_S : Δχ² ≤ χ²_1(0.95) = 3.84};
that of γ_a (and of K_B) the union over it of the conditional intervals
γ_a(K̃_S) ± Z95 sd(K̃_S): an interval that holds the truth whenever K̃_S's does and
the conditional one does (conservative: the profile likelihood's own interval of
γ_a is its subset with Δχ² + ((γ − γ_a(K̃_S))/sd)² ≤ 3.84). K̃_S is IDENTIFIED when
both ends of its interval lie inside the range, BOUNDED when one does (the ramp
tells one side only), NOT_IDENTIFIED when neither.

The droplet's valley (K_B = 0) is in the same 95 % set where Λ ≤ CHI2_95 (`shell_fit`:
its Δχ² is Λ; `ShellFit.bimodal` when the shell's valley is another one); there the
row is the droplet's, its interval widened to hold the shell's at K̃_S = 1/3 and the
profile over K_B from 0 at 1/3 and at both ends of K̃_S's range (`_droplet_bands`).
"""

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
import numpy.typing as npt
from scipy.optimize import minimize_scalar

from analysis.afm.tension import shell_ramp
from analysis.afm.tension.pause import Z95
from analysis.afm.tension.priors import Prior
from analysis.calibration.ramp_table import ShellTable
from analysis.afm.tension.shell_fit import (CHI2_95, NOT_SIGNIFICANT, PROFILE_TOL, SHEAR_TILDE, Fixed, ShellFit,
                                            bound_profile, fit_shell, refit_shell)

NODES = 9
XATOL = 0.02             # Brent's tolerance in ln K̃_S
FINE = 400               # points of the linear reading of the profile over ln K̃_S
IDENTIFIED, BOUNDED, NOT_IDENTIFIED, GIVEN = "identified", "bounded", "not identified", "given"


@dataclass(frozen=True)
class Profile:
    """The profile over K̃_S: its points (sorted), Δχ² and conditional fits, and the best."""

    shears: np.ndarray
    chi2: np.ndarray
    fits: list[ShellFit]
    best: ShellFit


def shear_range(table: ShellTable | None = None) -> tuple[float, float]:
    """[K̃_lo, K̃_hi]: the K_S/K_B axis of the shell ramp table (None: the shipped one)."""
    shears = shell_ramp.resolve(table).shears
    return float(shears[0]), float(shears[-1])


def profile(fit: ShellFit, x_um: npt.ArrayLike, force_nN: npt.ArrayLike, radius_um: float,
            bulk_mN_per_m: float | None = None, prior: Prior | None = None) -> Profile:
    """The profile of `fit` (a shell fit of the ramp, at any K̃_S) over K̃_S (module doc);
    K_B fixed at `bulk_mN_per_m` when given; with `prior` (`shell_fit.Fixed.prior`) the posterior's;
    on the shell ramp table of `fit` (`ShellFit.table`)."""
    nodes = np.geomspace(*shear_range(fit.table), NODES)
    done: dict[float, ShellFit] = {}

    def at(s: float, near: ShellFit) -> ShellFit:
        done[s] = refit_shell(near, x_um, force_nN, radius_um, Fixed(s, bulk_mN_per_m, prior, fit.table),
                              PROFILE_TOL)
        return done[s]

    start = int(np.argmin(np.abs(np.log(nodes / fit.shear_tilde))))
    near = fit
    for s in nodes[start:]:
        near = at(float(s), near)
    near = done[float(nodes[start])]
    for s in nodes[start - 1::-1] if start > 0 else []:
        near = at(float(s), near)
    b = int(np.argmin([done[float(s)].sse_nN2 for s in nodes]))
    lo, hi = np.log(nodes[max(b - 1, 0)]), np.log(nodes[min(b + 1, NODES - 1)])

    def sse(u: float) -> float:
        closest = min(done, key=lambda s: abs(np.log(s) - u))
        return at(float(np.exp(u)), done[closest]).sse_nN2

    minimize_scalar(sse, bounds=(lo, hi), method="bounded", options={"xatol": XATOL})
    shears = np.array(sorted(done))
    fits = [done[s] for s in shears]
    sses = np.array([g.sse_nN2 for g in fits])
    best = fits[int(np.argmin(sses))]
    dof = int(best.window.sum()) - (4 if bulk_mN_per_m is None else 3) - 1
    return Profile(shears, (sses - sses.min()) / (sses.min() / max(dof, 1)), fits, best)


def profile_bands(shears: npt.ArrayLike, chi2: npt.ArrayLike,
                  estimates: Sequence[tuple[npt.ArrayLike, npt.ArrayLike]]) -> list[tuple[float, float]]:
    """The 95 % band of K̃_S from a profile over it (its points `shears`, sorted, and their
    Δχ²) read on FINE points (module doc), then that of each (values, SDs) at the points:
    the union of value ± Z95 SD over K̃_S's band (at least 0)."""
    u = np.log(np.asarray(shears, float))
    grid = np.linspace(u[0], u[-1], FINE) if u.size > 1 else u
    grid = np.union1d(grid, u)
    ok = np.interp(grid, u, np.sqrt(np.asarray(chi2, float))) <= np.sqrt(CHI2_95)
    out = [(float(np.exp(grid[ok].min())), float(np.exp(grid[ok].max())))]
    for values, sds in estimates:
        v = np.interp(grid, u, np.asarray(values, float))[ok]
        w = Z95 * np.interp(grid, u, np.asarray(sds, float))[ok]
        out.append((float(max(np.min(v - w), 0.0)), float(np.max(v + w))))
    return out


def _bands(prof: Profile) -> tuple[tuple[float, float], tuple[float, float], tuple[float, float]]:
    """The 95 % bands of K̃_S, γ_a and K_B from the profile (`profile_bands`)."""
    shear, tension, bulk = profile_bands(prof.shears, prof.chi2, [
        ([g.tension_mN_per_m for g in prof.fits], [g.tension_sd_mN_per_m for g in prof.fits]),
        ([g.bulk_mN_per_m for g in prof.fits], [g.bulk_sd_mN_per_m for g in prof.fits])])
    return shear, tension, bulk


def fit_unknown_shear(x_um: npt.ArrayLike, force_nN: npt.ArrayLike, radius_um: float,
                      bulk_mN_per_m: float | None = None, cap_um: float | None = None,
                      prior: Prior | None = None, table: ShellTable | None = None) -> ShellFit:
    """The shell fit of one ramp with K̃_S unknown (module doc): the best K̃_S's fit with
    the bands of K̃_S, γ_a and K_B; the droplet's (`fit_shell` at 1/3) where the elastic
    term is not significant, its K̃_S band the whole range. With `prior` (the oscillations',
    `priors.Prior`) every fit reads the posterior and the reference K̃_S is the prior's. `table`:
    the shell ramp table (None: the shipped one)."""
    ref = SHEAR_TILDE if prior is None else float(np.clip(prior.shear_tilde, *shear_range(table)))
    fit = fit_shell(x_um, force_nN, radius_um, Fixed(ref, bulk_mN_per_m, prior, table), cap_um=cap_um)
    if fit.elastic_term == NOT_SIGNIFICANT:
        return _droplet_bands(fit, x_um, force_nN, radius_um, prior)
    prof = profile(fit, x_um, force_nN, radius_um, bulk_mN_per_m, prior)
    shear, tension, bulk = _bands(prof)
    best = prof.best
    lr = fit.elastic_lr
    if np.isfinite(lr):                          # Λ at the best K̃_S: SSE_0 = SSE(1/3) + Λ σ²(1/3)
        lr = (fit.sse_nN2 + lr * fit.noise_nN ** 2 - best.sse_nN2) / best.noise_nN ** 2
    if bulk_mN_per_m is not None:
        bulk = (bulk_mN_per_m, bulk_mN_per_m)
    return replace(best, elastic_term=fit.elastic_term, elastic_lr=float(lr), shear_band=shear,
                   tension_band_mN_per_m=tension, bulk_band_mN_per_m=bulk, bimodal=fit.bimodal and lr <= CHI2_95)


def _droplet_bands(fit: ShellFit, x_um: npt.ArrayLike, force_nN: npt.ArrayLike, radius_um: float,
                   prior: Prior | None = None) -> ShellFit:
    """The droplet's row (the elastic term not significant) with the bands of γ_a and K_B that hold
    the 95 % set over K̃_S too: its own interval (`shell_fit._select`, at K̃_S = 1/3) joined with the
    profile over K_B at each end of K̃_S's range (`bound_profile`, the limit SSE_0 + CHI2_95 σ²);
    bimodal also where a profile's set is split (two valleys)."""
    xs, fs = np.asarray(x_um, float)[fit.window], np.asarray(force_nN, float)[fit.window]
    g, half = fit.tension_mN_per_m, Z95 * fit.tension_sd_mN_per_m
    lo_g, hi_g, hi_k, split = g - half, g + half, fit.bulk_mN_per_m + Z95 * fit.bulk_sd_mN_per_m, False
    for shear in shear_range(fit.table):
        a, b, k, two = bound_profile(xs, fs, radius_um, shear, fit.theta(), fit.sse_nN2, fit.noise_nN, prior,
                                     fit.table)
        lo_g, hi_g, hi_k, split = min(lo_g, a), max(hi_g, b), max(hi_k, k), split or two
    return replace(fit, shear_band=shear_range(fit.table), tension_band_mN_per_m=(max(lo_g, 0.0), hi_g),
                   bulk_band_mN_per_m=(0.0, hi_k), bimodal=fit.bimodal or split)


def identification(fit: ShellFit) -> str:
    """IDENTIFIED, BOUNDED or NOT_IDENTIFIED from the fit's K̃_S band (GIVEN without one)."""
    if fit.shear_band is None:
        return GIVEN
    lo, hi = shear_range(fit.table)
    inside = [fit.shear_band[0] > lo * (1 + 1e-9), fit.shear_band[1] < hi * (1 - 1e-9)]
    if fit.elastic_term == NOT_SIGNIFICANT:
        return NOT_IDENTIFIED
    return IDENTIFIED if all(inside) else BOUNDED if any(inside) else NOT_IDENTIFIED
