"""A small oscillation about a viscoelastic shell's state, in the frequency domain (SPEC 10, 12).

A `solver.time_domain.TimeShell` at gap h_m after any history carries per element the stresses
σ_a = K_B,Δt a + σ_hist,a and σ_s = K_S,Δt s + σ_hist,s of its last step (its Lagrangian's
moduli and prestress `pa`, `ps`). The plate oscillated about h_m, h(t) = h_m + Re(δh e^{iωt}),
|δh| small: every strain answers δa e^{iωt}, δs e^{iωt}, and by Boltzmann superposition the
cortex's stresses answer with the complex moduli of its Prony series (`solver.prony`),

    δσ_a = K_B*(ω) δa,   δσ_s = K_S*(ω) δs,   K*(ω) = K_∞ + Σ_j K_j iωτ_j / (1 + iωτ_j),

whatever stress the history left (the drift of the state itself is not part of the response:
the segment fit's linear term takes it, SPEC 6). Per element the energy density
w = K_B a²/2 + K_S s²/2 + p_a a + p_s s has the Hessian K_B ∇a∇aᵀ + σ_a ∇²a (and the same in s),
so at the state's stresses the tangent with the complex moduli is

    H* = H + (K_B* - K_B,Δt) P_B + (K_S* - K_S,Δt) P_S,   P_B = ∇²L(K_B + 1, p_a - a) - ∇²L(K_B, p_a)

(P_S alike): one unit of modulus more with the prestress lowered by the strain keeps every σ
and adds exactly ∇a∇aᵀ. H is the state's Hessian in q = (u, z_p) (`solver.viscous.full_hessian`).
A state whose step held its history per element (`TimeShell(contact_history=False)`, the label
settled at its history) moves its contact label l with the response where the state's gradient
in l vanishes (dE*/dl = 0) and holds it otherwise (a tension-only gauge, its least value, or a
touching contact).

With the history's share in the contact balance (`TimeShell.shared`, the default): the step
balanced R(q; v) = (∇L with g_l + G_hist in the label's row, ∂L/∂z_p), the history's samples v
(P at the elements' mid-labels ψ̄0) read off their material at the label (`solver.fast.contact`).
Its tangent at fixed v, H_tot, is H with its label row and column the central difference of R in
l (R is the gradient of the step's energy: symmetric). Each material point's stress answers its
own strain, δσ = K* δa_mat, so with σ = K_Δt a + P the samples answer δv = (K* - K_Δt) δa_mat,
where the material under an element moves with l (the disc's does not):

    δa_mat = ∇a·δq - a'(ψ0) (dψ̄0/dl) δl,
    H* = H_tot + Σ_B,S (K* - K_Δt) J M,   J = ∂R/∂v,  M = ∂a_mat/∂q.

J M is P_B off the label's row and column; its column (w = 4π r̄0 dS, the prestress's weight)
Σ_e w_e ∇a_e M_e,l and its row Σ_e β_e ∇a_e, β = ∂(w a)/∂l + Dᵀ(w a dψ̄0/dl) (D the samples'
slopes, `hermite_slopes`), each one gradient with the prestress shifted, and β·M_l. The label moves
freely where E*(l) with the history carried has its minimum within STATIONARY_L of it
(|G| ≤ STATIONARY_L k, k = dG/dl > 0 with the rest relaxed, H_tot's Schur complement); elsewhere
the plate holds it (touching: k ≈ 0 or below), and its row is the touching condition
δz_j = δz_p (j the highest free node): it moves so that the free surface stays on the plate.
`solver.viscous.respond` solves H* δq = 0 for δh and gives,
with the droplet's g(h) = 2 H A_c and A(h) at h_m, the reading of SPEC 6:

    K*_lin = δγ_eff / ε̂_A,   δγ_eff = (δF - γ_0 g'(h_m) δh) / g(h_m),   ε̂_A = A'(h_m) δh / A(h_m).

About the relaxed droplet at h_m (no stress kept) it gives `solver.relaxed_state`'s loss angle
(2e-5 rad; its |K*| is the linear one, 3-8 % below that model's 0.5 µm secant). The split is
`studies/prestressed_response.py`'s material stiffness, there about an elastic prestress.

Limits: first order in the amplitude; the oscillation's own effect on the history is second
order. With the share, against the FINE simulation with it read by the segment fit (the test's
cell: 0.5-0.9 %, 0.0033 rad; 8 corners over β_B 0.05-0.3, β_S 0.1-0.4, K̃_S 0.2-2, γ_a/K_B
0.01-0.2, standard bending, 13.5 and 11 µm, 0.1-10 Hz, docs/studies/contact-history.md): abs(K*)
within -0.43..+1.50 % but one segment (+2.08 %, 10 Hz after a 0.1 Hz oscillation), the loss angle
within 0.0075 rad at 1 and 10 Hz (0.026 rad at 0.1 Hz over two periods, FINE's start transient);
the held-out protocols of bench/linearised_replay.py within 1.04 % and 0.0072 rad. The label
held (l fixed) reads 1-8 % high where it is free, up to 5 % low where it touches. With the history
held per element the label's carry along the strip is not in H*: where the carried history holds
the label the stepped oscillation's |K*| is up to 6.7 % above this one's on those corners (2-6 %
at any amplitude down to 0.03 µm, bench/linearised_replay.py), arg K* within 0.014 rad at 1 and
10 Hz (without a bending layer ~0.7 %); neither other closure of the label did better there.
"""

import copy
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from solver.fast import contact_at_least
from solver.fast.contact import carry_history, hermite_slopes, history_share, node_labels
from solver.fast.lagrangian import Lagrangian
from solver.time_domain import Cortex, TimeShell, element_strains
from solver.viscous import Linearised, full_hessian, hold_label, respond

STATIONARY = 1e-4         # |dE*/dl| below this times the force scale: the label moves with the response
STATIONARY_L = 0.01       # with the share: E*(l)'s minimum within this of the label, the label moves
STEP_L = 1e-5             # central difference in l of the balance with the history carried


@dataclass
class StateParts:
    """The state's linearisation (`Linearised`) and its Hessian's parts P_B, P_S (module docstring)."""

    lin: Linearised
    bulk: np.ndarray
    shear: np.ndarray
    moduli: tuple[float, float]        # K_B,Δt, K_S,Δt of the state's Lagrangian (with its regularisation)
    cortex: Cortex


def _unit(lag: Lagrangian, strain: np.ndarray, channel: str) -> Lagrangian:
    """The state's Lagrangian with one unit more of K_B (`channel` "bulk") or K_S and the
    prestress lowered by the strain: the same stresses, the tangent one ∇a∇aᵀ stiffer."""
    other = copy.copy(lag)
    t = lag.terms
    other.terms = t._replace(KB=t.KB + 1.0, pa=t.pa - strain) if channel == "bulk" else \
        t._replace(KS=t.KS + 1.0, ps=t.ps - strain)
    return other


def _with_prestress(lag: Lagrangian, pa: npt.NDArray[np.float64], ps: npt.NDArray[np.float64]) -> Lagrangian:
    """A shallow copy of `lag` with its own prestress arrays."""
    other = copy.copy(lag)
    other.terms = lag.terms._replace(pa=pa.copy(), ps=ps.copy())
    return other


def _gradient(lag: Lagrangian, u: npt.NDArray[np.float64], zp: float) -> npt.NDArray[np.float64]:
    """(∇L, ∂L/∂z_p) at the elements' prestress (size + 1)."""
    _, g, dzp, _ = lag.evaluate(u, zp, hessian=False)
    return np.r_[g, dzp]


def _shifted(lag: Lagrangian, u: npt.NDArray[np.float64], zp: float, channel: int,
             shift: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """`_gradient` with the prestress of `channel` (0: P_a, 1: P_s) shifted by `shift` per element:
    less `_gradient`'s, Σ_e w_e shift_e ∇(a_e or s_e) (the label's row also ∂w_e/∂l)."""
    pa, ps = lag.terms.pa, lag.terms.ps
    other = _with_prestress(lag, pa + shift, ps) if channel == 0 else _with_prestress(lag, pa, ps + shift)
    return _gradient(other, u, zp)


def _balance(lag: Lagrangian, u: npt.NDArray[np.float64], zp: float, history: tuple) -> npt.NDArray[np.float64]:
    """R: `_gradient` with the history (ψ̄0, P_a, P_s) read off its material at u's label and
    its share G_hist in the label's row (the step's balance with the share, `solver.fast.contact`)."""
    other = _with_prestress(lag, lag.terms.pa, lag.terms.ps)
    dpa, dps = carry_history(float(u[-2]), lag.ref.zeta, lag.ref.xi, history, other.terms)
    R = _gradient(other, u, zp)
    r0, z0 = lag.ref.positions(u[-2])[:2]
    R[-3] += history_share(u, zp, r0, z0, lag.N, lag.kc, lag.nd, dpa, dps)
    return R


def _weighted_strains(lag: Lagrangian, u: npt.NDArray[np.float64], zp: float) -> npt.NDArray[np.float64]:
    """w_e (a_e, s_e) per element, w_e = 4π r̄0_e dS_e (the prestress term's weight), and w_e."""
    r0, z0 = lag.ref.positions(u[-2])[:2]
    w = 4.0 * np.pi * 0.5 * (r0[1:] + r0[:-1]) * np.hypot(np.diff(r0), np.diff(z0))
    a, s = element_strains(lag, u, zp)
    return np.stack([w * a, w * s, w])


def _touching(lag: Lagrangian, u: npt.NDArray[np.float64], zp: float, H: npt.NDArray[np.float64],
              parts: list[npt.NDArray[np.float64]]) -> None:
    """The label's row of H the touching condition δz_j = δz_p (j the highest free node), of the
    parts zero: the plate holds the label where the free surface touches it."""
    k, z = lag.size - 2, lag.nodes(u, zp)[1]
    j = lag.kc + 1 + int(np.argmax(z[lag.kc + 1: lag.N]))
    H[k, :] = 0.0
    H[k, lag.zidx[j]], H[k, lag.size] = 1.0, -1.0
    for P in parts:
        P[k, :] = 0.0


def _carried(state: TimeShell, base: npt.NDArray[np.float64], parts: list[npt.NDArray[np.float64]],
             strains: tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]) -> None:
    """With the history's share in the balance: the total Hessian in place of `base` and the
    parts with the history's response moving with the material (module docstring); the label's
    row the touching condition (`_touching`) where E*(l) has no minimum at the label."""
    lag, u, zp = state.lag, state.u, 0.5 * state.h_um
    history = (state.labels(float(u[-2])), lag.terms.pa[lag.nd:].copy(), lag.terms.ps[lag.nd:].copy())
    stiffness, G = _label_balance(lag, u, zp, history, base)
    _moving_history(lag, u, zp, history[0], parts, strains)
    if not (stiffness > 0 and abs(G) <= STATIONARY_L * stiffness):
        _touching(lag, u, zp, base, parts)


def _stepped(u: npt.NDArray[np.float64]) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """u with its label l stepped by +STEP_L and -STEP_L."""
    up, um = u.copy(), u.copy()
    up[-2], um[-2] = u[-2] + STEP_L, u[-2] - STEP_L
    return up, um


def _label_balance(lag: Lagrangian, u: npt.NDArray[np.float64], zp: float, history: tuple[npt.NDArray[np.float64], ...],
                   base: npt.NDArray[np.float64]) -> tuple[float, float]:
    """The total Hessian's row and column of the label, the balance's central difference in l,
    written into `base`; returns the label's stiffness with the rest relaxed (0 where the rest has
    no equilibrium) and its balance G."""
    k = lag.size - 2
    up, um = _stepped(u)
    column = (_balance(lag, up, zp, history) - _balance(lag, um, zp, history)) / (2 * STEP_L)
    total = base.copy()
    total[:, k], total[k, :] = column, column
    rest = lag.keep                                                      # the unknowns but l (banded solve)
    try:
        stiffness = total[k, k] - total[k, rest] @ lag.solve(total[:k + 2, :k + 2], total[rest, k])[:, 0]
    except np.linalg.LinAlgError:        # no equilibrium to relax the rest to: no minimum at the label
        stiffness = 0.0
    G = _balance(lag, u, zp, history)[k]
    base[...] = total
    return float(stiffness), float(G)


def _moving_history(lag: Lagrangian, u: npt.NDArray[np.float64], zp: float, at: npt.NDArray[np.float64],
                    parts: list[npt.NDArray[np.float64]],
                    strains: tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]) -> None:
    """The parts' row and column of the label with the history (sampled at the labels `at`)
    moving with its material (module docstring), in place."""
    k, nd = lag.size - 2, lag.nd
    up, um = _stepped(u)
    dl = (_weighted_strains(lag, up, zp) - _weighted_strains(lag, um, zp)) / (2 * STEP_L)
    w = _weighted_strains(lag, u, zp)[2]
    _, dpsi = node_labels(float(u[-2]), lag.ref.zeta, lag.ref.xi)
    dmid = 0.5 * (dpsi[1:] + dpsi[:-1])
    slopes = np.column_stack([hermite_slopes(at, e) for e in np.eye(at.size)])      # D: dv/dψ0 at the samples
    g0 = _gradient(lag, u, zp)
    for c, (strain, P) in enumerate(zip(strains, parts)):
        along = np.zeros_like(strain)
        along[nd:] = hermite_slopes(at, strain[nd:]) * dmid                     # a'(ψ0) dψ̄0/dl
        moved = dl[c] / w - strain * dl[2] / w - along                   # M's column in l: ∂a/∂l - a' dψ̄0/dl
        beta = dl[c].copy()                                              # J's row in l: ∂(w a)/∂l + Dᵀ(w a dψ̄0/dl)
        beta[nd:] += slopes.T @ ((w * strain)[nd:] * dmid)
        P[:, k] = _shifted(lag, u, zp, c, moved) - g0
        P[k, :] = _shifted(lag, u, zp, c, beta / w) - g0
        P[k, k] = beta @ moved


def state_parts(state: TimeShell) -> StateParts:
    """The linearisation of `state` at its gap and its Hessian's parts (module docstring)."""
    lag, u, zp = state.lag, state.u, 0.5 * state.h_um
    _, g, dzp, H = lag.evaluate(u, zp)
    base = full_hessian(lag, u, zp, H)
    a, s = state.strains()
    parts = [full_hessian(_unit(lag, a, "bulk"), u, zp) - base, full_hessian(_unit(lag, s, "shear"), u, zp) - base]
    if not lag.elastic or contact_at_least(u):
        held = True
    elif state.shared:
        _carried(state, base, parts, (a, s))
        held = False
    else:
        held = abs(g[-2]) > STATIONARY * lag.force_scale
    if held:
        hold_label(base, 1.0)
        for P in parts:
            hold_label(P, 0.0)
    lin = Linearised(lag=lag, u=u, zp=zp, H=base, force_nN=-0.5 * dzp, h_mean_um=state.h_um,
                     shell=state.shell, held=held)
    return StateParts(lin, parts[0], parts[1], (lag.terms.KB, lag.terms.KS), state.cortex)


def linear_modulus(parts: StateParts, frequency_hz: float) -> complex:
    """K*_lin (mN/m) of the state oscillated at `frequency_hz` (module docstring)."""
    kb, ks = parts.cortex.bulk.complex_modulus(frequency_hz), parts.cortex.shear.complex_modulus(frequency_hz)
    extra = (kb - parts.moduli[0]) * parts.bulk + (ks - parts.moduli[1]) * parts.shear
    return respond(parts.lin, 0.0, frequency_hz, extra, sparse=True).complex_modulus
