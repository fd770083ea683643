"""The viscoelastic cortex oscillated: complex moduli by the correspondence principle.

SPEC section 10. A linear viscoelastic cortex oscillated at small amplitude
answers at ω like the elastic one with its moduli made complex,

    K_B* = K_B e^{iδ_B},   K_S* = K_S e^{iδ_S},   B* = B (K_B* + K_S*)/(K_B + K_S)

(B = t_c² (K_B + K_S)/24 times the variant's factor: `double` doubles it, `none`
keeps it 0; an explicit `bending_pN_um` stays real), while the active tension
γ_a, a prestress, stays real.

Linear response. The cortex's stresses relax within about a minute and the
protocol waits 50-150 s at each mean height, so the cell oscillates around the
*relaxed* state at h_m = h0 - Δh/2: the droplet at h_m with no elastic
prestrain (`relaxed`: compressed 1e-3 µm from a droplet 1e-3 µm above h_m).
There `solver.viscous.linearise` gives the Hessian H of the discrete Lagrangian
in q = (u, z_p). At a fixed state L is linear in (K_B, K_S, B), so H splits
exactly,

    H = H_rest + K_B H_B + K_S H_S + B H_b,

the parts by differences of Hessians of Lagrangians one unit of a modulus
apart at the same state (`hessian_parts`). The complex Hessian is

    H* = H + (K_B* - K_B) H_B + (K_S* - K_S) H_S + (B* - B) H_b,

and K*_lin(ω) is `solver.viscous.respond` with it (and, with a viscosity, the
Stokes interior's c D as there): one dense complex solve per (δ_B, δ_S, η, f).
Without prestrain the state does not depend on the moduli, so K*_lin is the
analytic continuation of the real small-amplitude modulus: to first order
Im K*_lin = δ_B K_B ∂K/∂K_B + δ_S K_S ∂K/∂K_S (tested, 2e-4).

The modulus the experiment sees (SPEC 6 takes K from a 0.5 µm peak-to-peak
oscillation, whose elastic value is the secant K of `solver.compression`):

    K* = K_sec C,   C = K*_lin(δ_B, δ_S, η) / K*_lin(0, 0, 0)

(`correction`), so loss angles 0 and no viscosity give today's K exactly. The
linear response about the relaxed state and the 0.5 µm secant differ by up to
~20 % in K itself (most for tall cells, where dA/dh is small); the factor C
carries only the ratio. Limits: first order in the amplitude; the state at
h_m fully relaxed; γ_a exactly real (a purely active, instantaneous prestress).
"""

import time
from dataclasses import dataclass, replace
from functools import lru_cache

import numpy as np

from common.errors import InputError
from solver.fast.lagrangian import Lagrangian
from solver.model import PN_UM_PER_MN_PER_M_UM2, Shell
from solver.viscous import Linearised, full_hessian, hold_label, linearise, prepare, respond

MODULI = ("bulk", "shear", "bending")     # the parts of H weighted by K_B, K_S and B
RELAX_UM = 1e-3       # the relaxed state at h_m: compressed this far from a droplet at h_m + RELAX_UM


def relaxed(shell: Shell) -> Shell:
    """The shell whose linearisation (`solver.viscous.linearise`) is the relaxed cell at
    h_m = h0 - Δh/2: its reference droplet at h_m + RELAX_UM, compressed by 2 RELAX_UM
    (half of it to h_m), so its elastic prestrain is ~1e-4 (`RELAX_UM`/R_cell)."""
    h_m = shell.h0_um - 0.5 * shell.dh_um
    return replace(shell, h0_um=h_m + RELAX_UM, dh_um=2 * RELAX_UM)


@dataclass
class Parts:
    """The linearised shell and its Hessian's parts per unit K_B, K_S and B."""

    lin: Linearised
    parts: dict                 # MODULI -> (n+1, n+1) array
    moduli: dict                # MODULI -> the real value (mN/m, mN/m, mN/m·µm²)


def _unit_step(lag, shell, name):
    """A Lagrangian on `lag`'s mesh one unit of modulus `name` above `shell`'s (B explicit,
    so that a step in K_B or K_S leaves B as it is)."""
    B = shell.bending_stiffness
    bulk, shear = shell.bulk_mN_per_m, shell.shear_mN_per_m
    step = {"bulk": dict(bulk_mN_per_m=bulk + 1.0), "shear": dict(shear_mN_per_m=shear + 1.0),
            "bending": {}}[name]
    b = (B + (1.0 if name == "bending" else 0.0)) * PN_UM_PER_MN_PER_M_UM2
    other = Lagrangian(replace(shell, bending_pN_um=b, **step), lag.ref)
    other.V0, other.area0 = lag.V0, lag.area0
    return other


def hessian_parts(shell: Shell, lin: Linearised | None = None) -> Parts:
    """The linearisation of `shell` at h_m (`solver.viscous.linearise`, or `lin`
    given) and the parts ∂H/∂K_B, ∂H/∂K_S, ∂H/∂B of its Hessian at that state."""
    lin = lin if lin is not None else linearise(relaxed(shell))
    lin.shell = shell
    lag, u, zp = lin.lag, lin.u, lin.zp
    base = lin.H.copy()
    if lin.held:
        hold_label(base, 0.0)
    H0 = full_hessian(lag, u, zp)
    if lin.held:
        hold_label(H0, 0.0)
    parts = {}
    for name in MODULI:
        Hk = full_hessian(_unit_step(lag, shell, name), u, zp)
        if lin.held:
            hold_label(Hk, 0.0)
        parts[name] = Hk - H0
    moduli = {"bulk": shell.bulk_mN_per_m, "shear": shell.shear_mN_per_m, "bending": shell.bending_stiffness}
    return Parts(lin=lin, parts=parts, moduli=moduli)


def complex_moduli(shell: Shell, bulk_loss_angle_rad: float, shear_loss_angle_rad: float) -> dict:
    """K_B*, K_S*, B* (complex; mN/m and mN/m·µm²) of `shell` at the loss angles."""
    kb = shell.bulk_mN_per_m * np.exp(1j * bulk_loss_angle_rad)
    ks = shell.shear_mN_per_m * np.exp(1j * shear_loss_angle_rad)
    B = shell.bending_stiffness
    total = shell.bulk_mN_per_m + shell.shear_mN_per_m
    if shell.bending_pN_um is None and total > 0:
        b = B * ((kb + ks) / total)
    else:
        b = complex(B)
    return {"bulk": kb, "shear": ks, "bending": b}


def extra_hessian(parts: Parts, bulk_loss_angle_rad: float, shear_loss_angle_rad: float) -> np.ndarray:
    """H* - H = Σ_k (M_k* - M_k) ∂H/∂M_k over the moduli M = K_B, K_S, B."""
    star = complex_moduli(parts.lin.shell, bulk_loss_angle_rad, shear_loss_angle_rad)
    return sum((star[k] - parts.moduli[k]) * parts.parts[k] for k in MODULI)


def check_loss_angles(*angles: float) -> None:
    for a in angles:
        if not (np.isfinite(a) and 0.0 <= a < np.pi / 2):
            raise InputError(f"a loss angle must be a finite number in [0, pi/2) rad (got {a:g})")


def complex_response(parts: Parts, bulk_loss_angle_rad: float, shear_loss_angle_rad: float,
                     frequency_hz: float, viscosity_Pa_s: float = 0.0, sparse: bool = False) -> complex:
    """K*(ω) (mN/m) of the linearised shell with complex moduli (and the interior's viscosity,
    which needs `parts.lin` from `solver.viscous.prepare`; `sparse`: `solver.viscous.respond`'s)."""
    check_loss_angles(bulk_loss_angle_rad, shear_loss_angle_rad)
    if viscosity_Pa_s and parts.lin.D is None:
        raise InputError("a viscous interior needs the fluid's condensation (solver.viscous.prepare)")
    extra = extra_hessian(parts, bulk_loss_angle_rad, shear_loss_angle_rad)
    return respond(parts.lin, viscosity_Pa_s, frequency_hz, extra, sparse).complex_modulus


@lru_cache(maxsize=4)
def _prepared(shell, viscous):
    lin = prepare(relaxed(shell))[0] if viscous else linearise(relaxed(shell))
    if not viscous:
        lin.D = None
    return hessian_parts(shell, lin)


def correction(parts: Parts, bulk_loss_angle_rad: float, shear_loss_angle_rad: float,
               frequency_hz: float, viscosity_Pa_s: float = 0.0) -> complex:
    """C = K*(δ_B, δ_S, η) / K*(0, 0, 0): the linear response's complex factor over its
    own elastic value (one linearisation), which turns an elastic K into K*."""
    K = complex_response(parts, bulk_loss_angle_rad, shear_loss_angle_rad, frequency_hz, viscosity_Pa_s)
    return K / respond(parts.lin, 0.0, frequency_hz).complex_modulus


def viscoelastic_keys(shell: Shell, elastic_modulus: float, frequency_hz: float, bulk_loss_angle_rad: float,
                      shear_loss_angle_rad: float, viscosity_Pa_s: float = 0.0, sparse: bool = False) -> dict:
    """K* = K C of `shell` (no viscosity or frequency of its own) whose elastic
    compression gave `elastic_modulus` K (mN/m), oscillated at `frequency_hz` around
    h_m = h0 - Δh/2 with the loss angles (and a viscous interior, η > 0):
    `modulus_mN_per_m` = |K*|, `storage_modulus_mN_per_m`, `loss_modulus_mN_per_m`,
    `loss_angle_rad`, `linear_modulus_mN_per_m` (|K*| of the linear response alone),
    `linear_elastic_modulus_mN_per_m` (its value without loss angles or viscosity) and the wall time
    (`sparse`: the shell's solves by sparse LU, `solver.viscous.respond`)."""
    start = time.perf_counter()
    check_loss_angles(bulk_loss_angle_rad, shear_loss_angle_rad)
    eta = float(viscosity_Pa_s or 0.0)
    parts = _prepared(replace(shell, viscosity_Pa_s=None, frequency_hz=None), eta > 0)
    lin = complex_response(parts, bulk_loss_angle_rad, shear_loss_angle_rad, frequency_hz, eta, sparse)
    base = respond(parts.lin, 0.0, frequency_hz, sparse=sparse).complex_modulus.real
    K = elastic_modulus * lin / base
    return {"viscosity_Pa_s": eta, "frequency_hz": float(frequency_hz),
            "bulk_loss_angle_rad": float(bulk_loss_angle_rad), "shear_loss_angle_rad": float(shear_loss_angle_rad),
            "modulus_mN_per_m": abs(K), "storage_modulus_mN_per_m": K.real, "loss_modulus_mN_per_m": K.imag,
            "loss_angle_rad": float(np.angle(K)), "linear_modulus_mN_per_m": abs(lin),
            "linear_elastic_modulus_mN_per_m": float(base), "h_mean_um": parts.lin.h_mean_um,
            "viscoelastic_wall_s": time.perf_counter() - start}
