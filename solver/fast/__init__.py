"""The fast solver: the compressed equilibrium of the shell, computed directly.

Formulation (SPEC section 2 symbols). The reference state is the droplet at h0,
labelled by material coordinates (`solver.fast.mesh`); the discrete
Lagrangian of the compressed shell (`solver.fast.lagrangian`)

    L(u; h) = E_tension + E_stretch + E_bend - p (V(u) - V0)

is stationary at the equilibrium: ∇_u L = 0 for the node positions, the
contact label l = log ψ_c (how much material has rolled onto the plate) and
the pressure p. Newton's method (exact Hessian, banded solves) finds the
positions and p at fixed l; the reduced energy E*(l) (that equilibrium's
energy) is very flat in l, and its unconstrained minimum has the free
surface poking through the plate, so l is found by an outer safeguarded
Newton search for the admissible local minimum of E*(l) (`_contact`,
compiled whole in `solver.fast.contact`). The
start is the reference state, followed along h0 → h1 in 1, 2, 4 or 8 steps
(the contact predicted from the droplet on the way), or, for a tension-only
shell, the droplet at h1 (its exact answer). Where those fail (a reference
near the free sphere, or a deep compression) an adaptive continuation
(`advance`) follows the plate from h0 to h1 with the contact label found at
every step: steps of CONTINUE_STEP / H_d at most, halved on a rejected step
(down to CONTINUE_LEAST / H_d), grown by half after an accepted one, each
started from the secant through the last two equilibria (the first from the
last one squeezed to the new gap, its contact label raised as the droplet's).
A continued step reaches its label from below and would stop on the first
admissible one, where the free surface touches the plate, even where E*(l)
has a lower minimum above it (a coarse mesh's bending layer: R 5 µm, K̃_S 2);
the step keeps the admissible minimum of lowest E* (`lowest_contact`), the
one a compression from the reference finds, so the equilibrium at a gap does
not depend on the path to it (an elastic, frictionless, non-adhesive contact
has no hysteresis).

Constraints:
- contact: material on the plate may not lift off, so l ≥ log ψ_min, and the
  free surface must stay below the plate; where less contact would lower the
  energy but lift the surface through the plate, the answer is the label at
  which the free surface touches the plate;
- no fold: neighbouring elements turn by less than π/2 (without bending a
  low-tension shell also has folded equilibria of higher energy);
- for a tension-only shell (K_B = K_S = 0) l is a gauge (any material may sit
  at the contact line): it is held fixed.

A tiny in-plane stiffness (1e-3 γ_a) is added to K_B and K_S so that a
tension-only shell still has a unique node distribution; it changes F_tot by
~1e-6 relative.

The plate force is the envelope derivative F_tot = -∂L/∂h1 = -(1/2) ∂L/∂z_p at
the solution (virtual work), in nN (energies in mN/m·µm², lengths in µm).
"""

from functools import lru_cache

import numpy as np
import numpy.typing as npt

from solver.fast import contact, newton
from common.errors import SolverError
from solver.fast.contact import LOG_PSI_MIN
from solver.fast.lagrangian import SCALE_LEAST, Lagrangian, NewtonMatrix
from solver.fast.mesh import reference
from solver.frustum import enclosed_volume, nodal_stretches, surface_area
from solver.geometry import droplet, meridian
from solver.model import Shell
from solver.solution import Solution

STEPS = (1, 2, 4, 8)         # continuation steps tried in turn
NEWTON_MAXIT = 30            # Newton iterations at one contact label at most
CONTINUE_STEP = 0.015        # `advance`: largest plate step, in units of 1/H_d (≈ R near the sphere)
CONTINUE_LEAST = 1e-6        # `advance`: a step halved below this (× 1/H_d) gives up
SECOND_START = 0.1           # `lowest_contact`: the second search starts at least this far above in l


def _admissible(lag, u, zp):
    """Nodes in order along the plate, off the axis, no element of zero
    length, and no fold: neighbouring elements turn by less than π/2."""
    r, z = lag.nodes(u, zp)[:2]
    return bool(np.all(np.isfinite(u))) and newton.shape_ok(r, z, lag.kc)


def _gap(lag, u, zp):
    """How far the free surface rises above the plate (µm; > 0: it crosses)."""
    return contact.gap(np.asarray(u, dtype=float), float(zp), lag.N, lag.kc)


def _slack(lag, u, zp):
    """How far a tension-only shell's free surface may rise above the plate:
    its polygon, free to slide, bulges by a few % of the first free element
    just outside the contact node (a discretisation error, F is unaffected);
    an elastic shell may not cross at all."""
    if lag.elastic:
        return 0.0
    r, z = lag.nodes(u, zp)[:2]
    return 0.1 * np.hypot(r[lag.kc + 1] - r[lag.kc], z[lag.kc + 1] - z[lag.kc])


def _newton(lag, u, zp, tol=1e-6, maxit=None):
    """Newton's method on ∇L = 0 for the node positions and p at fixed l;
    steps are halved while they leave the admissible shapes or multiply the
    residual (compiled, one call: `solver.fast.newton.newton`). Returns the
    solution, its Newton matrix and the iterations."""
    maxit = NEWTON_MAXIT if maxit is None else maxit
    status, u, g, band, lp, it = newton.newton(
        np.asarray(u, dtype=float), float(zp), lag.ref.positions(u[-2]), lag.terms, lag.band_order,
        lag.N, float(lag.V0), float(lag.force_scale), float(tol), int(maxit))
    if status != newton.CONVERGED:
        raise _newton_error(status, g, it, maxit)
    return u, g, NewtonMatrix(band, lp[0], lp[1]), it


def _newton_error(status, g, it, maxit):
    """The SolverError saying why Newton's method stopped (`newton.newton`'s status)."""
    if status == newton.SINGULAR:
        return SolverError(f"singular Newton matrix at iteration {it}")
    if status == newton.REJECTED:
        return SolverError(f"Newton step rejected at iteration {it} (left the admissible "
                           "shapes or made the residual explode)")
    return SolverError(f"Newton did not converge in {maxit} iterations (largest residual "
                       f"force {np.abs(g[:-2]).max():.3g} nN, volume residual {g[-1]:.3g} um3)")


def contact_at_least(u: npt.NDArray[np.float64]) -> bool:
    """Whether the unknowns u have the least contact label, l = log ψ_min."""
    return u[-2] <= LOG_PSI_MIN + 1e-12


NO_HISTORY = (np.empty(0), np.empty(0), np.empty(0))


def _contact(lag, u, zp, tol=1e-6, maxit=40, retreat=False, history=NO_HISTORY, predict=False):
    """The contact label: the admissible local minimum of E*(l), the
    equilibrium energy at fixed l (compiled, one call:
    `solver.fast.contact.contact`, whose docstring has the search and
    `retreat`, `predict`, and `history`: the stored history that moves with the material). Returns
    the solution and the Newton iterations; SolverError (or LinAlgError for a
    singular tangent system) as the Python loop raised them."""
    return _search(lag, u, zp, tol, maxit, retreat, history, predict)[:2]


def _search(lag, u, zp, tol=1e-6, maxit=40, retreat=False, history=NO_HISTORY, predict=False):
    """`_contact`, and whether its answer is the touching label (held by the
    plate, G > 0 there)."""
    labels, shape = lag.ref.arrays()
    status, u, g, iterations, last, lo, hi = contact.contact(
        np.asarray(u, dtype=float), float(zp), labels, shape, lag.terms, lag.band_order, lag.keep,
        lag.N, float(lag.V0), float(lag.force_scale), float(tol), int(maxit), NEWTON_MAXIT, bool(retreat),
        bool(predict), history)
    if status == contact.FOUND:
        return u, iterations, last == contact.HELD
    if status == contact.TANGENT_SINGULAR:
        raise np.linalg.LinAlgError(f"singular Newton matrix (zero pivot {last})")
    if status == contact.NO_CONTACT:
        raise SolverError(f"no contact line found (l = log psi_c in [{lo:.4g}, {hi:.4g}] after "
                          f"{maxit} steps)")
    raise _newton_error(status, g, last, NEWTON_MAXIT)


def lowest_contact(lag: Lagrangian, shell: Shell, u: npt.NDArray[np.float64], zp: float,
                   retreat: bool = True, history: tuple = NO_HISTORY,
                   second: bool = True, predict: bool = False) -> tuple[npt.NDArray[np.float64], int]:
    """The contact search from u at z_p (`_contact`), ended on the admissible
    local minimum of E*(l) of lowest energy. The search from a label below
    the answer (a continued step's) ends on the least admissible label, where
    the free surface touches the plate and G = dE*/dl > 0; on a coarse mesh
    E*(l) also has an unconstrained minimum (G = 0) a few % of ψ_c above it
    and lower, which a search from above (a compression from the reference)
    finds. So where the search ends touching, a second one starts from the
    droplet's label at 2 z_p (at least SECOND_START above), and the
    admissible answer of lower E* is kept. Returns the unknowns and the
    Newton iterations of both searches. With a `history` that moves with the
    material (`_contact`) the first search's answer is kept: E* of two labels
    would need the history carried to each; `second` False keeps it too
    (the caller's policy: `solver.time_domain` asks only where the plate
    presses deeper than before). `predict`: both searches take the tangent's
    touching label (`solver.fast.contact`). A history that is zero everywhere (a cortex without
    Maxwell elements, or the first step from the stress-free droplet) is no history: the
    elastic search, both searches."""
    if history[0].size and not (np.any(history[1]) or np.any(history[2])):
        history = NO_HISTORY
    u, iterations, held = _search(lag, u, zp, retreat=retreat, history=history, predict=predict)
    if not (held and second) or history[0].size:
        return u, iterations                    # G = 0, or the least label
    v = u.copy()
    v[-2] = max(_predicted_label(lag, shell, 2.0 * zp), u[-2] + SECOND_START)
    try:
        v, more = _contact(lag, v, zp, retreat=retreat, predict=predict)
    except (SolverError, np.linalg.LinAlgError):
        return u, iterations
    iterations += more
    if (_gap(lag, v, zp) <= _slack(lag, v, zp) and _admissible(lag, v, zp)
            and equilibrium_energy(lag, v, zp) < equilibrium_energy(lag, u, zp)):
        return v, iterations
    return u, iterations


def equilibrium_energy(lag: Lagrangian, u: npt.NDArray[np.float64], zp: float) -> float:
    """E* = L + p (V - V0) at the equilibrium u at z_p (mN/m·µm²; = E there)."""
    return float(lag.newton_system(u, zp, hessian=False)[0] + u[-1] * (lag.volume(u, zp) - lag.V0))


def reference_state(lag: Lagrangian) -> npt.NDArray[np.float64]:
    """The unknowns of the reference droplet at h0: least contact, p = 2 γ_a H_d."""
    r0, z0 = lag.ref.positions(LOG_PSI_MIN)[:2]
    return np.concatenate([r0[1:], z0[lag.kc + 1: lag.N], [LOG_PSI_MIN, 2.0 * lag.gamma * lag.ref.H]])


def _predicted_label(lag, shell, h):
    """log ψ_c from the droplet: material rolled on ≈ R_c(h) - a0, dψ/ds = 2 H_d."""
    dR = float(droplet(shell.volume_um3, h).contact_radius_um) - lag.ref.a0
    return np.log(np.clip(dR * 2.0 * lag.ref.H, np.exp(LOG_PSI_MIN), 0.5))


def _droplet_start(lag, shell):
    """The nodes spread over the droplet at h1 (the exact answer for a
    tension-only shell), the plate nodes in proportion to their labels."""
    h, ref = shell.h1_um, lag.ref
    d = droplet(shell.volume_um3, h)
    Rc = float(d.contact_radius_um)
    logpsic = _predicted_label(lag, shell, h)
    r0 = ref.positions(logpsic)[0]
    r_plate = Rc * r0[1: lag.kc + 1] / r0[lag.kc]
    rf, zf, _ = meridian(shell.volume_um3, h, 0.5 * np.pi * ref.xi)
    p = 2.0 * lag.gamma * float(d.mean_curvature_per_um)
    return np.concatenate([r_plate, rf, zf[:-1], [logpsic, p]])


def _follow(lag, shell, steps):
    """From the reference state along h0 → h1 in `steps` equal steps, the
    contact label predicted from the droplet on the way, found at h1."""
    h0, iterations = shell.h0_um, 0
    u = reference_state(lag)
    h_last = h0
    for i in range(1, steps + 1):
        h = h0 - shell.dh_um * i / steps
        u = u.copy()
        u[lag.N: -2] *= h / h_last          # the last shape squeezed to the new gap
        u[-2] = max(u[-2], _predicted_label(lag, shell, h))
        if i < steps:
            u, _, _, it = _newton(lag, u, 0.5 * h)
        else:
            u, it = _contact(lag, u, 0.5 * h)
        iterations, h_last = iterations + it, h
    return u, iterations


def advance(lag: Lagrangian, shell: Shell, u: npt.NDArray[np.float64], h_from: float, h_to: float,
            step: float | None = None, last: tuple[float, npt.NDArray[np.float64]] | None = None
            ) -> tuple[npt.NDArray[np.float64], int, float, tuple[float, npt.NDArray[np.float64]] | None]:
    """The equilibrium at gap h_to (µm) from the equilibrium u at h_from ≥
    h_to, by the adaptive continuation of the module docstring; `step` the
    first plate step (µm, default the largest), `last` the equilibrium before
    u as (gap, unknowns), if any. Returns the unknowns, the Newton iterations,
    the step and `last` to go on with; SolverError if a step halved below
    CONTINUE_LEAST / H_d still fails. Sets lag's force scale at each step
    (`_follow_scale`)."""
    largest, least = CONTINUE_STEP / lag.ref.H, CONTINUE_LEAST / lag.ref.H
    step, h, iterations = min(step or largest, largest), h_from, 0
    while h > h_to:
        h_next = max(h - step, h_to)
        _follow_scale(lag, shell, h_next)
        try:
            v, it = lowest_contact(lag, shell, _predicted(lag, shell, u, h, h_next, last), 0.5 * h_next)
            if not (_gap(lag, v, 0.5 * h_next) <= _slack(lag, v, 0.5 * h_next)
                    and _admissible(lag, v, 0.5 * h_next)):
                raise SolverError("the free surface crossed the plate")
        except (SolverError, np.linalg.LinAlgError) as err:
            step *= 0.5
            if step < least:
                raise SolverError(f"continuation stalled at h = {h:.6g} um: {err}") from None
            continue
        last, u, h, iterations = (h, u), v, h_next, iterations + it
        step = min(1.5 * step, largest)
    return u, iterations, step, last


def _follow_scale(lag, shell, h):
    """lag's scale of a converged nodal force at gap h: that of `Lagrangian`
    with the contact radius of the droplet at h in place of a0 where larger
    (a deep compression from the sphere has round-off in its residual above
    the scale of its small a0)."""
    contact_um = max(lag.ref.a0, SCALE_LEAST / lag.ref.H, float(droplet(shell.volume_um3, h).contact_radius_um))
    lag.force_scale = (lag.gamma + lag.KB + lag.KS) * contact_um * 0.1


def _predicted(lag, shell, u, h, h_next, last):
    """The start at gap h_next from the equilibrium u at h: the secant through
    `last` (gap, unknowns) and u, if there is one and it gives an admissible
    shape; else u squeezed (the free nodes' heights scaled) with its contact
    label raised by the droplet's increase between h and h_next."""
    if last is not None:
        v = u + (u - last[1]) * ((h_next - h) / (h - last[0]))
        v[-2] = max(v[-2], LOG_PSI_MIN)
        if _admissible(lag, v, 0.5 * h_next):
            return v
    v = u.copy()
    v[lag.N: -2] *= h_next / h
    v[-2] += max(_predicted_label(lag, shell, h_next) - _predicted_label(lag, shell, h), 0.0)
    return v


@lru_cache(maxsize=256)
def _mesh(volume, h0, resolution, layer):
    """The reference mesh (`solver.fast.mesh.reference`) with its volume
    (= V by the mesh's scale) and area, kept per (V, h0, resolution, layer)."""
    ref = reference(volume, h0, resolution, layer)
    r0, z0 = ref.positions(np.log(1e-12))[:2]
    return ref, enclosed_volume(r0, z0), surface_area(r0, z0)


def problem(shell: Shell) -> Lagrangian:
    """The shell's Lagrangian on its reference mesh (cached per (V, h0, layer))."""
    B = shell.bending_stiffness
    layer = np.sqrt(B / shell.tension_mN_per_m) if B > 0 else 0.2
    ref, V0, area0 = _mesh(float(shell.volume_um3), float(shell.h0_um), float(shell.resolution),
                           round(float(layer), 4))
    lag = Lagrangian(shell, ref)
    lag.V0, lag.area0 = V0, area0
    return lag


def equilibrium(shell: Shell) -> tuple[Lagrangian, npt.NDArray[np.float64], int]:
    """The solved problem, its unknowns and the Newton iterations, trying
    the starts in turn until one reaches an admissible equilibrium."""
    lag = problem(shell)
    zp, failure = 0.5 * shell.h1_um, None
    for steps in STEPS if lag.elastic else (0,) + STEPS:
        try:
            if steps == 0:       # tension-only: the droplet, l held (a gauge)
                u, _, _, iterations = _newton(lag, _droplet_start(lag, shell), zp)
            else:
                u, iterations = _follow(lag, shell, steps)
        except SolverError as err:
            failure = err
            continue
        if _gap(lag, u, zp) <= _slack(lag, u, zp) and _admissible(lag, u, zp):
            return lag, u, iterations
        failure = SolverError("the free surface crossed the plate")
    if lag.elastic:
        try:
            u, iterations = advance(lag, shell, reference_state(lag), shell.h0_um, shell.h1_um)[:2]
            return lag, u, iterations
        except SolverError as err:
            failure = err
    raise SolverError(f"no admissible equilibrium found (continuation up to {STEPS[-1]} "
                      f"steps, then adaptive): {failure}")


def energy(shell: Shell) -> float:
    """E* = min E at fixed volume and gap h1 (mN/m·µm², = 1e-15 J): the energy
    whose derivative -dE*/dh1 is the plate force (virtual work)."""
    lag, u, _ = equilibrium(shell)
    return equilibrium_energy(lag, u, 0.5 * shell.h1_um)


def plate_force_nN(lag: Lagrangian, u: npt.NDArray[np.float64], h_um: float) -> float:
    """F_tot = -∂L/∂h = -(1/2) ∂L/∂z_p at the equilibrium u at gap h (nN)."""
    return float(-0.5 * lag.evaluate(u, 0.5 * h_um, hessian=False)[2])


def solve(shell: Shell) -> Solution:
    """Compressed equilibrium of `shell` (a `solver.model.Shell`): a `Solution`."""
    lag, u, iterations = equilibrium(shell)
    zp = 0.5 * shell.h1_um
    force = plate_force_nN(lag, u, shell.h1_um)
    if not np.isfinite(force):
        raise SolverError("non-finite plate force")
    r, z, psic, p = lag.nodes(u, zp)
    r0, z0 = lag.ref.positions(u[-2])[:2]
    lam1, lam2 = nodal_stretches(r, z, r0, z0)
    return Solution(force_nN=float(force), volume_um3=lag.volume(u, zp),
                    area_um2=lag.area(u, zp), area0_um2=lag.area0, r_um=r, z_um=z,
                    lambda1=lam1, lambda2=lam2, converged=True, iterations=iterations,
                    message=f"contact label psi_c = {psic:.5g}, pressure {p:.6g} mN/m/um")


def warm_up(shell: Shell) -> None:
    """Load every compiled function a compression calls from numba's on-disk
    cache (0.1-0.2 s a process, the first time), by solving `shell` once
    (2-3 ms more) and throwing the result away: what a campaign's ranks do
    before their first task (`campaign.tasks.warm_up`)."""
    solve(shell)
