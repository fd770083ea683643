"""K̃_S = K_S/K_B of the power-law shell's ramp-and-hold reading unknown (no `--shear-ratio`,
no oscillation prior): profiled over SHEAR_RANGE, and γ_a's interval widened by what K̃_S
leaves open (SPEC 11-12; `powerlaw_fit` is the fit at one K̃_S; the profile is read as the
elastic shell's, `shell_shear.profile_bands`).

The fit (`powerlaw_fit.correct`, β free: the tabled simulator's where the power-law table
holds the recording, else the defect correction's) at each of NODES values of K̃_S log-spaced
over SHEAR_RANGE: first at the node nearest 1/3 (`powerlaw_fit.start`, polished), then outward,
each started from its neighbour's optimum and correction (tabled: the first node's polish carried;
simulated: refreshed by at most PROFILE_SIMULATIONS simulations at the node); then once more at the vertex of the parabola in
ln K̃_S through the best node and its two neighbours (where the best is inside the range).
The best K̃_S's fit, its correction carried on to the tolerances, is the reading
(`powerlaw_fit.conclude`: without a hold, β's profile there), with σ² = SSE_min / (n − 7)
(K̃_S the seventh parameter) and

    Δχ²(K̃_S) = (SSE(K̃_S) − SSE_min) / σ².

K̃_S's 95 % interval is {K̃_S : Δχ² ≤ CHI2_95}: each end between a point inside and the
next outside found by regula falsi on √Δχ² − √CHI2_95 in ln K̃_S (the two points' fits first
carried on to the tolerances, their node's few simulations leaving the SSE high; at most
END_FITS fits an end, each started from the nearer point's optimum and correction and
settled, until the end's two points are END_TOL apart in ln K̃_S), then read between the
points (√Δχ² linear in ln K̃_S); where an end's fit finds a lower SSE than the best (a sharp
profile's vertex fit stopped short of it), it is the best: the reading concluded there and
the ends located again, once. γ_a's is the union over that set of γ_a(K̃_S) ± Z95 sd(K̃_S)
(sd at the common σ²), joined with β's band at the
best K̃_S without a hold (β is profiled there only, not over every K̃_S). An end of the range
inside the set: the recording bounds K̃_S on that side no further than the range.
"""

from dataclasses import replace

import numpy as np
import numpy.typing as npt

from analysis.afm.tension.powerlaw_fit import (PROFILE_SIMULATIONS, PowerLawFit, Samples, Solved, conclude, correct,
                                               prepare, sds, start)
from analysis.afm.tension.ramp import RampFit
from analysis.afm.tension.shell_fit import CHI2_95, SHEAR_TILDE
from analysis.afm.tension.shell_shear import profile_bands
from analysis.calibration.powerlaw_table import PowerLawTable
from analysis.calibration.ramp_table import ShellTable
from common.errors import SolverError

SHEAR_RANGE = (0.1, 2.0)
NODES = 5
NEAR = 0.05              # in ln K̃_S: a vertex this close to a node is not fitted again
END_FITS = 2             # fits locating each end of K̃_S's interval, at most
END_TOL = 0.02           # in ln K̃_S: an end between two points this close is located


def _vertex(u: npt.NDArray[np.float64], sse: npt.NDArray[np.float64]) -> float | None:
    """The minimum in u of the parabola through three points (None where it opens downwards),
    kept between the outer two."""
    a, b, _ = np.polyfit(u, sse, 2)
    return float(np.clip(-b / (2.0 * a), u[0], u[-1])) if a > 0 else None


def _at(s: Samples, radius_um: float, shear: float, near: Solved, table: ShellTable | None,
        powerlaw: PowerLawTable | None = None) -> Solved | None:
    """The fit at K̃_S `shear` from the fit `near` (a neighbour's): its q and correction,
    refreshed by at most PROFILE_SIMULATIONS simulations (`powerlaw_fit.correct`); None where
    the simulator finds no equilibrium (the point left out of the profile)."""
    try:
        return correct(s, radius_um, shear, near.q, correction=near.correction, table=table, cap=PROFILE_SIMULATIONS,
                       powerlaw=powerlaw)
    except SolverError:
        return None


def _profile(s: Samples, radius_um: float, drop: RampFit, table: ShellTable | None,
             powerlaw: PowerLawTable | None = None) -> tuple[dict[float, Solved], npt.NDArray[np.float64]]:
    """{K̃_S: the defect correction's fit there} over the nodes and the vertex (module doc; a
    node the simulator cannot run left out), and the surrogate's θ at the first node (on the
    shell ramp table `table`, None: the shipped one)."""
    nodes = [float(v) for v in np.geomspace(*SHEAR_RANGE, NODES)]
    first = int(np.argmin(np.abs(np.log(np.array(nodes) / SHEAR_TILDE))))
    done: dict[float, Solved] = {}
    done[nodes[first]], p = start(s, radius_um, nodes[first], drop, table, powerlaw)
    for way in (range(first + 1, NODES), range(first - 1, -1, -1)):
        near = done[nodes[first]]
        for k in way:
            fit = _at(s, radius_um, nodes[k], near, table, powerlaw)
            if fit is not None:
                done[nodes[k]] = near = fit
    have = [v for v in nodes if v in done]
    b = int(np.argmin([done[v].sse for v in have]))
    if 0 < b < len(have) - 1:
        u = np.log(have[b - 1:b + 2])
        top = _vertex(u, np.array([done[v].sse for v in have[b - 1:b + 2]]))
        if top is not None and np.min(np.abs(u - top)) > NEAR:
            fit = _at(s, radius_um, float(np.exp(top)), done[have[b]], table, powerlaw)
            if fit is not None:
                done[float(np.exp(top))] = fit
    return done, p


def _settle(s: Samples, radius_um: float, shear: float, fit: Solved, table: ShellTable | None,
            powerlaw: PowerLawTable | None = None) -> Solved:
    """A profile point's fit with its correction carried on to the tolerances (`powerlaw_fit.correct`;
    as it was where the simulator finds no equilibrium on the way)."""
    if fit.converged:
        return fit
    try:
        more = correct(s, radius_um, shear, fit.q, correction=fit.correction, table=table, powerlaw=powerlaw)
    except SolverError:
        return fit
    return replace(more, simulations=fit.simulations + more.simulations)


def _ends(s: Samples, radius_um: float, done: dict[float, Solved], sigma2: float, table: ShellTable | None,
          powerlaw: PowerLawTable | None = None) -> None:
    """Each end of K̃_S's interval located between the points of the profile `done` (module
    doc), the two points around it first settled; the fits added to `done`."""
    settled: set[float] = set()
    for side in (-1, 1):
        fits = 0
        while fits < END_FITS:
            shears = sorted(done)
            sse = np.array([done[v].sse for v in shears])
            z = np.sqrt(np.maximum(sse - sse.min(), 0.0) / sigma2) - np.sqrt(CHI2_95)
            b = int(np.argmin(sse))
            out = [k for k in range(b, len(shears) if side > 0 else -1, side) if z[k] > 0]
            if not out:
                break
            k, j = out[0], out[0] - side
            rough = [v for v in (shears[j], shears[k]) if not done[v].converged and v not in settled]
            if rough:
                for v in rough:
                    done[v] = _settle(s, radius_um, v, done[v], table, powerlaw)
                    settled.add(v)
                continue
            u_in, u_out = np.log(shears[j]), np.log(shears[k])
            if abs(u_out - u_in) < END_TOL:
                break
            u = float(u_in + (u_out - u_in) * -z[j] / (z[k] - z[j]))
            near = shears[j] if abs(u - u_in) <= abs(u - u_out) else shears[k]
            fit = _at(s, radius_um, float(np.exp(u)), done[near], table, powerlaw)
            if fit is None:
                break
            done[float(np.exp(u))] = _settle(s, radius_um, float(np.exp(u)), fit, table, powerlaw)
            fits += 1


def _best(s: Samples, radius_um: float, done: dict[float, Solved], p: npt.NDArray[np.float64],
          table: ShellTable | None, powerlaw: PowerLawTable | None = None) -> tuple[float, PowerLawFit]:
    """The best K̃_S of the profile `done` and the reading there (`powerlaw_fit.conclude`, σ²
    from the lowest SSE), its correction carried on to the tolerances first where its node's
    stopped short; its SSE in `done` lowered to the reading's (β's restart may fit better)."""
    shears = sorted(done)
    sse = np.array([done[v].sse for v in shears])
    b = int(np.argmin(sse))
    node = _settle(s, radius_um, shears[b], done[shears[b]], table, powerlaw)
    fit = conclude(s, radius_um, shears[b], node, p, float(np.min(np.delete(sse, b), initial=np.inf)),
                   profiled=1, table=table, powerlaw=powerlaw)
    done[shears[b]] = replace(node, sse=min(node.sse, fit.sse_nN2))
    return shears[b], fit


def fit_ramp_hold_profiled(time_s: npt.ArrayLike, x_um: npt.ArrayLike, force_nN: npt.ArrayLike,
                           ramp_samples: int, radius_um: float, hold: str = "height",
                           table: ShellTable | None = None, powerlaw: PowerLawTable | None = None) -> PowerLawFit:
    """`powerlaw_fit.fit_ramp_hold` with K̃_S unknown: the fit at the best K̃_S of the profile,
    with K̃_S's 95 % interval (`shear_band`) and γ_a's widened over it (module doc); the
    surrogate on the shell ramp table `table`, the tabled simulator on the power-law table
    `powerlaw` (None: the shipped ones)."""
    s, drop = prepare(time_s, x_um, force_nN, ramp_samples, radius_um, hold)
    done, p = _profile(s, radius_um, drop, table, powerlaw)
    best, fit = _best(s, radius_um, done, p, table, powerlaw)
    beta_runs = fit.simulations - done[best].simulations              # β's profile's (no hold)
    _ends(s, radius_um, done, fit.noise_nN ** 2, table, powerlaw)
    if min(done.values(), key=lambda v: v.sse).sse < done[best].sse:   # an end's fit found a better one
        best, fit = _best(s, radius_um, done, p, table, powerlaw)
        beta_runs += fit.simulations - done[best].simulations
        _ends(s, radius_um, done, fit.noise_nN ** 2, table, powerlaw)
    sigma2 = fit.noise_nN ** 2
    shears = sorted(done)
    sse = np.array([done[v].sse for v in shears])
    b = shears.index(best)
    tension = np.array([done[v].q[1] for v in shears])
    sd = np.array([sds(done[v], sigma2)[1] for v in shears])
    tension[b], sd[b] = fit.tension_mN_per_m, fit.tension_sd_mN_per_m
    shear_band, band = profile_bands(shears, np.maximum(sse - sse[b], 0.0) / sigma2, [(tension, sd)])
    lo, hi = fit.tension_interval_mN_per_m
    return replace(fit, shear_band=shear_band, tension_band_mN_per_m=(min(lo, band[0]), max(hi, band[1])),
                   simulations=sum(v.simulations for v in done.values()) + beta_runs)
