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

(`solver.fast.kernel`'s per-element `pa`, `ps`). One equilibrium per step: the fast solver's
contact search and Newton iteration (exact Hessian), warm-started from the last step's shape
squeezed to the new gap. Then a_new, s_new of every element give the new internal variables.

Material and mesh. The mesh's nodes on the free surface and the strip that rolls onto the plate
are labelled by their reference angle ψ0, which moves with the contact label l: when l changes
from one step to the next, the internal variables and last strains of those elements are carried
to their material by linear interpolation in ψ0 (element mid-labels; the disc's material is
fixed). The step starts from l extrapolated from the last two steps, with the history carried
there, and is carried again to the solved label; within the contact search it is held per element
(its derivative in l is left out of the contact line's balance). The label is set where the free
surface touches the plate in the bending layer, where E*(l) is flat: ψ_c swings by a factor of ~6
over a 0.05 µm oscillation, so this carry along the strip is the scheme's weakest approximation.

The plate force is -(1/2) ∂L/∂z_p at the step's equilibrium (the prestress included), in nN.
"""

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import numpy.typing as npt

from common.errors import InputError
from solver.fast import _contact, problem
from solver.fast.contact import LOG_PSI_MIN
from solver.fast.lagrangian import Lagrangian
from solver.geometry import droplet
from solver.model import PN_UM_PER_MN_PER_M_UM2, Shell
from solver.prony import Prony, fit_power_law

EXTRAPOLATE = 1.0   # the contact label's start: l_n + EXTRAPOLATE (l_n - l_n-1)


@dataclass(frozen=True)
class Cortex:
    """The cortex's relaxation moduli: K_B(t) and K_S(t) as Prony series (mN/m, s)."""

    bulk: Prony
    shear: Prony


def power_law_cortex(bulk_1s_mN_per_m: float, shear_1s_mN_per_m: float, bulk_exponent: float,
                     shear_exponent: float) -> Cortex:
    """K_B(t) = K_B,1s (t/1 s)^-β_B and K_S(t) = K_S,1s (t/1 s)^-β_S as Prony series
    (`solver.prony.fit_power_law`)."""
    return Cortex(fit_power_law(bulk_exponent, bulk_1s_mN_per_m).prony,
                  fit_power_law(shear_exponent, shear_1s_mN_per_m).prony)


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
        """Carry the elements from `start` on from mid-labels `old` to `new` (linear in ψ0)."""
        self.strain[start:] = np.interp(new, old, self.strain[start:])
        for row in self.viscous:
            row[start:] = np.interp(new, old, row[start:])


@dataclass
class TimeShell:
    """A shell with a viscoelastic cortex at one instant: its unknowns and internal variables.

    `shell` gives V, h0 (the stress-free reference droplet), γ_a, the mesh and B (bending
    stays elastic; give `bending_pN_um` to fix it apart from the moduli); its K_B and K_S are
    not used: `cortex` holds the moduli. Before its first step it is the reference droplet,
    whose force is the tension's alone, F_a = 2 γ_a H A_c at (V, h0) (`solver.geometry`)."""

    shell: Shell
    cortex: Cortex
    lag: Lagrangian = field(init=False)
    u: npt.NDArray[np.float64] = field(init=False)
    h_um: float = field(init=False)
    channels: tuple[_Channel, _Channel] = field(init=False)
    _steps: dict = field(init=False, default_factory=dict)
    _label: float = field(init=False)
    _last_label: float = field(init=False)
    _reference: Lagrangian = field(init=False)    # `lag` until a step (steps take `_steps`' own)

    def __post_init__(self) -> None:
        bulk0, shear0 = (float(p.relaxation(0.0)) for p in (self.cortex.bulk, self.cortex.shear))
        if bulk0 + shear0 <= 0:
            raise InputError("the cortex needs a nonzero instantaneous modulus")
        base = self._elastic(bulk0, shear0)
        self.lag = self._reference = base
        r0, z0 = base.ref.positions(LOG_PSI_MIN)[:2]
        self.u = np.concatenate([r0[1:], z0[base.kc + 1: base.N], [LOG_PSI_MIN, 2.0 * base.gamma * base.ref.H]])
        self.h_um = float(self.shell.h0_um)
        self._label = self._last_label = float(LOG_PSI_MIN)   # where the internal variables sit
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
        """The step's Lagrangian with the effective moduli K_Δt (kept per Δt)."""
        key = round(dt_s, 12)
        if key not in self._steps:
            self._steps[key] = self._elastic(self.cortex.bulk.step_factors(dt_s)[0],
                                             self.cortex.shear.step_factors(dt_s)[0])
        return self._steps[key]

    def step(self, h_um: float, dt_s: float) -> float:
        """Move the plate to gap h (µm) over Δt (s) and return the plate force (nN) there."""
        if not dt_s > 0:
            raise InputError(f"a time step must be > 0 s (got {dt_s:g})")
        lag = self._step_lagrangian(dt_s)
        bulk, shear = self.channels
        u = self.u.copy()
        u[lag.N: -2] *= h_um / self.h_um              # the last shape squeezed to the new gap
        u[-2] = max(u[-2] + EXTRAPOLATE * (u[-2] - self._last_label), LOG_PSI_MIN)   # l extrapolated
        self._last_label = float(self.u[-2])
        self._carry(u[-2])
        lag.terms = lag.terms._replace(pa=bulk.history(dt_s), ps=shear.history(dt_s))
        u, _ = _contact(lag, u, 0.5 * h_um)
        self._carry(u[-2])
        self.u, self.h_um, self.lag = u, float(h_um), lag
        a, s = self.strains()
        bulk.advance(dt_s, a)
        shear.advance(dt_s, s)
        return self.force_nN()

    def saved(self) -> tuple[Any, ...]:
        """What a step changes (unknowns, gap, Lagrangian, labels, internal variables), for `restore`."""
        return (self.u.copy(), self.h_um, self.lag, self._label, self._last_label,
                [(ch.strain.copy(), ch.viscous.copy()) for ch in self.channels])

    def restore(self, saved: tuple[Any, ...]) -> None:
        """Back to the state `saved` returned (after a step that failed)."""
        self.u, self.h_um, self.lag, self._label, self._last_label, channels = saved
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
        if self.lag is self._reference:
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


def element_strains(lag: Lagrangian, u: npt.NDArray[np.float64],
                    zp: float) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """(e1 + e2, e1 - e2) of every element at the unknowns u and plate z_p (λ1 = ds/dS,
    λ2 = r̄/r̄0 against the reference at u's contact label, as the kernel has them)."""
    r, z = lag.nodes(u, zp)[:2]
    r0, z0 = lag.ref.positions(u[-2])[:2]
    e1 = np.hypot(np.diff(r), np.diff(z)) / np.hypot(np.diff(r0), np.diff(z0)) - 1.0
    e2 = (r[1:] + r[:-1]) / (r0[1:] + r0[:-1]) - 1.0
    return e1 + e2, e1 - e2

