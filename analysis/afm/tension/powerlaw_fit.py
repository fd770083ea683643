"""γ_a, K_B(1 s) and β of one approach ramp and the hold after it, read as
one deformation-relaxation curve of the shell whose cortex relaxes as a power law
(SPEC 11-12; the elastic shell is its β = 0).

The model of the samples (t_i, x_i, F_i), δ_i = max(x0 - x_i, 0):

    F_i = F_b + s (x_i - x0) + F_pl(t_i, δ; R, γ_a, K_B(1 s), β, K̃_S),

F_pl the plate force of the time-domain shell along the recorded protocol
(`powerlaw_simulated`), K̃_S given (`shear_tilde`, default 1/3 as `shell_fit`; unknown:
profiled by `powerlaw_shear` with these fits).

Samples. The ramp's window is the droplet fit's (`ramp.fit_ramp`, depth capped at
0.3 R, the shell table's); its samples are averaged in runs of consecutive ones to at
most RAMP_POINTS, the hold's in HOLD_BINS bins log-spaced in the time since the hold
began; each mean is weighted by its count (residual sqrt(n_b) (model - mean)), so a
white noise of SD σ gives every weighted residual SD σ.

Fit, where the power-law table holds the recording (`powerlaw_tabled`: a ramp alone or with a
constant-height hold, every parameter within the table's axes): the least squares of the tabled
simulator in q = (x0, γ_a, K_B(1 s), β), (F_b, s) solved linearly at each q (variable
projection), from the starts of START_BULK × START_BETA, then TABLE_RESCUE_STARTS (K_B(1 s) =
k T, γ_a = T/2, T the droplet's tension), in turn until one fits as well as the baseline's noise
allows (`_misfit`), the best kept (`tabled_fit`, no simulation; SDs from its own Jacobian). Every later fit (β's and K̃_S's profiles) is the
tabled one where it stays inside, the defect correction below where it leaves the table
(`correct`). The table rests on a scaling the simulator keeps only approximately (its force at
v/R far from the table's ρ_0 is 0.1-0.3 % off on the hold, `powerlaw_grid`), and a hold pins
γ_a by the share of the force that does not relax, so a fit of the table alone reads γ_a up to
5 % off at zero noise. The reading's fit is therefore polished (`polished`): POLISH_SIMULATIONS
times one simulation at q gives the table's error c = F_sim(q) - F_tab(q) at the samples and q
is fitted again to F_tab + c. Its SDs are the tabled simulator's Jacobian's (c is constant).

Elsewhere (a constant-force hold; a fit outside the table's axes): defect correction (output
space mapping). The simulator is the model; the surrogate
(`powerlaw_shell`: the elastic shell's energy carried as one strain with Boltzmann
superposition; within a few per cent of the simulator, cheap) its proxy. First the surrogate
by least squares in θ = (x0, F_b, s, γ_a, K_B(1 s), β) from START_BULK × START_BETA (where the
simulator finds no equilibrium at its best, its next fit, then those from RESCUE_STARTS); then,
from q_0 its (x0, γ_a, K_B(1 s), β), at each step one simulation at q_k gives the correction

    c_k = F_sim(q_k) - F_sur(q_k)   (at the averaged samples),

and q_{k+1} is the least squares of the corrected surrogate F_sur(q) + c_k (no simulation;
(F_b, s) solved linearly at each q, variable projection), the next q mixed from the last
ANDERSON_MEMORY + 1 steps (Anderson); it stops when q moves less than REL_TOL in γ_a and
K_B(1 s), BETA_TOL in β and X0_TOL_UM in x0 (`converged`) or after SIMULATIONS. At the fixed
point J_sur^T r = 0 with r the simulator's residual: at zero noise the truth, with noise it
differs from the simulator's own least squares (`solve`, kept as the bench's reference) by
about (J_sur^T J_sur)^-1 (J_sim - J_sur)^T r. A constant-force hold's surrogate (the recorded
creep) and simulator (the held force) differ to first order, so there the correction is
c_k + D (q - q_k), D by forward differences at the first step (4 simulations) and updated by
Broyden's rank one after each. SDs from the simulator's own Jacobian at the fixed point
(`simulator_jacobian`: forward differences, one simulation a parameter and one at q; of the
projected residuals, whose normal matrix is the marginal one of the nonlinear parameters; the
corrected surrogate's misses the defect's slope), σ² = SSE/(n - 6); γ_a's 95 % interval
± Z95 sd. Without a hold β is profiled too:
at each β of PROFILE_BETAS (β fixed, K_B(1 s) started where K_B(1 s) T^-β at the ramp's contact
time T is the best fit's, the best fit's correction refreshed by at most PROFILE_SIMULATIONS
simulations), and γ_a's interval widened to hold every node's γ_a ± Z95 sd (β fixed) with
Δχ² = ΔSSE/σ² ≤ CHI2_95 (σ² from the lowest SSE); the best node, where it fits better,
restarts the fit from it.

What one ramp without a hold tells: for a pure power law at constant speed v the
cortex's force depends on K_B(1 s) and v only through K_B(1 s) v^β, and on β through
the curve's shape with depth alone; β and K_B(1 s) are then strongly correlated and
told apart only by that shape, while γ_a is pinned by the force's shallow part (its
interval the widest without a hold). The hold measures the relaxation itself, so β
and K_B(1 s) come apart.
"""

from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import numpy.typing as npt
from scipy.optimize import least_squares

from analysis.afm.tension import powerlaw_shell, powerlaw_simulated, powerlaw_tabled
from analysis.afm.tension.pause import Z95
from analysis.afm.tension.powerlaw_simulated import RampHold
from analysis.afm.tension.ramp import RampFit, baseline_noise, fit_ramp
from analysis.afm.tension.shell_fit import CHI2_95, SHEAR_TILDE
from analysis.calibration.powerlaw_table import PowerLawTable
from analysis.calibration.ramp_table import ShellTable
from analysis.mixing import mixed
from common.errors import InputError, SolverError

Array = npt.NDArray[np.float64]
RAMP_POINTS = 120
HOLD_BINS = 30
MAX_DEPTH = 0.3            # δ/R: the shell table's deepest
BETA_MAX = 0.6
START_BULK = (0.5, 5.0)    # K_B(1 s) / T of the surrogate's starts (T the droplet's)
START_BETA = (0.2,)
SURROGATE_EVALUATIONS = 300        # the surrogate's evaluations a start, at most
RESCUE_STARTS = ((0.5, 5.0, 30.0), (0.1, 0.25))    # the starts tried where the simulator cannot run the best
TABLE_RESCUE_STARTS = ((0.5, 5.0, 30.0), (0.05, 0.35))  # the tabled fit's, where its best misfits (`_misfit`)
MISFIT = 2.0               # a fit misfits whose SSE exceeds this times (n - 6) σ_0², σ_0 the baseline's noise
SIMULATIONS = 12           # the defect correction's simulations, at most
PROFILE_SIMULATIONS = 2    # ... at a profile's node, started from its neighbour's correction
REL_TOL = 1e-3             # q settled: γ_a and K_B(1 s) moved less than this share,
BETA_TOL = 1e-3            # β less than this,
X0_TOL_UM = 1e-3           # x0 less than this (µm)
ANDERSON_MEMORY = 2        # the iteration's earlier steps its mixing uses
FIRST_ORDER_HOLDS = ("force",)   # holds whose correction is carried to first order
SIM_XTOL = 1e-4            # the simulator's own least squares (`solve`, the reference):
SIM_STEP = 1e-3            # its relative finite-difference step
SIM_EVALUATIONS = 60
PROFILE_BETAS = (0.0, 0.1, 0.2, 0.3, 0.4, 0.5)     # β of the profile of a ramp without a hold
POLISH_SIMULATIONS = 1     # simulations taking the table's own error out of the reading's fit (`polished`)


@dataclass(frozen=True)
class Samples:
    """The fit's samples: means of runs of the recording's (times s, heights µm, forces nN),
    their counts, and how many are the ramp's; the raw samples they average (`raw_time_s`,
    `raw_x_um`, the ramp's first `raw_ramp` of them) and the runs' bounds in them (`edges`)."""

    time_s: Array
    x_um: Array
    force_nN: Array
    count: Array
    ramp_points: int
    raw_time_s: Array
    raw_x_um: Array
    raw_ramp: int
    edges: npt.NDArray[np.int64]
    hold: str = "height"
    baseline_noise_nN: float = float("nan")

    @property
    def history(self) -> RampHold:
        """The raw samples' history (`powerlaw_simulated`)."""
        return RampHold(self.raw_time_s, self.raw_x_um, self.raw_ramp, self.hold)

    def averaged(self, raw: Array) -> Array:
        """Means of a quantity at the raw samples over the runs."""
        return np.add.reduceat(raw, self.edges[:-1]) / self.count


@dataclass(frozen=True)
class PowerLawFit:
    """The fitted power-law shell: γ_a (mN/m), K_B(1 s) (mN/m), β with their SDs and γ_a's
    95 % interval; contact x0 (µm), baseline F_b (nN) and slope s (nN/µm), K̃_S used, the
    noise SD σ (nN), the samples fitted (`Samples`), whether a hold was fitted, the
    surrogate's own γ_a, K_B(1 s), β (the simulator's start; tabled: the table's own fit before
    its polish), without a hold γ_a's band over β's profile (`tension_band_mN_per_m`, module doc;
    with K̃_S profiled also over it, `powerlaw_shear`), the fit's SSE (nN²), K̃_S's 95 % interval
    where profiled, the simulations the reading ran (all its fits), whether its best fit's q
    settled and whether it read the power-law table (`tabled`)."""

    tension_mN_per_m: float
    tension_sd_mN_per_m: float
    bulk_1s_mN_per_m: float
    bulk_1s_sd_mN_per_m: float
    beta: float
    beta_sd: float
    contact_um: float
    baseline_nN: float
    baseline_slope_nN_per_um: float
    shear_tilde: float
    noise_nN: float
    samples: Samples
    hold: bool
    surrogate: tuple[float, float, float]
    tension_band_mN_per_m: tuple[float, float] | None = None
    sse_nN2: float = float("nan")
    shear_band: tuple[float, float] | None = None
    simulations: int = 0
    converged: bool = True
    tabled: bool = False

    @property
    def tension_interval_mN_per_m(self) -> tuple[float, float]:
        """γ_a ± Z95 sd (the lower end at least 0), widened to the band over β where profiled."""
        half = Z95 * self.tension_sd_mN_per_m
        lo, hi = max(self.tension_mN_per_m - half, 0.0), self.tension_mN_per_m + half
        if self.tension_band_mN_per_m is not None:
            lo, hi = min(lo, self.tension_band_mN_per_m[0]), max(hi, self.tension_band_mN_per_m[1])
        return lo, hi


def samples(time_s: npt.ArrayLike, x_um: npt.ArrayLike, force_nN: npt.ArrayLike, ramp_samples: int,
            window: npt.NDArray[np.bool_], hold: str = "height") -> Samples:
    """The fit's samples (module doc) from the ramp's window (a mask on its samples, which
    runs to the ramp's end) and the hold."""
    t, x, f = (np.asarray(a, float) for a in (time_s, x_um, force_nN))
    first = int(np.nonzero(window)[0][0])
    t, x, f = t[first:], x[first:], f[first:]
    n = ramp_samples - first
    edges = np.unique(np.linspace(0, n, min(n, RAMP_POINTS) + 1).round().astype(int))
    ramp_points = edges.size - 1
    if t.size > n:
        since = t[n:] - t[n - 1]
        bounds = np.geomspace(max(since[0], 1e-6), since[-1] * (1 + 1e-9), HOLD_BINS + 1)
        edges = np.unique(np.r_[edges, n + np.searchsorted(since, bounds[1:-1]), t.size])
    count = np.diff(edges).astype(float)
    mean = [np.add.reduceat(a, edges[:-1]) / count for a in (t, x, f)]
    return Samples(mean[0], mean[1], mean[2], count, ramp_points, t, x, n, edges, hold)


def _surrogate(s: Samples, radius: float, shear: float, p: Array, table: ShellTable | None = None) -> Array:
    """Weighted residuals of the surrogate at θ = (x0, F_b, s, γ_a, K_B(1 s), β) on the shell ramp
    table `table` (None: the shipped one)."""
    model = p[1] + p[2] * (s.x_um - p[0]) + powerlaw_shell.force_nN(s.time_s, p[0] - s.x_um, radius, p[3], p[4],
                                                                    p[5], shear, table)
    return np.sqrt(s.count) * (model - s.force_nN)


def surrogate_fits(s: Samples, radius: float, shear: float, x0: float, droplet_tension: float,
                   table: ShellTable | None = None,
                   starts: tuple[tuple[float, ...], tuple[float, ...]] = (START_BULK, START_BETA)) -> list[Array]:
    """θ of the surrogate's fit from each start (K_B(1 s)/T of starts[0] × β of starts[1]; module
    doc), the best first, on the shell ramp table `table`."""
    lo = [-np.inf, -np.inf, -np.inf, 1e-4, 1e-3, 0.0]
    hi = [np.inf, np.inf, np.inf, np.inf, np.inf, BETA_MAX]
    found = []
    for kb in starts[0]:
        for beta in starts[1]:
            p0 = np.array([x0, 0.0, 0.0, 0.5 * droplet_tension, kb * droplet_tension, beta])
            scale = [0.01, 0.01, 0.01, max(droplet_tension, 1e-3), max(kb * droplet_tension, 1e-2), 0.05]
            res = least_squares(lambda p: _surrogate(s, radius, shear, p, table), p0, bounds=(lo, hi), x_scale=scale,
                                xtol=1e-10, ftol=1e-10, max_nfev=SURROGATE_EVALUATIONS)
            if np.isfinite(res.cost):
                found.append((float(res.cost), res.x))
    if not found:
        raise InputError("approach ramp: no rise the power-law shell can fit")
    return [x for _, x in sorted(found, key=lambda c: c[0])]


def _simulated(s: Samples, radius: float, shear: float, q: Array) -> Array:
    """The simulator's force (nN) at q = (x0, γ_a, K_B(1 s), β), averaged as the samples."""
    return s.averaged(powerlaw_simulated.force_nN(s.history, q[0], radius, q[1], q[2], q[3], shear))


def _surrogate_force(s: Samples, radius: float, shear: float, q: Array, table: ShellTable | None) -> Array:
    """The surrogate's force (nN) at q = (x0, γ_a, K_B(1 s), β) at the samples."""
    return powerlaw_shell.force_nN(s.time_s, q[0] - s.x_um, radius, q[1], q[2], q[3], shear, table)


@dataclass(frozen=True)
class Correction:
    """The simulator's force less the surrogate's (`tabled`: less the tabled simulator's) at the
    samples (nN): `offset` at q = `at` (x0, γ_a, K_B(1 s), β), to first order `slope` (n × 4;
    zero: the defect correction's constant one): c(q) = offset + slope (q - at) (module doc)."""

    offset: Array
    slope: Array
    at: Array
    tabled: bool = False

    def __call__(self, q: Array) -> Array:
        return self.offset + self.slope @ (q - self.at)


def _scale(q: Array) -> Array:
    """The scales of (x0, γ_a, K_B(1 s), β) near q (µm, mN/m, mN/m, 1)."""
    return np.array([0.01, max(abs(q[1]), 1e-3), max(abs(q[2]), 1e-2), 0.05])


class _Projected:
    """Residuals at (x0, γ_a, K_B(1 s), β) of a model force with (F_b, s) solved linearly:
    the tabled simulator's (`tabled`), else the simulator's (`correction` None) or the surrogate's
    plus `correction` (module doc);
    `beta` fixes β (then q = (x0, γ_a, K_B(1 s))); `strict`: a simulation without an equilibrium
    raises (else every residual is 1e3, which the least squares steps away from)."""

    def __init__(self, s: Samples, radius: float, shear: float, beta: float | None = None,
                 correction: Correction | None = None, table: ShellTable | None = None, strict: bool = False,
                 tabled: powerlaw_tabled.TabledForce | None = None):
        self.s, self.radius, self.shear, self.w, self.beta = s, radius, shear, np.sqrt(s.count), beta
        self.correction, self.table, self.strict, self.tabled = correction, table, strict, tabled
        self.linear = np.zeros(2)

    def full(self, q: Array) -> Array:
        """(x0, γ_a, K_B(1 s), β) of the free parameters q."""
        return np.asarray(q, float) if self.beta is None else np.append(q, self.beta)

    def __call__(self, q: Array) -> Array:
        s = self.s
        if self.tabled is not None or self.correction is None:
            try:
                model = (_simulated(s, self.radius, self.shear, self.full(q)) if self.tabled is None
                         else s.averaged(self.tabled(self.full(q))))
                if self.tabled is not None and self.correction is not None:
                    model = model + self.correction(self.full(q))
            except (SolverError, InputError):
                if self.strict:
                    raise
                return np.full(s.time_s.size, 1e3)
        else:
            full = self.full(q)
            model = _surrogate_force(s, self.radius, self.shear, full, self.table) + self.correction(full)
        a = self.w[:, None] * np.stack([np.ones_like(model), s.x_um - q[0]], axis=1)
        coef, *_ = np.linalg.lstsq(a, self.w * (s.force_nN - model), rcond=None)
        self.linear = coef
        return self.w * (model + coef[0] + coef[1] * (s.x_um - q[0]) - s.force_nN)


@dataclass(frozen=True)
class Solved:
    """One fit: its parameters (x0, γ_a, K_B(1 s)[, β]), SSE, Jacobian, (F_b, s); of the
    defect correction also its last correction (nN at the samples), the simulations it ran and
    whether q settled within the tolerances (module doc)."""

    q: Array
    sse: float
    jac: Array
    linear: Array
    correction: Correction | None = None
    simulations: int = 0
    converged: bool = True
    tabled: bool = False


def _least_squares(resid: _Projected, q0: Array, **options: Any) -> Solved:
    """`resid`'s least squares in its free parameters from q0, within the parameters' bounds (in
    the parameters' scales unless `x_scale` is given)."""
    q0 = np.asarray(q0, float)[:3 if resid.beta is not None else 4]
    lo, hi = [-np.inf, 1e-4, 1e-3, 0.0], [np.inf, np.inf, np.inf, BETA_MAX]
    k = q0.size
    options.setdefault("x_scale", _scale(resid.full(q0))[:k])
    res = least_squares(resid, np.clip(q0, lo[:k], hi[:k]), bounds=(lo[:k], hi[:k]), **options)
    r = resid(res.x)
    return Solved(res.x, float(r @ r), res.jac, resid.linear.copy(), resid.correction)


def solve(s: Samples, radius: float, shear: float, q0: Array, beta: float | None = None) -> Solved:
    """The simulator's own least squares from q0 by finite differences (up to SIM_EVALUATIONS
    simulations), β free or fixed at `beta`: the reference the defect correction is checked
    against (bench/powerlaw_ramp_hold.py)."""
    fit = _least_squares(_Projected(s, radius, shear, beta), q0, diff_step=SIM_STEP, xtol=SIM_XTOL, ftol=1e-8,
                         max_nfev=SIM_EVALUATIONS)
    return Solved(fit.q, fit.sse, fit.jac, fit.linear, None, SIM_EVALUATIONS, True)


def _settled(new: Array, old: Array) -> bool:
    """Whether q moved less than the tolerances (module doc)."""
    step = np.abs(new - old)
    return bool(step[0] <= X0_TOL_UM and np.all(step[1:3] <= REL_TOL * np.abs(old[1:3]))
                and (step.size < 4 or step[3] <= BETA_TOL))


def _anderson(inputs: list[Array], outputs: list[Array], lo: Array, hi: Array) -> Array:
    """The next q of the fixed-point iteration q → G(q) from its last ANDERSON_MEMORY + 1
    (input, output) pairs by Anderson's mixing (in the parameters' scales), within [lo, hi]."""
    if len(outputs) < 2:
        return outputs[-1]
    scale = _scale(outputs[-1])[:len(outputs[-1])]
    return np.clip(mixed(np.array(inputs) / scale, np.array(outputs) / scale, ANDERSON_MEMORY) * scale, lo, hi)


def _defect(s: Samples, radius: float, shear: float, full: Array, table: ShellTable | None) -> Array:
    """The simulator's force less the surrogate's (nN) at the samples at (x0, γ_a, K_B(1 s), β)."""
    return _simulated(s, radius, shear, full) - _surrogate_force(s, radius, shear, full, table)


def _slope(s: Samples, radius: float, shear: float, full: Array, offset: Array, free: int,
           table: ShellTable | None) -> Array:
    """d(simulator − surrogate)/dq at `full` by forward differences (SIM_STEP relative) in the
    first `free` parameters (n × 4, the rest zero): `free` simulations."""
    slope = np.zeros((offset.size, 4))
    for i in range(free):
        h = SIM_STEP * max(abs(full[i]), _scale(full)[i])
        slope[:, i] = (_defect(s, radius, shear, full + h * np.eye(4)[i], table) - offset) / h
    return slope


def _broyden(slope: Array, miss: Array, step: Array, scale: Array) -> Array:
    """The slope updated by Broyden's rank one so that it carries the last step's change of the
    correction (`miss`: the change less the slope's prediction), in the parameters' `scale`."""
    w = step / scale ** 2
    return slope + np.outer(miss, w) / (step @ w) if step @ w > 0 else slope


def tabled_fit(s: Samples, radius: float, shear: float, q0: Array, beta: float | None = None,
               powerlaw: PowerLawTable | None = None, correction: Correction | None = None) -> Solved | None:
    """The least squares of the tabled simulator (`powerlaw_tabled`) on the power-law table
    `powerlaw` (None: the shipped one), plus `correction` where it is the table's (`polished`: a
    neighbour's, carried), from q0, β free or fixed at `beta`; None where the hold is not one it
    holds or the fit ends outside it (the caller then simulates)."""
    if s.raw_time_s.size > s.raw_ramp and s.hold != "height":
        return None
    table = powerlaw_tabled.resolve(powerlaw)
    force = powerlaw_tabled.TabledForce(s.history, radius, shear, table)
    carried = correction if correction is not None and correction.tabled else None
    resid = _Projected(s, radius, shear, beta, carried, tabled=force)
    fit = _least_squares(resid, q0, xtol=1e-10, ftol=1e-10, x_scale="jac")
    resid(fit.q)                                   # `interior` of the fit itself
    if not force.interior:
        return None
    return replace(fit, tabled=True, converged=True, correction=carried)


def polished(s: Samples, radius: float, shear: float, fit: Solved, powerlaw: PowerLawTable | None = None,
             runs: int | None = None) -> Solved:
    """A tabled fit (β free) with the table's own error taken out (module doc): at most `runs` times
    one simulation at q, c = F_sim(q) - F_tab(q), and the least squares of F_tab + c from q; the fit
    as it was where it is not tabled or carries the table's correction already, and as it was
    last where a simulation fails or the refit leaves the table. The correction stays with the fit
    (`Correction.tabled`): its neighbours in β's and K̃_S's profiles are fitted with it."""
    runs = POLISH_SIMULATIONS if runs is None else runs
    if not fit.tabled or runs < 1 or fit.q.size != 4 or fit.correction is not None:
        return fit
    force = powerlaw_tabled.TabledForce(s.history, radius, shear, powerlaw_tabled.resolve(powerlaw))
    done = 0
    for _ in range(runs):
        try:
            c = _simulated(s, radius, shear, fit.q) - s.averaged(force(fit.q))
        except (SolverError, InputError):
            break
        done += 1
        carried = Correction(c, np.zeros((c.size, 4)), fit.q, tabled=True)
        resid = _Projected(s, radius, shear, None, carried, tabled=force)
        again = _least_squares(resid, fit.q, xtol=1e-10, ftol=1e-10, x_scale="jac")
        resid(again.q)
        if not force.interior:
            break
        fit = replace(again, tabled=True, converged=True, correction=carried)
    return replace(fit, simulations=fit.simulations + done)


def correct(s: Samples, radius: float, shear: float, q0: Array, beta: float | None = None,
            correction: Correction | None = None, table: ShellTable | None = None,
            cap: int = SIMULATIONS, powerlaw: PowerLawTable | None = None) -> Solved:
    """The tabled simulator's fit from q0 where the power-law table holds it (`tabled_fit`), else
    the defect correction from q0 (module doc), β free or fixed at `beta`: the corrected
    surrogate fitted first with `correction` where given (a neighbour's; none: q0 is the
    surrogate's own fit), then at most `cap` simulations, each refreshing the correction's
    offset at the current q (a constant-force hold: to first order, its slope made once, or
    the neighbour's kept); the surrogate on the shell ramp table `table`, the tabled simulator on
    the power-law table `powerlaw` (None: the shipped ones)."""
    fast = tabled_fit(s, radius, shear, np.asarray(q0, float)[:3 if beta is not None else 4], beta, powerlaw,
                      correction)
    if fast is not None:
        return fast
    if correction is not None and correction.tabled:
        correction = None                           # the table's, not the surrogate's: q0 starts afresh
    q = start = np.asarray(q0, float)[:3 if beta is not None else 4]
    k = q.size
    lo, hi = np.array([-np.inf, 1e-4, 1e-3, 0.0])[:k], np.array([np.inf, np.inf, np.inf, BETA_MAX])[:k]
    fit = None
    if correction is not None:
        fit = _least_squares(_Projected(s, radius, shear, beta, correction, table), q, xtol=1e-10, ftol=1e-10)
        q = fit.q
    slope = None if correction is None else correction.slope
    if slope is None and not (s.hold in FIRST_ORDER_HOLDS and s.raw_time_s.size > s.raw_ramp):
        slope = np.zeros((s.time_s.size, 4))
    good: Array | None = None
    previous = Correction(np.zeros(0), np.zeros((0, 4)), np.zeros(4))
    inputs: list[Array] = []
    outputs: list[Array] = []
    extra = 0
    for run in range(1, cap + 1):
        full = q if beta is None else np.append(q, beta)
        try:
            c = _defect(s, radius, shear, full, table)
            if slope is None:
                slope, extra = _slope(s, radius, shear, full, c, k, table), k
        except (SolverError, InputError):
            if good is None and q is start:
                raise SolverError("the simulator finds no equilibrium at the surrogate's fit") from None
            q = start if good is None else 0.5 * (q + good)     # back towards q0, or the last q simulated
            inputs, outputs = [], []
            continue
        if good is not None and extra:
            slope = _broyden(slope, c - previous(full), full - previous.at, _scale(full))
        good, previous = q, Correction(c, slope, full)
        fit = _least_squares(_Projected(s, radius, shear, beta, previous, table), q, xtol=1e-10, ftol=1e-10)
        if _settled(fit.q, q):
            return replace(fit, simulations=run + extra, converged=True)
        inputs.append(q)
        outputs.append(fit.q)
        q = _anderson(inputs, outputs, lo, hi)
    assert fit is not None
    return replace(fit, simulations=cap + extra, converged=False)


def _rescaled_bulk(q: Array, beta: float, s: Samples) -> float:
    """K_B(1 s) at exponent `beta` with the same modulus K_B(1 s) T^-β at the ramp's contact
    time T as q's: a start for the profile (module doc)."""
    span = max(float(s.time_s[s.ramp_points - 1] - s.time_s[0]), 1e-3)
    return float(q[2] * span ** (beta - q[3]))


def _beta_profile(s: Samples, radius: float, shear: float, best: Solved, table: ShellTable | None,
                  powerlaw: PowerLawTable | None = None) -> list[tuple[float, Solved]]:
    """[(β, the fit at β fixed)] at each β of PROFILE_BETAS, each from `best`'s correction (module
    doc); a β where the simulator finds no equilibrium left out."""
    nodes = []
    for beta in PROFILE_BETAS:
        try:
            nodes.append((beta, correct(s, radius, shear, np.array([best.q[0], best.q[1],
                                                                    _rescaled_bulk(best.q, beta, s)]),
                                        beta, best.correction, table, PROFILE_SIMULATIONS, powerlaw)))
        except SolverError:
            continue                    # the simulator finds no equilibrium there: β left out
    return nodes


def sds(fit: Solved, sigma2: float) -> Array:
    """The SDs of a fit's free parameters from its Jacobian."""
    return np.sqrt(np.clip(np.diag(sigma2 * np.linalg.pinv(fit.jac.T @ fit.jac)), 0.0, None))


def simulator_jacobian(s: Samples, radius: float, shear: float, fit: Solved) -> Solved:
    """`fit` with the Jacobian of the simulator's own projected residuals at its q, by forward
    differences (SIM_STEP relative; one simulation a free parameter and one at q): the SDs of
    the reading (the corrected surrogate's Jacobian misses the defect's slope; its γ_a SD was
    0.55-0.91 × this one's with a hold). Where a step finds no equilibrium, `fit` as it was
    (q.size + 1 simulations either way). A tabled fit as it is: its Jacobian is the tabled
    simulator's."""
    if fit.tabled:
        return fit
    resid = _Projected(s, radius, shear, strict=True)
    q = np.asarray(fit.q, float)
    try:
        r0 = resid(q)
        jac = np.empty((r0.size, q.size))
        for i in range(q.size):
            h = SIM_STEP * max(abs(q[i]), _scale(q)[i])
            jac[:, i] = (resid(q + h * np.eye(q.size)[i]) - r0) / h
    except (SolverError, InputError):
        return fit
    return replace(fit, jac=jac)


def prepare(time_s: npt.ArrayLike, x_um: npt.ArrayLike, force_nN: npt.ArrayLike, ramp_samples: int,
            radius_um: float, hold: str = "height") -> tuple[Samples, RampFit]:
    """The fit's samples (`samples`) and the droplet's fit of the ramp (its window and the starts)."""
    t, x, f = (np.asarray(a, float) for a in (time_s, x_um, force_nN))
    if not (t.shape == x.shape == f.shape) or not 2 <= ramp_samples <= t.size:
        raise InputError("a ramp and hold needs times, heights and forces of one length and a ramp")
    drop = fit_ramp(x[:ramp_samples], f[:ramp_samples], radius_um, "droplet", cap_um=MAX_DEPTH * radius_um)
    s = samples(t, x, f, ramp_samples, drop.window, hold)
    return replace(s, baseline_noise_nN=baseline_noise(f[:ramp_samples])[1]), drop


def start(s: Samples, radius_um: float, shear: float, drop: RampFit, table: ShellTable | None = None,
          powerlaw: PowerLawTable | None = None) -> tuple[Solved, Array]:
    """The fit at K̃_S `shear` and its start's θ: the tabled simulator's from the starts of
    START_BULK × START_BETA, then TABLE_RESCUE_STARTS, in turn until one does not misfit, the best
    kept, where the power-law table `powerlaw` holds it (`tabled_fit`), polished (`polished`); else the defect correction's
    from the surrogate's best (on the shell ramp table `table`, None: the shipped one) and, with a
    hold the table does not hold, from the tabled fit of the ramp alone (`_ramp_start`), the lower
    SSE kept. Where the simulator finds no equilibrium at the surrogate's best (a droplet-like
    valley, K_B(1 s) near γ_a), from its next best fit, then from those of the RESCUE_STARTS."""
    fits: list[Solved] = []
    for kb, beta in [(k, b) for bulks, betas in ((START_BULK, START_BETA), TABLE_RESCUE_STARTS)
                     for k in bulks for b in betas]:
        fit = tabled_fit(s, radius_um, shear, _tabled_q0(drop, kb, beta), None, powerlaw)
        fits += [] if fit is None else [fit]
        if fits and not _misfit(s, min(f.sse for f in fits)):
            break                                   # a start that fits as well as the noise allows
    if fits:
        best = min(fits, key=lambda f: f.sse)
        return polished(s, radius_um, shear, best, powerlaw), np.r_[best.q[0], best.linear, best.q[1:]]
    ramp = _ramp_start(s, radius_um, shear, drop, powerlaw)
    from_ramp = None
    if ramp is not None:
        try:
            from_ramp = correct(s, radius_um, shear, ramp.q, table=table, powerlaw=powerlaw)
        except SolverError:
            pass
    for starts in ((START_BULK, START_BETA), RESCUE_STARTS):
        for p in surrogate_fits(s, radius_um, shear, drop.contact_um, drop.tension_mN_per_m, table, starts):
            try:
                fit = correct(s, radius_um, shear, p[[0, 3, 4, 5]], table=table, powerlaw=powerlaw)
            except SolverError:
                continue
            if from_ramp is not None and from_ramp.sse < fit.sse:
                return replace(from_ramp, simulations=from_ramp.simulations + fit.simulations), p
            return replace(fit, simulations=fit.simulations + (0 if from_ramp is None else from_ramp.simulations)), p
    if from_ramp is not None and ramp is not None:
        return from_ramp, np.r_[ramp.q[0], ramp.linear, ramp.q[1:]]
    raise SolverError("the simulator finds no equilibrium at any of the surrogate's fits")


def _tabled_q0(drop: RampFit, bulk_per_tension: float, beta: float) -> Array:
    """A start q0 = (x0, γ_a, K_B(1 s), β) of the tabled fit from the droplet's fit `drop`: x0 its
    contact, γ_a half its tension T, K_B(1 s) = `bulk_per_tension` T."""
    return np.array([drop.contact_um, 0.5 * drop.tension_mN_per_m, bulk_per_tension * drop.tension_mN_per_m, beta])


def _ramp_start(s: Samples, radius_um: float, shear: float, drop: RampFit,
                powerlaw: PowerLawTable | None) -> Solved | None:
    """The tabled simulator's fit of the recording's ramp alone (its runs before the hold), a start
    for the defect correction of a hold the table does not hold (a constant-force one); None where
    there is no such hold or the table does not hold the ramp."""
    if s.raw_time_s.size == s.raw_ramp:
        return None
    k = s.ramp_points
    alone = replace(s, time_s=s.time_s[:k], x_um=s.x_um[:k], force_nN=s.force_nN[:k], count=s.count[:k],
                    raw_time_s=s.raw_time_s[:s.raw_ramp], raw_x_um=s.raw_x_um[:s.raw_ramp], edges=s.edges[:k + 1],
                    hold="height")
    fits = [f for f in (tabled_fit(alone, radius_um, shear, _tabled_q0(drop, kb, beta), None, powerlaw)
                        for kb in START_BULK for beta in START_BETA) if f is not None]
    return min(fits, key=lambda f: f.sse) if fits else None


def _misfit(s: Samples, sse: float) -> bool:
    """Whether a fit's SSE exceeds MISFIT times what the baseline's noise σ_0 leaves, (n - 6) σ_0²
    (a start that ended in another valley, e.g. the droplet's at the table's edge; a fit of the
    right model leaves 1 ± sqrt(2/n) of it)."""
    return bool(sse > MISFIT * max(s.time_s.size - 6, 1) * s.baseline_noise_nN ** 2)


def conclude(s: Samples, radius_um: float, shear: float, best: Solved, surrogate: Array,
             other_sse: float = np.inf, profiled: int = 0, table: ShellTable | None = None,
             powerlaw: PowerLawTable | None = None) -> PowerLawFit:
    """The fit from the defect correction's `best` at K̃_S `shear`: without a hold β's profile
    (module doc), σ² from the lowest SSE (also `other_sse`, of fits elsewhere) over n - 6 -
    `profiled` (the parameters profiled besides), the SDs and γ_a's band over β's nodes, the
    simulations of `best` and β's profile counted; the surrogate on the table `table`, the
    tabled simulator on `powerlaw`."""
    held = s.raw_time_s.size > s.raw_ramp
    nodes = [] if held else _beta_profile(s, radius_um, shear, best, table, powerlaw)
    runs = best.simulations + sum(n.simulations for _, n in nodes)
    if nodes:
        beta, node = min(nodes, key=lambda n: n[1].sse)
        if node.sse < best.sse:
            again = correct(s, radius_um, shear, np.append(node.q, beta), correction=node.correction, table=table,
                            powerlaw=powerlaw)
            runs += again.simulations
            best = again if again.sse < best.sse else best
    sse_min = min([best.sse, other_sse] + [n.sse for _, n in nodes])
    sigma2 = sse_min / max(s.time_s.size - 6 - profiled, 1)
    before = best.simulations
    best = polished(s, radius_um, shear, best, powerlaw)
    runs += best.simulations - before
    best = simulator_jacobian(s, radius_um, shear, best)
    runs += 0 if best.tabled else best.q.size + 1
    sd = sds(best, sigma2)
    q = best.q
    band = None
    if nodes:
        inside = [(n.q[1], sds(n, sigma2)[1]) for _, n in nodes if (n.sse - sse_min) / sigma2 <= CHI2_95]
        band = (max(min([q[1] - Z95 * sd[1]] + [g - Z95 * e for g, e in inside]), 0.0),
                max([q[1] + Z95 * sd[1]] + [g + Z95 * e for g, e in inside]))
    return PowerLawFit(tension_mN_per_m=float(q[1]), tension_sd_mN_per_m=float(sd[1]),
                       bulk_1s_mN_per_m=float(q[2]), bulk_1s_sd_mN_per_m=float(sd[2]), beta=float(q[3]),
                       beta_sd=float(sd[3]), contact_um=float(q[0]), baseline_nN=float(best.linear[0]),
                       baseline_slope_nN_per_um=float(best.linear[1]), shear_tilde=shear,
                       noise_nN=float(np.sqrt(sigma2)), samples=s, hold=held,
                       surrogate=(float(surrogate[3]), float(surrogate[4]), float(surrogate[5])),
                       tension_band_mN_per_m=None if band is None else (float(band[0]), float(band[1])),
                       sse_nN2=best.sse, simulations=runs, converged=best.converged, tabled=best.tabled)


def fit_ramp_hold(time_s: npt.ArrayLike, x_um: npt.ArrayLike, force_nN: npt.ArrayLike, ramp_samples: int,
                  radius_um: float, shear_tilde: float = SHEAR_TILDE, hold: str = "height",
                  table: ShellTable | None = None, powerlaw: PowerLawTable | None = None) -> PowerLawFit:
    """The power-law shell fitted to a ramp (the first `ramp_samples` samples, ending at its
    deepest) and the hold after it (the rest; none: the ramp alone) at constant `hold`
    ("height" or "force"), K̃_S `shear_tilde` given (`powerlaw_shear`: profiled); the surrogate
    on the shell ramp table `table`, the tabled simulator on the power-law table `powerlaw` (None:
    the shipped ones)."""
    s, drop = prepare(time_s, x_um, force_nN, ramp_samples, radius_um, hold)
    best, p = start(s, radius_um, shear_tilde, drop, table, powerlaw)
    return conclude(s, radius_um, shear_tilde, best, p, table=table, powerlaw=powerlaw)
