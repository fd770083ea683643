"""A protocol simulated in time on the shell with a viscoelastic cortex (SPEC 6, 11 and 12).

`simulate(shell, cortex, protocol, resolution, sampling)` runs a `solver.protocol.Protocol` on
`solver.time_domain.TimeShell` from the stress-free droplet at the protocol's start (the shell's
h0 is set to it) and returns the instrument's samples: every equilibrium one step of the fast
solver, every step through `_advance` (`TimeShell.advance`: sub-steps of its own choice, each one
equilibrium, a failed one undone and halved).

How each step is stepped (`Resolution`; FINE for the synthetic experiments, LINEARISED for the
protocol-aware reading's replay of a recording, `analysis.afm.replayed`, REPLAY for its full
replay, the held-out check):

- a ramp moves the plate at most `ramp_step_um` a step, linear in time at its speed; a ramp to a
  force stops at the step where the force crosses it, that step's gap found by regula falsi;
- a hold grows its steps from `hold_first_s` (FINE: 1/`sample_hz`) by `hold_growth` up
  to `hold_largest_s`; consecutive height holds are one hold. A constant-force hold finds at
  every step the gap whose force is the hold's (a secant from the creep the last step predicts,
  with its slope dF/dh, else bracketed and Brent on h: `_at_force`);
- an oscillation takes `steps_per_period` steps a period. FINE: over all its periods, with
  steps doubling from one sample interval up to the first (the plate's speed jumps at its start
  and the fast Maxwell elements answer within their τ), the force splined to the samples (cubic,
  not-a-knot: an error ~ (5/384) (2π/64)^4 of the force's amplitude, 1e-6). REPLAY: at most
  `max_periods` periods, the steps themselves the samples, then the plate held at h_m for the
  rest; where a step fails even halved, the whole protocol again with `retry_finer` times finer
  ramps and oscillations.

LINEARISED (`linearised`): a hold is one step (the Prony series' exponential integrator is
exact for a strain constant in time, and a hold's strain barely moves; `hold_first_s` inf), except
a wait (a height hold after a ramp), stepped from `wait_first_s` (1 s) doubling to 16 s so that
`Recording.waits` holds its relaxation (the cortex's memory read from it,
`analysis.afm.wait_relaxation`), and
an oscillation is not stepped: the plate is held at h_m through it, and halfway through, the
state answers at f in the frequency domain (`solver.state_response`: K*_lin about the state with
the cortex's complex moduli; an `Answer` in `Recording.answers`, no samples). Ramps are stepped
as REPLAY steps them. Against REPLAY and FINE: bench/linearised_replay.py.

REPLAY against FINE, read with the true cortex by the segment fit, on two cells of 33 and 18
segments: |K*| within 1.6 % (0.8 % on average), loss angle within 0.014 rad
(`tests/test_protocol_replay.py` checks a small cell); it takes ~1700 steps for a cell of 11
heights at three frequencies, 3 ms a step.

Sampling (`Sampling`): oscillations at `sample_hz` (or `min_samples_per_period` a period where
that is finer), the ramps and holds between at `approach_hz` (linear between steps, the last
sample at their end), the protocol's start the first sample (the reference droplet: its force
the tension's, F_a = 2 γ_a H A_c at (V, h0)). `Recording.stretches` say which
samples are a ramp, a hold or an oscillation (at which f); `Recording.waits` the steps
themselves of every wait (a height hold between a ramp and what follows it): their end times (s)
and forces (nN), the wait's start first.

`contact_history`: the stored history's share of dE/dl in the contact line's balance
(`solver.time_domain.TimeShell`; on by default, False holds the history per element in the
search). LINEARISED's answers linearise the balance the state's step solved
(`solver.state_response`).

`history` "relaxed": every ramp to a height after the first starts from its own relaxed droplet,
the first ramp's depth above its target (a fresh `TimeShell`: no stress from earlier steps, the
assumption of the published relaxed-state reading); "carried" (default): one cortex history.
"""

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np
import numpy.typing as npt
from scipy.interpolate import CubicSpline
from scipy.optimize import root_scalar

from common.errors import InputError, SolverError
from common.names import CORTEX_HISTORIES
from solver.model import Shell
from solver.protocol import Hold, Oscillate, Protocol, Ramp
from solver.time_domain import Cortex, TimeShell

Array = npt.NDArray[np.float64]
FORCE_TOL_UM = 1e-6       # µm: the gap of a constant-force step, to this
SECANT_STEPS = 6          # secant steps a constant-force step tries before it brackets


@dataclass(frozen=True)
class Resolution:
    """How finely a protocol is stepped (module docstring)."""

    ramp_step_um: float
    hold_first_s: float | None        # None: 1/sample_hz
    hold_growth: float
    hold_largest_s: float
    steps_per_period: int
    max_periods: int | None = None    # None: every period
    spline: bool = True               # False: the oscillation's steps are its samples
    retry_finer: int = 1              # > 1: a failed run again, this many times finer
    linearised: bool = False          # True: oscillations answered about the state, not stepped
    wait_first_s: float | None = None  # a wait's first step (s), doubling to WAIT_LARGEST_S; None: as a hold

    def finer(self, factor: int) -> "Resolution":
        return replace(self, ramp_step_um=self.ramp_step_um / factor,
                       steps_per_period=self.steps_per_period * factor, retry_finer=1)


FINE = Resolution(ramp_step_um=0.02, hold_first_s=None, hold_growth=1.2, hold_largest_s=2.0, steps_per_period=64)
REPLAY = Resolution(ramp_step_um=0.05, hold_first_s=0.01, hold_growth=2.0, hold_largest_s=30.0,
                    steps_per_period=16, max_periods=2, spline=False, retry_finer=4)
LINEARISED = Resolution(ramp_step_um=0.05, hold_first_s=math.inf, hold_growth=1.0, hold_largest_s=math.inf,
                        steps_per_period=16, spline=False, retry_finer=4, linearised=True, wait_first_s=1.0)
WAIT_LARGEST_S = 16.0     # s: a wait's largest step where `wait_first_s` steps it


@dataclass(frozen=True)
class Answer:
    """An oscillation answered about the state (LINEARISED): at f and mean gap h_m, the plate
    force F_0 (nN) of the state halfway through it and K*_lin (mN/m, `solver.state_response`)."""

    frequency_hz: float
    h_mean_um: float
    force_nN: float
    modulus_mN_per_m: complex


@dataclass(frozen=True)
class Sampling:
    """The instrument's rates: oscillations at `sample_hz` (at least `min_samples_per_period` a
    period), ramps and holds at `approach_hz`."""

    sample_hz: float = 100.0
    approach_hz: float = 1.0
    min_samples_per_period: int = 0

    def __post_init__(self) -> None:
        for name in ("sample_hz", "approach_hz"):
            if not (math.isfinite(getattr(self, name)) and getattr(self, name) > 0):
                raise InputError(f"{name} must be a finite number > 0 (got {getattr(self, name)!r})")

    def interval_s(self, frequency_hz: float) -> float:
        """The oscillation's sampling interval at `frequency_hz` (s)."""
        slowest = 1.0 / self.sample_hz
        return min(slowest, 1.0 / (self.min_samples_per_period * frequency_hz)) if self.min_samples_per_period \
            else slowest


@dataclass(frozen=True)
class Stretch:
    """Samples [start, stop) of a recording: a "ramp", a "hold" or an "oscillation" at f."""

    kind: str
    start: int
    stop: int
    frequency_hz: float | None = None


@dataclass
class Recording:
    """The samples of a simulated protocol, its stretches and the equilibrium solves (`steps`)."""

    time_s: Array
    force_nN: Array
    height_um: Array
    stretches: list[Stretch] = field(default_factory=list)
    steps: int = 0
    contact_label: float = math.nan      # l = ln ψ_c of the shell at the end (`solver.time_domain`)
    answers: list[Answer] = field(default_factory=list)   # LINEARISED: one per oscillation
    waits: list[tuple[Array, Array]] = field(default_factory=list)   # per wait its steps' (t s, F nN)

    def oscillations(self) -> list[Stretch]:
        return [s for s in self.stretches if s.kind == "oscillation"]


def _advance(state: TimeShell, h_um: float, dt_s: float) -> float:
    """The plate force (nN) after moving the plate to h over Δt: `TimeShell.advance`, which
    chooses its own sub-steps (none fails where a smaller one would succeed). Every step of a
    simulation goes through here."""
    return state.advance(h_um, dt_s)


def _bracket(residual: Callable[[float], float], h0_um: float,
             first_um: float = 1e-3, tries: int = 12) -> tuple[float | None, float | None]:
    """Gaps (lo, hi) around h0 where `residual` changes sign: from h0, steps of `first_um`
    doubling, towards the side the residual's sign asks (below zero: the force is short, so a
    smaller gap). A bracket, not a secant: the force of a step is smooth in the gap only up to the
    equilibrium's tolerance, and the sign is what a root needs. (None, None) if none is found."""
    r0 = residual(h0_um)
    if r0 == 0.0:
        return h0_um, h0_um
    direction = -1.0 if r0 < 0.0 else 1.0
    step = first_um
    for _ in range(tries):
        h = h0_um + direction * step
        if residual(h) * r0 <= 0.0:
            return (min(h, h0_um), max(h, h0_um))
        step *= 2.0
    return None, None


def _bracketed(residual: Callable[[float], float], h0: float, guess_um: float | None, force_nN: float) -> float:
    """The root of `residual` bracketed (from `guess_um` or the gap now `h0`), then by Brent."""
    lo = hi = None
    if guess_um is not None and math.isfinite(guess_um):
        lo, hi = _bracket(residual, guess_um, max(0.25 * abs(guess_um - h0), 10.0 * FORCE_TOL_UM))
    if lo is None or hi is None:
        lo, hi = _bracket(residual, h0)
    if lo is None or hi is None:
        raise SolverError(f"no gap holds the force {force_nN:g} nN near {h0:.6g} um")
    if hi > lo:
        found = root_scalar(residual, bracket=(lo, hi), method="brentq", xtol=FORCE_TOL_UM, maxiter=60)
        if not found.converged:
            raise SolverError(f"no gap holds the force {force_nN:g} nN ({found.flag})")
        return float(found.root)
    return lo


def _secant(residual: Callable[[float], float], guess_um: float, slope: float, steps: int = SECANT_STEPS) -> float | None:
    """The root of `residual` by secant steps from `guess_um`, the first along `slope`: the last gap
    tried, once the step it asks for is below FORCE_TOL_UM / 10 (the gap then that near the root:
    no step more to take, and a force as level as Brent's to FORCE_TOL_UM holds it); None if none
    is within `steps` (a flat or wrong-signed slope, or a force not smooth in the gap there: the
    caller brackets)."""
    if not slope < 0.0:                       # a smaller gap presses harder: dF/dh < 0
        return None
    h, r = guess_um, residual(guess_um)
    step = -r / slope
    for _ in range(steps):
        if abs(step) <= 0.1 * FORCE_TOL_UM:
            return h
        h_next = h + step
        r_next = residual(h_next)
        if r_next == r:
            return None
        step = -r_next * (h_next - h) / (r_next - r)
        h, r = h_next, r_next
    return None


def _slope(seen: list[tuple[float, float]], widest_um: float = 0.1) -> float:
    """dF/dh of a step's search: between its last gap (the root) and the gap it tried farthest from
    it within `widest_um` (wide enough that the equilibrium's tolerance does not blur it); nan if
    it tried no other."""
    h, r = seen[-1]
    others = [(abs(g - h), g, q) for g, q in seen[:-1] if 0.0 < abs(g - h) <= widest_um]
    if not others:
        return math.nan
    _, g, q = max(others)
    return (q - r) / (g - h)


def hold_steps(res: Resolution, sampling: Sampling, duration_s: float, wait: bool = False) -> list[float]:
    """The steps (s) of a hold of `duration_s` at resolution `res`: growing from the first (module
    docstring; 1 / `sampling.sample_hz` where `res` sets none); a wait's from `wait_first_s` where
    `res` sets it."""
    if wait and res.wait_first_s is not None:
        first, growth, largest = res.wait_first_s, 2.0, WAIT_LARGEST_S
    else:
        first = res.hold_first_s if res.hold_first_s is not None else 1.0 / sampling.sample_hz
        growth, largest = res.hold_growth, res.hold_largest_s
    out, dt, done = [], first, 0.0
    while done < duration_s - 1e-12:
        out.append(min(dt, duration_s - done))
        done += out[-1]
        dt = min(dt * growth, largest)
    return out


def simulate(shell: Shell, cortex: Cortex, protocol: Protocol, resolution: Resolution = FINE,
             sampling: Sampling = Sampling(), history: str = "carried",
             contact_history: bool = True) -> Recording:
    """The recording of `protocol` on `shell` (its h0 the protocol's start) with `cortex`
    (module docstring); SolverError where a step finds no equilibrium."""
    if history not in CORTEX_HISTORIES:
        raise InputError(f"the cortex history must be one of {', '.join(CORTEX_HISTORIES)} (got {history!r})")
    first = protocol.steps[0]
    if history == "relaxed" and not (isinstance(first, Ramp) and first.to_um is not None
                                     and first.to_um < protocol.start_um):
        raise InputError("a relaxed history needs a first ramp down to a height below the protocol's start")
    try:
        return _Run(shell, cortex, protocol, resolution, sampling, history, contact_history).run()
    except SolverError:
        if resolution.retry_finer <= 1:
            raise
        return _Run(shell, cortex, protocol, resolution.finer(resolution.retry_finer), sampling, history,
                    contact_history).run()


class _Run:
    """One simulation: the state, the samples so far and the stretch of ramps and holds being stepped."""

    def __init__(self, shell: Shell, cortex: Cortex, protocol: Protocol, resolution: Resolution,
                 sampling: Sampling, history: str, contact_history: bool):
        self.shell, self.cortex, self.protocol = replace(shell, h0_um=protocol.start_um), cortex, protocol
        self.res, self.sampling, self.history = resolution, sampling, history
        self.contact_history = contact_history
        self.state = TimeShell(self.shell, cortex, contact_history)
        self.t, self.level, self.steps, self.pending = protocol.start_s, protocol.start_um, 0, 0.0
        self.pending_wait = False       # the pending hold is a wait: height holds only
        self.waits: list[tuple[Array, Array]] = []
        f0 = self.state.force_nN()
        self.samples: list[tuple[Array, Array, Array]] = [(np.array([self.t]), np.array([self.level]), np.array([f0]))]
        self.stretches: list[Stretch] = []
        self.answers: list[Answer] = []
        self.n = 1
        self._open()

    def _open(self) -> None:
        """Start a stretch of ramps and holds at the state now."""
        self.origin = (self.t, self.state.h_um, self.state.force_nN())
        self.points: list[tuple[float, float, float]] = []
        self.kinds: list[tuple[str, float]] = []       # (kind, end time)

    def _step(self, h_um: float, dt_s: float) -> float:
        self.steps += 1
        force = _advance(self.state, h_um, dt_s)
        self.t += dt_s
        self.points.append((self.t, h_um, force))
        return force

    def run(self) -> Recording:
        ramps = 0
        for s in self.protocol.steps:
            if isinstance(s, Hold) and s.kind == "height":
                self.pending_wait = self.pending_wait or self.pending == 0
                self.pending += s.duration_s
                continue
            self._flush()
            if isinstance(s, Ramp):
                if self.history == "relaxed" and s.to_um is not None and ramps:
                    self._relax(s.to_um)
                self._ramp(s)
                ramps += 1
            elif isinstance(s, Hold):
                self._force_hold(s.duration_s)
            elif self.res.linearised:
                self._answer(s)
            else:
                self._oscillate(s)
        self._flush()
        self._close()
        t, h, f = (np.concatenate([p[k] for p in self.samples]) for k in range(3))
        return Recording(t, f, h, self.stretches, self.steps, float(self.state.u[-2]), self.answers, self.waits)

    def _relax(self, to_um: float) -> None:
        """A fresh cortex, relaxed the first ramp's depth above `to_um` (module docstring)."""
        first = self.protocol.steps[0]
        assert isinstance(first, Ramp) and first.to_um is not None
        self.state = TimeShell(replace(self.shell, h0_um=to_um + self.protocol.start_um - first.to_um), self.cortex,
                               self.contact_history)
        self.level = self.state.h_um
        if not self.points:
            self.origin = (self.t, self.state.h_um, self.state.force_nN())

    def _ramp(self, ramp: Ramp) -> None:
        if ramp.to_um is None:
            assert ramp.to_nN is not None
            self._ramp_to_force(ramp.to_nN, ramp.speed_um_per_s)
        else:
            h_from, h_to = self.level, ramp.to_um
            n = int(np.ceil(abs(h_to - h_from) / self.res.ramp_step_um))
            if n:
                times = np.linspace(0.0, abs(h_to - h_from) / ramp.speed_um_per_s, n + 1)
                for k in range(1, n + 1):
                    self._step(h_from + (h_to - h_from) * k / n, times[k] - times[k - 1])
            self.level = h_to
        self.kinds.append(("ramp", self.t))

    def _ramp_to_force(self, force_nN: float, speed: float) -> None:
        """Move the plate (down if the force is below `force_nN`, else up; down from the
        protocol's start, whose force is the tension's, F_a) until the force reaches it; the
        last step's gap by regula falsi on the force."""
        f_now = self.state.force_nN()
        if not self.steps and force_nN <= f_now:
            raise InputError(f"a ramp to {force_nN:g} nN from the protocol's start: the force there, "
                             f"the tension's, is already {f_now:.4g} nN")
        sign = -1.0 if force_nN > f_now else 1.0
        dh, dt = self.res.ramp_step_um, self.res.ramp_step_um / speed
        while True:
            saved, h0, f0 = self.state.saved(), self.state.h_um, f_now
            if h0 + sign * dh <= 0:
                raise SolverError(f"the ramp closed the gap before the force reached {force_nN:g} nN")
            self.steps += 1
            f_now = _advance(self.state, h0 + sign * dh, dt)
            if (f_now - force_nN) * (f0 - force_nN) <= 0:
                break
            self.t += dt
            self.points.append((self.t, self.state.h_um, f_now))
        lo, hi, f_lo, f_hi = h0, h0 + sign * dh, f0 - force_nN, f_now - force_nN
        h = hi
        for _ in range(30):
            if abs(f_hi) < 1e-9 * max(abs(force_nN), 1.0) or abs(hi - lo) < FORCE_TOL_UM:
                break
            h = hi - f_hi * (hi - lo) / (f_hi - f_lo)
            self.state.restore(saved)
            self.steps += 1
            f_h = _advance(self.state, h, abs(h - h0) / speed) - force_nN
            if f_h * f_hi < 0:
                lo, f_lo = hi, f_hi
            else:
                f_lo *= 0.5                  # Illinois: the end kept twice is halved
            hi, f_hi = h, f_h
        if self.state.h_um != hi:
            self.state.restore(saved)
            self.steps += 1
            _advance(self.state, hi, abs(hi - h0) / speed)
        self.t += abs(hi - h0) / speed
        self.level = hi
        self.points.append((self.t, hi, self.state.force_nN()))

    def _flush(self) -> None:
        """The height holds pending, as one hold at the plate's level; a wait's steps kept."""
        if self.pending > 0:
            times, forces = [self.t], [self.state.force_nN()]
            for dt in hold_steps(self.res, self.sampling, self.pending, self.pending_wait):
                forces.append(self._step(self.level, dt))
                times.append(self.t)
            self.kinds.append(("hold", self.t))
            if self.pending_wait:
                self.waits.append((np.array(times), np.array(forces)))
        self.pending, self.pending_wait = 0.0, False

    def _force_hold(self, duration_s: float) -> None:
        """Hold the force the hold starts with. After the first step, the creep the last step
        predicts, Δh_k ≈ Δh_(k-1) (Δt_k / Δt_(k-1))^(1/2) (between a creep that slows as t^(β-1)
        and one that keeps its rate), is the guess a secant starts from with the last step's
        slope dF/dh (`_secant`); where it does not settle, and at the first step, the gap is
        bracketed, then found by Brent's method on h (`_at_force`)."""
        target, last, slope = self.state.force_nN(), None, math.nan
        for dt in hold_steps(self.res, self.sampling, duration_s):
            h0 = self.state.h_um
            slope = self._at_force(target, dt, None if last is None else h0 + last[0] * math.sqrt(dt / last[1]), slope)
            last = (self.state.h_um - h0, dt)
        self.level = self.state.h_um
        self.kinds.append(("hold", self.t))

    def _at_force(self, force_nN: float, dt_s: float, guess_um: float | None = None,
                  slope: float = math.nan) -> float:
        """One step of Δt to the gap whose plate force is `force_nN`: from `guess_um` by a secant
        where `slope` is the last step's dF/dh, else the bracket sought from `guess_um` (steps of a
        quarter of its distance from the gap now) or from the gap now. Returns this step's dF/dh."""
        saved, h0 = self.state.saved(), self.state.h_um
        last = [math.nan]
        seen: list[tuple[float, float]] = []

        def residual(h: float) -> float:
            self.state.restore(saved)
            self.steps += 1
            last[0] = h
            seen.append((h, _advance(self.state, h, dt_s) - force_nN))
            return seen[-1][1]
        root = None
        if guess_um is not None and math.isfinite(guess_um) and math.isfinite(slope):
            try:
                root = _secant(residual, guess_um, slope)
            except SolverError:              # a secant step to a gap with no equilibrium: bracket instead
                root = None
        if root is None:
            root = _bracketed(residual, h0, guess_um, force_nN)
        if last[0] != root:
            residual(root)
        self.t += dt_s
        self.points.append((self.t, root, self.state.force_nN()))
        return _slope(seen)

    def _close(self) -> None:
        """Sample the stretch of ramps and holds stepped since `_open` (module docstring)."""
        if self.points:
            t_from, h_from, f_from = self.origin
            sim = np.array(self.points)
            end, rate = float(sim[-1, 0]), self.sampling.approach_hz
            t = np.r_[t_from + np.arange(1.0, np.ceil((end - t_from) * rate - 1e-9)) / rate, end]
            h: Array = np.asarray(np.interp(t, np.r_[t_from, sim[:, 0]], np.r_[h_from, sim[:, 1]]), float)
            f: Array = np.asarray(np.interp(t, np.r_[t_from, sim[:, 0]], np.r_[f_from, sim[:, 2]]), float)
            self.samples.append((t, h, f))
            at = 0
            for kind, t_end in self.kinds:
                stop = int(np.searchsorted(t, t_end + 1e-9, side="right"))
                if stop > at:
                    self._stretch(kind, at, stop)
                at = max(at, stop)
            self.n += t.size
        self._open()

    def _stretch(self, kind: str, start: int, stop: int, frequency_hz: float | None = None) -> None:
        last = self.stretches[-1] if self.stretches else None
        if last is not None and last.kind == kind == "hold" and last.stop == self.n + start:
            self.stretches[-1] = replace(last, stop=self.n + stop)
        else:
            self.stretches.append(Stretch(kind, self.n + start, self.n + stop, frequency_hz))

    def _answer(self, osc: Oscillate) -> None:
        """LINEARISED: the plate held at h_m through the oscillation, the state halfway answering
        at f (`solver.state_response.linear_modulus`); no samples."""
        from solver.state_response import linear_modulus, state_parts   # the frequency domain's imports: only here
        half = 0.5 * osc.duration_s
        force = self._step(self.level, half)
        K = linear_modulus(state_parts(self.state), osc.frequency_hz)
        self.answers.append(Answer(float(osc.frequency_hz), self.level, force, K))
        self.kinds.append(("hold", self.t))
        self.pending, self.pending_wait = self.pending + half, False

    def _oscillate(self, osc: Oscillate) -> None:
        self._close()
        h_m, f, A, phi = self.level, osc.frequency_hz, osc.amplitude_um, osc.phase_rad
        f0, t0 = self.state.force_nN(), self.t
        per_step = 1.0 / (f * self.res.steps_per_period)
        if self.res.spline:
            dt = self.sampling.interval_s(f)
            t_samples = dt * np.arange(1.0, int(round(osc.periods / (f * dt))) + 1.0)
            t_steps = _step_times(float(t_samples[-1]), per_step, dt)
        else:
            periods = min(osc.periods, self.res.max_periods or osc.periods)
            t_steps = per_step * np.arange(1.0, self.res.steps_per_period * periods + 1.0)
            t_samples = t_steps
            self.pending, self.pending_wait = self.pending + osc.duration_s - periods / f, False
        h_steps = h_m + A * np.sin(2 * np.pi * f * t_steps + phi)
        forces = np.empty(t_steps.size)
        for k, (h, d) in enumerate(zip(h_steps, np.diff(t_steps, prepend=0.0))):
            self.steps += 1
            forces[k] = _advance(self.state, float(h), float(d))
        if self.res.spline:
            force = np.asarray(CubicSpline(np.r_[0.0, t_steps], np.r_[f0, forces])(t_samples), float)
        else:
            force = forces
        h_samples = h_m + A * np.sin(2 * np.pi * f * t_samples + phi)
        self.samples.append((t0 + t_samples, h_samples, force))
        self.stretches.append(Stretch("oscillation", self.n, self.n + t_samples.size, float(f)))
        self.n += t_samples.size
        self.t = t0 + float(t_samples[-1])
        self._open()


def _step_times(end_s: float, step_s: float, first_s: float) -> Array:
    """Times (s) from the start of an oscillation to cover `end_s`: multiples of `step_s`, and
    before the first of them `first_s` doubling (the force's kink at the start resolved)."""
    lead = first_s * 2.0 ** np.arange(max(int(np.ceil(np.log2(step_s / first_s))), 0))
    grid = step_s * np.arange(1, int(np.ceil(end_s / step_s - 1e-9)) + 1)
    return np.r_[lead[lead < 0.75 * step_s], grid]
