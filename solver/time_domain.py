"""The confined shell with a linear viscoelastic cortex, stepped in time.

SPEC sections 2 and 12. The shell of `solver.fast` (same mesh, geometric nonlinearity,
frictionless plate contact, incompressible interior held by the pressure p), but its
area moduli are relaxation functions written as Prony series (`solver.prony`),

    σ_a(t) = ∫ K_B(t - t') da(t'),   σ_s(t) = ∫ K_S(t - t') ds(t'),   a = e1 + e2,  s = e1 - e2,

per element of the mesh (e_i = λ_i - 1 as in SPEC 2; σ_a, σ_s the stresses conjugate to a and s,
which for constant moduli are K_B a and K_S s). Bending stays elastic with the shell's B, and
γ_a is the active tension as before. The interior is quasi-static (no inertia, no viscosity).

Internal variables: per Maxwell element j of each modulus and per mesh element, the viscous
part of the strain measure, a_v,j and s_v,j, whose spring carries h_j = K_j (a - a_v,j). Over a
step Δt the strain is taken linear in time and the exponential integrator is exact for it
(`solver.prony`): the step's stress is K_Δt a_new + σ_hist, so the step's equilibrium is the
stationary point of the elastic Lagrangian with the step's effective moduli K_B,Δt, K_S,Δt plus
the history's prestress, linear in the strain,

    Σ_e 4π r̄0_e dS_e [σ_hist,a,e (e1+e2) + σ_hist,s,e (e1-e2)],   σ_hist = Σ_j (d_j h_j - K_j g_j a_old)

(`solver.fast.kernel`'s per-element `pa`, `ps`). One equilibrium per step (`step`): the fast
solver's contact search with its retreat, its tangent's touching label (`predict`: a step's
start sits next to its answer) and Newton iteration (exact Hessian), ended on the
admissible contact label of lowest energy (`solver.fast.lowest_contact`) where the plate presses
deeper than it has before (a ramp into new depth: where a continued search and a compression from
the reference can end on two labels), else on the continued search's (holds, oscillations and
retracts over depths already visited follow the branch taken there; a second search at every
such step would double the cost of a protocol), started as
`solver.fast.advance` starts its steps (the secant in the gap through the last two equilibria,
else the last shape squeezed to the new gap with its contact label raised as the droplet's),
or, where that finds none, from the squeezed shape with its contact label extrapolated from the
last two steps; accepted only if the free surface stays below the plate, the shape
admissible, its contact label within the search's range (ψ_c < 1.4 rad, `LOG_PSI_MAX`) and the
plate force F ≥ 0 (to PULL_TOL_NN, the least contact's resolution: the plate only pushes, and
a step that would need it to pull is no equilibrium, which `advance` halves).
Then a_new, s_new of every element give the new internal variables. (With the
extrapolated start first the ramps from the sphere at β = 0 give the elastic continuation's
force too, to 2e-6 on the R 5 µm corners; at paper heights both starts give it to 5e-6.)
Whichever the start, the history is carried to the extrapolated label for the search: it is
where the material is expected, and the carried history then does not depend on the start.
The extrapolation is scaled by the plate's move over the last one where that is shorter (a
sub-step after a longer step would overshoot the label); where the search still finds no
equilibrium, the history is carried to the start's label instead (`STARTS`).

With `contact_history` (the default) every step's search reads the history off its material at
each trial label, its share of dE/dl in the balance (below). Without it (`contact_history=False`),
the solved label l depends on the label c its history is held at, l = f(c), and the step's
equilibrium is the one with its history where its label is, f(c) = c. Held per element in the
search, the history moves l against c: s = dl/dc reaches -0.4 to -0.7 at 10 Hz after a wait
of several τ_c (the stored history then the cortex's whole stress), and with c extrapolated
from the last two labels the label's error follows e_n+1 = s (2 e_n - e_n-1), which grows for
s < -1/3 (label and force alternate until no equilibrium is found). So a step whose label lands
more than CARRY_TOL_L from its c is solved again with c' = c + (l - c)/(1 - s), s the secant
through its last two solves (CARRY_SLOPE for the first), until it settles (`_settled`): the
accepted label is then the fixed point to CARRY_TOL_L whatever s, and the extrapolation only
saves solves. Where it does not settle in CARRY_TRIES solves (f jumps: near the top of a fast
retract f(c) can leave the plate for some c and not others, or |s| > 1), or no start finds an
equilibrium with the history held, the step is solved with the history's share in the balance
(below), which is the complete balance and needs no fixed point.

Robust stepping (`advance`, what every protocol calls). A step t → t + Δt, h → h', with the gap
linear in time, is taken in sub-steps [s_k, s_k+1] ⊂ [0, 1] of its own choice: the gap
h + s (h' - h) at time t + s Δt, the exponential integrator over each sub-step's (s_k+1 - s_k) Δt.
For a strain linear in time the split is exact (d_j, g_j compose: one step or many give the
same h_j), so sub-steps change only how finely the strain's path is followed. A sub-step moves
the plate at most CONTINUE_STEP / H_d (`solver.fast`'s continuation, ≈ 0.015 R near the sphere);
one that finds no equilibrium is undone and halved (down to SMALLEST_FRACTION of the step), one
that succeeds makes the next STRIDE_GROWTH times longer; that plate stride carries over to the
next call. So a step fails only where sub-steps of SMALLEST_FRACTION of it fail (none did on
the ramps from 2R - 0.01 µm to δ = R over the physiological range, bench/free_sphere_ramps.py).

Material and mesh. The mesh's nodes on the free surface and the strip that rolls onto the plate
are labelled by their reference angle ψ0, which moves with the contact label l: when l changes
from one step to the next, the internal variables and last strains of those elements are carried
to their material by linear interpolation in ψ0 (element mid-labels; the disc's material is
fixed). The history is carried to the start's label, and carried again to the solved label;
within the contact search it is read off its material at every trial label, its share of dE/dl in
the balance (`contact_history`, the default: every step; `solver.fast.contact.carry_history`,
`history_share`; `shared` says the last step did so with a nonzero history, and
`solver.state_response` linearises that balance; what it changes:
docs/studies/contact-history.md), or, with `contact_history=False`, held per element (its
derivative in l left out of the contact line's balance, the fixed point above) except where that
finds no settled label (that step). The label is set where the free
surface touches the plate in the bending layer, where E*(l) is flat: ψ_c swings by a factor of ~6
over a 0.05 µm oscillation, so this carry along the strip is the scheme's weakest approximation.

The plate force is -(1/2) ∂L/∂z_p at the step's equilibrium (the prestress included), in nN.
"""

import copy
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import numpy.typing as npt

from common.errors import InputError, SolverError
from solver.droplet_table import force_per_tension_um, mean_curvature_per_um
from solver.fast import CONTINUE_STEP, NO_HISTORY, _admissible, _follow_scale, _gap, lowest_contact, problem
from solver.fast.contact import LOG_PSI_MAX, LOG_PSI_MIN, carry_history
from solver.fast.lagrangian import Lagrangian
from solver.geometry import droplet
from solver.model import PN_UM_PER_MN_PER_M_UM2, Shell
from solver.prony import Prony, fit_power_law

STRIDE_GROWTH = 1.5          # `advance`: a sub-step after an accepted one is this much longer
SMALLEST_FRACTION = 2.0**-16  # `advance`: a sub-step halved below this fraction of the step gives up
# `step`'s tries in turn: (start `_continued`, else `_extrapolated`; history carried to the
# extrapolated label, else to the start's)
STARTS = ((True, True), (True, False), (False, True))
CARRY_TOL_L = 0.005   # `step`: a label this far from where its history was carried is solved again
CARRY_SLOPE = -0.5    # `step`: dl/dc assumed for the first re-solve (measured -0.73 to 0)
PULL_TOL_NN = 1e-3    # `step`: a plate force below -this (nN) would need the plate to pull
CARRY_TRIES = 6       # `step`: solves of one step before its label is given up as unsettled


@dataclass(frozen=True)
class Cortex:
    """The cortex's relaxation moduli: K_B(t) and K_S(t) as Prony series (mN/m, s)."""

    bulk: Prony
    shear: Prony


def power_law_cortex(bulk_1s_mN_per_m: float, shear_1s_mN_per_m: float, bulk_exponent: float,
                     shear_exponent: float, memory_s: float = float("inf"),
                     shear_memory_s: float | None = None) -> Cortex:
    """K_B(t) = K_B,1s (t/1 s)^-β_B e^(-t/τ_c) and K_S(t) = K_S,1s (t/1 s)^-β_S e^(-t/τ_c) as
    Prony series (`solver.prony.fit_power_law`), τ_c = `memory_s` (s; inf: no turnover, the pure
    power law). One τ_c for both moduli by default: the actin network's turnover renews the
    whole material, its bulk and shear response alike; `shear_memory_s` gives K_S its own."""
    shear_memory = memory_s if shear_memory_s is None else shear_memory_s
    return Cortex(fit_power_law(bulk_exponent, bulk_1s_mN_per_m, memory_s=memory_s).prony,
                  fit_power_law(shear_exponent, shear_1s_mN_per_m, memory_s=shear_memory).prony)


@dataclass
class _Channel:
    """One strain measure (a = e1+e2 or s = e1-e2) of every mesh element and its Maxwell elements."""

    prony: Prony
    strain: npt.NDArray[np.float64]            # last step's strain, per element
    viscous: npt.NDArray[np.float64]           # (Maxwell elements, mesh elements): a_v,j

    def stresses(self) -> npt.NDArray[np.float64]:
        """h_j = K_j (a - a_v,j) of every Maxwell element (j, e)."""
        return np.asarray(self.prony.weights)[:, None] * (self.strain - self.viscous)

    def history(self, dt_s: float) -> npt.NDArray[np.float64]:
        """σ_hist = Σ_j (d_j h_j - K_j g_j a_old) per element for a step Δt."""
        _, d, g = self.prony.step_factors(dt_s)
        K = np.asarray(self.prony.weights)[:, None]
        return (d[:, None] * self.stresses() - K * g[:, None] * self.strain).sum(0)

    def advance(self, dt_s: float, strain: npt.NDArray[np.float64]) -> None:
        """The internal variables after a step Δt to `strain` (exact for a linear strain)."""
        _, d, g = self.prony.step_factors(dt_s)
        K = np.asarray(self.prony.weights)[:, None]
        h = d[:, None] * self.stresses() + K * g[:, None] * (strain - self.strain)
        self.viscous = strain - h / K
        self.strain = strain.copy()

    def remap(self, old: npt.NDArray[np.float64], new: npt.NDArray[np.float64], start: int) -> None:
        """Carry the elements from `start` on from mid-labels `old` to `new` (linear in ψ0, held
        at the ends as `np.interp`; the strain and every Maxwell element at once)."""
        j = np.clip(np.searchsorted(old, new, side="right"), 1, old.size - 1)
        x0, x1 = old[j - 1], old[j]
        w = np.clip(np.divide(new - x0, x1 - x0, out=np.zeros_like(new), where=x1 > x0), 0.0, 1.0)
        for values in (self.strain[None, start:], self.viscous[:, start:]):
            values[...] = values[:, j - 1] * (1.0 - w) + values[:, j] * w


@dataclass
class TimeShell:
    """A shell with a viscoelastic cortex at one instant: its unknowns and internal variables.

    `shell` gives V, h0 (the stress-free reference droplet), γ_a, the mesh and B (bending
    stays elastic; give `bending_pN_um` to fix it apart from the moduli); its K_B and K_S are
    not used: `cortex` holds the moduli. Before its first step it is the reference droplet,
    whose force is the tension's alone, F_a = 2 γ_a H A_c at (V, h0) (`solver.geometry`)."""

    shell: Shell
    cortex: Cortex
    contact_history: bool = True       # the history's share of dE/dl in the contact search (False: held)
    lag: Lagrangian = field(init=False)
    u: npt.NDArray[np.float64] = field(init=False)
    h_um: float = field(init=False)
    channels: tuple[_Channel, _Channel] = field(init=False)
    equilibria: int = field(init=False, default=0)    # equilibria found (`step`s taken) so far
    _base: Lagrangian = field(init=False)
    _label: float = field(init=False)
    _last: tuple[float, npt.NDArray[np.float64]] = field(init=False)
    _stride: float = field(init=False)
    _deepest_um: float = field(init=False)     # the least gap reached so far (µm)
    shared: bool = field(init=False, default=False)   # the last step balanced a nonzero history's share of dE/dl
    _instant_bulk: float = field(init=False)     # K_B(0) (mN/m)

    def __post_init__(self) -> None:
        bulk0, shear0 = (float(p.relaxation(0.0)) for p in (self.cortex.bulk, self.cortex.shear))
        if bulk0 + shear0 <= 0:
            raise InputError("the cortex needs a nonzero instantaneous modulus")
        base = self._elastic(bulk0, shear0)
        self._instant_bulk = bulk0
        self._base = self.lag = base
        r0, z0 = base.ref.positions(LOG_PSI_MIN)[:2]
        self.u = np.concatenate([r0[1:], z0[base.kc + 1: base.N], [LOG_PSI_MIN, 2.0 * base.gamma * base.ref.H]])
        self.h_um = float(self.shell.h0_um)
        self._label = float(LOG_PSI_MIN)          # where the internal variables sit
        self._last = (self.h_um, self.u)          # the equilibrium before this one (the secant's)
        self._stride = CONTINUE_STEP / base.ref.H  # `advance`'s next plate move (µm)
        self._deepest_um = self.h_um
        n = base.N
        bulk, shear = (_Channel(p, np.zeros(n), np.zeros((len(p.weights), n)))
                       for p in (self.cortex.bulk, self.cortex.shear))
        self.channels = (bulk, shear)

    def _elastic(self, bulk: float, shear: float) -> Lagrangian:
        """The elastic Lagrangian on the shell's mesh with moduli (K_B, K_S) and the shell's B."""
        B = self.shell.bending_stiffness * PN_UM_PER_MN_PER_M_UM2
        ref_lag = problem(self.shell)
        lag = Lagrangian(replace(self.shell, bulk_mN_per_m=float(bulk), shear_mN_per_m=float(shear),
                                 bending_pN_um=B), ref_lag.ref)
        lag.V0, lag.area0 = ref_lag.V0, ref_lag.area0
        return lag

    def _step_lagrangian(self, dt_s: float) -> Lagrangian:
        """A Lagrangian of the step with the effective moduli K_Δt (a shallow copy of the
        elastic one, its moduli replaced; the prestress is set by the step)."""
        lag = copy.copy(self._base)
        reg = self._base.KB - self._instant_bulk   # `Lagrangian`'s regularisation
        lag.KB, lag.KS = (p.step_factors(dt_s)[0] + reg for p in (self.cortex.bulk, self.cortex.shear))
        lag.terms = lag.terms._replace(KB=float(lag.KB), KS=float(lag.KS))
        return lag

    def step(self, h_um: float, dt_s: float) -> float:
        """One equilibrium: move the plate to gap h (µm) over Δt (s) and return the plate force
        (nN) there; SolverError (the state unchanged) where none is found (`advance` splits)."""
        if not dt_s > 0:
            raise InputError(f"a time step must be > 0 s (got {dt_s:g})")
        saved = self.saved()
        for share in (True,) if self.contact_history else (False, True):
            for continued, carry_extrapolated in STARTS:
                try:
                    return self._settled(h_um, dt_s, continued, carry_extrapolated, share, saved)
                except (SolverError, np.linalg.LinAlgError) as err:
                    self.restore(saved)
                    failure = err
        raise SolverError(f"no equilibrium at gap {h_um:.6g} um after {dt_s:.3g} s: {failure}")

    def _settled(self, h_um: float, dt_s: float, continued: bool, carry_extrapolated: bool, share: bool,
                 saved: tuple[Any, ...]) -> float:
        """`_equilibrium`, with the history's `share` in the contact balance in one solve; without
        it, solved again until its label lands within CARRY_TOL_L of the label its history was
        carried to (module docstring): the next carry c' = c + (l - c)/(1 - s), s = dl/dc on the
        secant through the last two tries (CARRY_SLOPE for the first); SolverError where the
        label has not settled after CARRY_TRIES solves."""
        if share:
            return self._equilibrium(h_um, dt_s, continued, carry_extrapolated, share=True)[0]
        carry, tries = None, []
        for _ in range(CARRY_TRIES):
            force, carried = self._equilibrium(h_um, dt_s, continued, carry_extrapolated, carry)
            label = float(self.u[-2])
            if abs(label - carried) <= CARRY_TOL_L:
                return force
            tries.append((carried, label))
            self.restore(saved)
            carry = _next_carry(tries)
        raise SolverError(f"the contact label did not settle at its carried history (at {tries[-1][1]:.4g} "
                          f"with the history at {tries[-1][0]:.4g})")

    def _equilibrium(self, h_um: float, dt_s: float, continued: bool, carry_extrapolated: bool,
                     carry_label: float | None = None, share: bool = False) -> tuple[float, float]:
        """`step`'s work from the start `_continued` or, if not `continued`, `_extrapolated`: the
        history carried to `carry_label` if given, else to the extrapolated label (or the
        start's), the contact search (`solver.fast`'s, with its retreat), the admissible shape
        and a pushing plate checked, the history carried to the solved label and advanced; the
        force (nN) and the label the search held the history at."""
        lag = self._step_lagrangian(dt_s)
        _follow_scale(lag, self.shell, h_um)
        bulk, shear = self.channels
        u = self._continued(lag, h_um) if continued else self._extrapolated(lag, h_um)
        if carry_label is None:
            carry_label = float(self._extrapolated(lag, h_um)[-2] if carry_extrapolated else u[-2])
        self._carry(carry_label)
        pa, ps = bulk.history(dt_s), shear.history(dt_s)
        lag.terms = lag.terms._replace(pa=pa, ps=ps)
        history = (self.labels(self._label), pa[lag.nd:].copy(), ps[lag.nd:].copy()) \
            if share else NO_HISTORY
        u, _ = lowest_contact(lag, self.shell, u, 0.5 * h_um, history=history, second=h_um < self._deepest_um,
                              predict=True)
        if history is not NO_HISTORY:      # the prestress of the label found (the search's last may differ)
            carry_history(float(u[-2]), lag.ref.zeta, lag.ref.xi, history, lag.terms)
        if not (_gap(lag, u, 0.5 * h_um) <= 0.0 and _admissible(lag, u, 0.5 * h_um)):
            raise SolverError("the free surface crossed the plate")
        if not u[-2] < LOG_PSI_MAX:
            raise SolverError("the contact label left the search's range")
        force = float(-0.5 * lag.newton_system(u, 0.5 * h_um, hessian=False)[2])
        if not force >= -PULL_TOL_NN:
            raise SolverError(f"the plate would have to pull ({force:.4g} nN): it only pushes")
        self._carry(u[-2])
        self.shared = history is not NO_HISTORY and bool(np.any(history[1]) or np.any(history[2]))
        self._last = (self.h_um, self.u)
        self.u, self.h_um, self.lag = u, float(h_um), lag
        self._deepest_um = min(self._deepest_um, self.h_um)
        a, s = self.strains()
        bulk.advance(dt_s, a)
        shear.advance(dt_s, s)
        self.equilibria += 1
        return force, carry_label

    def _extrapolated(self, lag: Lagrangian, h_um: float) -> npt.NDArray[np.float64]:
        """The second start at gap h: the last shape squeezed to the new gap, its contact label
        extrapolated from the last two steps, l_n + r (l_n - l_n-1) (at least log ψ_min), r the
        plate's move over the last one where shorter (a sub-step after a longer step), else 1."""
        v = self.u.copy()
        v[lag.N: -2] *= h_um / self.h_um
        move, last_move = h_um - self.h_um, self.h_um - self._last[0]
        ratio = min(1.0, abs(move / last_move)) if move and last_move else 1.0
        v[-2] = max(self.u[-2] + ratio * (self.u[-2] - self._last[1][-2]), LOG_PSI_MIN)
        return v

    def _continued(self, lag: Lagrangian, h_um: float) -> npt.NDArray[np.float64]:
        """The start at gap h: the secant in the gap through the last two equilibria where both
        steps move the plate and it gives an admissible shape (`solver.fast.advance`'s), else the
        last shape squeezed to the new gap with its contact label raised by the droplet's
        increase (l = log ψ_c, ψ_c ≈ 2 H_d (R_c(h) - a0)); the last shape itself for a hold."""
        u, h = self.u, self.h_um
        if h_um == h:
            return u.copy()
        h_last, u_last = self._last
        if h_last != h and (h_last - h) * (h - h_um) > 0:
            v = u + (u - u_last) * ((h_um - h) / (h - h_last))
            v[-2] = max(v[-2], LOG_PSI_MIN)
            if _admissible(lag, v, 0.5 * h_um):
                return v
        v = u.copy()
        v[lag.N: -2] *= h_um / h
        v[-2] += max(self._label_of(h_um) - self._label_of(h), 0.0)
        return v

    def _label_of(self, h_um: float) -> float:
        """log ψ_c of the droplet at gap h: material rolled on ≈ R_c(h) - a0, dψ/ds = 2 H_d."""
        ref = self.lag.ref
        rolled = contact_radius_um(self.shell.volume_um3, h_um) - ref.a0
        return float(np.log(np.clip(rolled * 2.0 * ref.H, np.exp(LOG_PSI_MIN), 0.5)))

    def advance(self, h_um: float, dt_s: float) -> float:
        """Move the plate to gap h (µm) over Δt (s), linear in time, in sub-steps of its own
        choice, and return the plate force (nN) at the end: the robust step (module docstring).
        SolverError (the state unchanged) if a sub-step of SMALLEST_FRACTION of the step fails."""
        if not dt_s > 0:
            raise InputError(f"a time step must be > 0 s (got {dt_s:g})")
        saved, h_from, move = self.saved(), self.h_um, h_um - self.h_um
        largest_um = CONTINUE_STEP / self.lag.ref.H
        fraction = 1.0 if move == 0 else min(1.0, self._stride / abs(move))
        done, force = 0.0, np.nan
        while done < 1.0:
            end, before = (1.0 if done + fraction > 1.0 - 1e-9 else done + fraction), self.saved()
            try:
                force = self.step(h_from + end * move if end < 1.0 else h_um, (end - done) * dt_s)
            except SolverError as err:
                self.restore(before)
                fraction *= 0.5
                self._stride = min(self._stride, abs(fraction * move)) if move else self._stride
                if fraction < SMALLEST_FRACTION:
                    self.restore(saved)
                    raise SolverError(f"no equilibrium in steps of {SMALLEST_FRACTION:g} of the step "
                                      f"from {h_from:.6g} to {h_um:.6g} um: {err}") from None
                continue
            done = end
            self._stride = min(self._stride * STRIDE_GROWTH, largest_um)
            fraction = min(fraction * STRIDE_GROWTH, 1.0 if move == 0 else self._stride / abs(move))
        return force

    def saved(self) -> tuple[Any, ...]:
        """What a step changes (unknowns, gap, Lagrangian, labels, internal variables), for `restore`."""
        return (self.u.copy(), self.h_um, self.lag, self._label, self._last, self._stride, self._deepest_um,
                self.shared, [(ch.strain.copy(), ch.viscous.copy()) for ch in self.channels])

    def restore(self, saved: tuple[Any, ...]) -> None:
        """Back to the state `saved` returned (after a step that failed)."""
        (self.u, self.h_um, self.lag, self._label, self._last, self._stride, self._deepest_um, self.shared,
         channels) = saved
        for ch, (strain, viscous) in zip(self.channels, channels):
            ch.strain, ch.viscous = strain.copy(), viscous.copy()

    def _carry(self, label: float) -> bool:
        """Carry the internal variables from the elements' material at `self._label` to that at
        contact label `label`; whether anything moved."""
        if label == self._label:
            return False
        old, new = self.labels(self._label), self.labels(label)
        for ch in self.channels:
            ch.remap(old, new, self.lag.nd)
        self._label = float(label)
        return True

    def force_nN(self) -> float:
        """The plate force -(1/2) ∂L/∂z_p (nN) at the current state and the last step's prestress;
        before any step (the unknowns the reference mesh, no equilibrium yet) the reference
        droplet's F_a = 2 γ_a H A_c (nN)."""
        if self.lag is self._base:        # the untouched reference (a step takes a copy)
            reference = droplet(self.shell.volume_um3, self.shell.h0_um)
            return float(self.shell.tension_mN_per_m * reference.force_per_tension_um)
        return float(-0.5 * self.lag.newton_system(self.u, 0.5 * self.h_um, hessian=False)[2])

    def strains(self) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """(e1 + e2, e1 - e2) of every element now (`element_strains`)."""
        return element_strains(self.lag, self.u, 0.5 * self.h_um)

    def labels(self, label: float) -> npt.NDArray[np.float64]:
        """The reference angle ψ0 at the middle of every element from the disc's edge on, at
        contact label l = `label`."""
        ref, psic = self.lag.ref, np.exp(label)
        psi = np.concatenate([[0.0], psic * ref.zeta, psic + (0.5 * np.pi - psic) * ref.xi])
        return 0.5 * (psi[1:] + psi[:-1])


def _next_carry(tries: list[tuple[float, float]]) -> float:
    """The next carried label c' = c + (l - c)/(1 - s) from the tries (c, l) so far: the root of
    l(c) - c on the secant through the last two (s = dl/dc), CARRY_SLOPE for the first; s held
    below 1/2 (l(c) - c falls in c wherever the carry is stable)."""
    c, l = tries[-1]
    s = CARRY_SLOPE
    if len(tries) > 1 and tries[-2][0] != c:
        s = min((l - tries[-2][1]) / (c - tries[-2][0]), 0.5)
    return c + (l - c) / (1.0 - s)


def contact_radius_um(volume_um3: float, h_um: float) -> float:
    """R_c of the droplet at gap h (µm): A_c = F_a/(2 γ_a H), from `solver.droplet_table`."""
    g, H = force_per_tension_um(volume_um3, h_um), mean_curvature_per_um(volume_um3, h_um)
    return float(np.sqrt(g / (2.0 * np.pi * H)))


def element_strains(lag: Lagrangian, u: npt.NDArray[np.float64],
                    zp: float) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """(e1 + e2, e1 - e2) of every element at the unknowns u and plate z_p (λ1 = ds/dS,
    λ2 = r̄/r̄0 against the reference at u's contact label, as the kernel has them)."""
    r, z = lag.nodes(u, zp)[:2]
    r0, z0 = lag.ref.positions(u[-2])[:2]
    e1 = np.hypot(np.diff(r), np.diff(z)) / np.hypot(np.diff(r0), np.diff(z0)) - 1.0
    e2 = (r[1:] + r[:-1]) / (r0[1:] + r0[:-1]) - 1.0
    return e1 + e2, e1 - e2

