"""The force of a shell whose cortex relaxes as a power law, along a recorded
deformation history (an approach ramp and the hold after it; SPEC 11-12).

The cortex's area moduli relax as K_B(t) = K_B(1 s) t^-β and K_S(t) = K̃_S K_B(t)
(one β; `solver.time_domain.power_law_cortex`), the active tension γ_a is a
prestress. The elastic shell of SPEC 2 pressed from its free sphere to δ
(`shell_ramp`: F = γ_a R ĝ(δ/R) + K_B R e(δ/R, γ̃_a, K̃_S, R)) stores the energy

    W(δ) = K_B R² w(δ/R),   w(d) = ∫_0^d e(d') dd',

and is written as one generalised strain U(d) = sqrt(2 w(d)) with F_e = K_B R U U'(d)
(U' = dU/dd = e/U). The viscoelastic shell carries the same strain with Boltzmann
superposition of its history (the strain's work conjugate taken at the present
shape):

    F(t) = γ_a R ĝ(d(t)) + R U'(d(t)) ∫ K_B(t - t') dU(d(t')),   d = δ/R,

exact for β = 0 (the elastic shell) and for a uniformly stretched membrane; the
shell's own strain field is not uniform, which `bench/powerlaw_ramp_hold.py` checks
against the time-domain simulator. e is read at γ̃_a = γ_a / K_B(1 s). Between
samples the strain is taken linear in time and the power law is integrated
exactly:

    ∫_{t_{m-1}}^{t_m} (t_n - t')^-β dt' / Δt_m
        = [(t_n - t_{m-1})^{1-β} - (t_n - t_m)^{1-β}] / ((1 - β) Δt_m),

so the stress at sample n is Σ_{m ≤ n} M_nm ΔU_m (`memory_matrix`; β = 0: the sum
of the ΔU, U itself). The deformation history is the recorded one, δ = max(x0 - x, 0)
(x = z + F/k): a constant-height hold (δ constant, F relaxing) and a constant-force
hold (F constant, δ creeping) are the same model. For a ramp at speed v from the
contact, t = δ/v, so the ramp's force depends on K_B(1 s) and v only through
K_B(1 s) v^β (bending, elastic at K(1 s), aside).
"""

import numpy as np
import numpy.typing as npt
from scipy.integrate import cumulative_trapezoid
from scipy.interpolate import PchipInterpolator

from analysis.afm.tension import shell_ramp
from analysis.calibration.ramp_table import ShellTable
from solver.droplet_table import DEPTH_MAX, unit_force_per_tension

Array = npt.NDArray[np.float64]
STRAIN_NODES = 400          # nodes of w(d) from 0 to the table's deepest δ/R


_MEMORY: dict[tuple[bytes, float], Array] = {}


def memory_matrix(time_s: npt.ArrayLike, beta: float) -> Array:
    """M (n × n, lower triangular): the stress at sample n is Σ_m M_nm ΔU_m for a strain
    linear in time between samples (module doc); column 0 is zero (no step before the first
    sample). Samples at the same time act as a step (the limit Δt → 0). The last one made
    is kept (a fit's evaluations at one β share it)."""
    t = np.asarray(time_s, float)
    key = (t.tobytes(), float(beta))
    if key not in _MEMORY:
        _MEMORY.clear()
        _MEMORY[key] = _memory_matrix(t, float(beta))
    return _MEMORY[key].copy()


def _memory_matrix(t: Array, beta: float) -> Array:
    """`memory_matrix` made."""
    a = 1.0 - beta
    lag = np.clip(t[:, None] - t[None, :], 0.0, None)         # t_n - t_m
    p = lag ** a
    dt = np.diff(t)
    m = np.zeros((t.size, t.size))
    # column m (≥ 1): [(t_n - t_{m-1})^a - (t_n - t_m)^a] / (a Δt_m), for n ≥ m
    step = dt > 0
    cols = np.where(step, (p[:, :-1] - p[:, 1:]) / (a * np.where(step, dt, 1.0)), 0.0)
    same = ~step                                               # a jump: its strain then K(t_n - t_m)
    if np.any(same):
        with np.errstate(divide="ignore"):
            jump = np.where(lag[:, 1:] > 0, lag[:, 1:] ** -beta, 1.0)
        cols = np.where(same[None, :], jump, cols)
    m[:, 1:] = cols * (np.arange(t.size)[:, None] >= np.arange(1, t.size)[None, :])
    return m


_STRAINS: dict[tuple[int, float, float, float], tuple[PchipInterpolator, PchipInterpolator]] = {}


def strain(depth_over_radius: npt.ArrayLike, gamma_tilde: float, shear_tilde: float, radius_um: float,
           table: ShellTable | None = None) -> tuple[Array, Array]:
    """(U, U') at deformations δ/R (module doc), held at the table's deepest δ/R beyond it;
    w(d) integrated on STRAIN_NODES depths (kept per cell)."""
    t = shell_ramp.resolve(table)
    key = (id(t), float(gamma_tilde), float(shear_tilde), float(radius_um))
    if key not in _STRAINS:
        if len(_STRAINS) > 256:
            _STRAINS.clear()
        d = np.linspace(0.0, t.max_depth, STRAIN_NODES + 1)
        e = t.elastic(d, gamma_tilde, shear_tilde, radius_um)
        u = np.sqrt(2.0 * np.clip(cumulative_trapezoid(e, d, initial=0.0), 0.0, None))
        slope = np.empty_like(u)
        slope[1:] = e[1:] / np.where(u[1:] > 0, u[1:], np.inf)
        slope[0] = slope[1]
        _STRAINS[key] = (PchipInterpolator(d, u), PchipInterpolator(d, slope))
    u_of, slope_of = _STRAINS[key]
    d = np.clip(np.asarray(depth_over_radius, float), 0.0, t.max_depth)
    return u_of(d), slope_of(d)


def elastic_force_nN(time_s: npt.ArrayLike, depth_um: npt.ArrayLike, radius_um: float, bulk_1s_mN_per_m: float,
                     beta: float, gamma_tilde: float, shear_tilde: float, table: ShellTable | None = None,
                     matrix: Array | None = None) -> Array:
    """The cortex's share R U'(d) ∫ K_B(t - t') dU (nN) at the samples (t, δ) of a history
    (δ ≤ 0: no contact); `matrix` the samples' `memory_matrix` at β where already made."""
    d = np.clip(np.asarray(depth_um, float), 0.0, None) / radius_um
    u, slope = strain(d, gamma_tilde, shear_tilde, radius_um, table)
    mm = memory_matrix(time_s, beta) if matrix is None else matrix
    du = np.diff(u, prepend=u[0])
    return bulk_1s_mN_per_m * radius_um * slope * (mm @ du)


def force_nN(time_s: npt.ArrayLike, depth_um: npt.ArrayLike, radius_um: float, tension_mN_per_m: float,
             bulk_1s_mN_per_m: float, beta: float, shear_tilde: float, table: ShellTable | None = None) -> Array:
    """F (nN) of the power-law shell (module doc) along the history (t s, δ µm)."""
    d = np.clip(np.asarray(depth_um, float), 0.0, None) / radius_um
    out = tension_mN_per_m * radius_um * unit_force_per_tension(np.minimum(d, DEPTH_MAX))
    if bulk_1s_mN_per_m > 0:
        out = out + elastic_force_nN(time_s, depth_um, radius_um, bulk_1s_mN_per_m, beta,
                                     tension_mN_per_m / bulk_1s_mN_per_m, shear_tilde, table)
    return out


def clear_caches() -> None:
    """Forget the memory matrices and strain curves kept (`memory_matrix`, `strain`): a cold start."""
    _MEMORY.clear()
    _STRAINS.clear()
