"""The frequency-domain reading of a Prony-series cortex: the waited-state model (SPEC 10, 12).

The bias map's protocol (`solver.protocol.Protocol`: a ramp, a hold, an oscillation) ramps the
plate from the stress-free droplet at h0 to h_m = h0 - Δh/2 in t_r = Δh_m / v (0.25 µm at 0.2 µm/s: 1.25 s), waits T_w and oscillates at
f. A power-law cortex has not relaxed by then: an element strained by a (a = e1 + e2, and
likewise s = e1 - e2) over the ramp carries

    σ_a(t) = ∫ K_B(t - t') da(t') ≈ K_B(t_w) a,   t_w = T_w + t_r/2,

(a ramp linear in time: the mean of K_B over [T_w, T_w + t_r], which is K_B(T_w + t_r/2) to
second order in t_r/T_w; `waited_time_s`). The waited state is the elastic shell with the
moduli the cortex has then,

    K_B,w = K_B(t_w),   K_S,w = K_S(t_w)        (`solver.prony.Prony.relaxation`),

compressed h0 → h_m (`solver.viscous.linearise`): its strains, its prestress
σ = K_w a and its plate force F_0 (the mean tension γ_0 = F_0 / g(h_m)). Oscillated there, the
stress increment is K*(ω) δa on the material stiffness M while the prestress stays what it is
(the geometric stiffness G real):

    H*(ω) = H_w + (K_B* - K_B,w) M_B + (K_S* - K_S,w) M_S,   K_B* = K_B(iω), K_S* = K_S(iω)

(`studies.prestressed_response`: linearised about the waited state, label free where it is
stationary), and `solver.viscous.respond` reads it as the experiment does: K*_w(ω) = δγ_eff / ε̂_A
(`linear_modulus_mN_per_m` = |K*_w|). As in `solver.relaxed_state`, the experiment's 0.5 µm
peak-to-peak oscillation is given the secant of the elastic shell and the linear response only
the ratio:

    K* = K_sec,w C_w,   C_w = K*_w(ω) / K_w,   |K*| = `modulus_mN_per_m`,   δ = arg K*_w = `loss_angle_rad`,

K_sec,w the secant modulus of the waited shell compressed h0 → h0 - Δh (`solver.compression`),
K_w its linear response with real moduli (the same state, extra = 0). For an elastic cortex
(β = 0: K(t_w) = K* = K) this is `solver.relaxed_state` exactly (C = 1 both). Bending as the
shell has it (the protocol map's is "none"; a real B stays real, as γ_a does).

The prestress K(t_w) a is the time domain's (its mean tension γ_0 within 0.4 % on the bias
map's physiological nodes, `bench/waited_state.py`); what separates the model from the time
domain there is the contact label: the time domain's lags the waited equilibrium's (its history
is left out of dE/dl), and about the waited state with the time domain's label held the two
|K*| agree to -0.4..+1.1 % (docs/studies/waited-state.md).

Limits: the strains creep during the wait (γ_a and the relaxing moduli redistribute them; a
different β_B and β_S turn the ratio K_S/K_B), which K(t_w) a of the final strains ignores; the
prestress keeps relaxing during the oscillation (5 periods: T_w → T_w + 5/f), which the
segment fit's drift takes out; first order in the 0.25 µm amplitude.
"""

from dataclasses import replace

import numpy as np

from common.errors import InputError
from solver.compression import compress
from solver.model import Shell
from solver.protocol import Protocol, Ramp
from studies.prestressed_response import complex_response
from solver.time_domain import Cortex
from solver.viscous import linearise, respond


def waited_time_s(protocol: Protocol) -> float:
    """t_w = T_w + t_r/2 (s): the time from the middle of the protocol's first ramp
    (t_r = Δh_m / v, from its start to a height) to the start of its first oscillation, the
    holds between making T_w."""
    ramp = protocol.steps[0]
    if not (isinstance(ramp, Ramp) and ramp.to_um is not None):
        raise InputError("the waited state needs a protocol that starts with a ramp to a height")
    ramp_s = abs(protocol.start_um - ramp.to_um) / ramp.speed_um_per_s
    return float(protocol.ages_s()[0] + 0.5 * ramp_s)


def waited_moduli(cortex: Cortex, waited_s: float) -> tuple[float, float]:
    """(K_B(t_w), K_S(t_w)) in mN/m: the relaxation moduli at t_w (s)."""
    return float(cortex.bulk.relaxation(waited_s)), float(cortex.shear.relaxation(waited_s))


def waited_state(shell: Shell, cortex: Cortex, frequency_hz: float, waited_s: float) -> dict[str, float]:
    """|K*| (`modulus_mN_per_m`) and loss angle (`loss_angle_rad`) of the waited-state model of
    `shell` (h0 and h_m = h0 - Δh/2 its own, its moduli replaced by the cortex's at t_w =
    `waited_s`) at `frequency_hz`, with the moduli's own loss angles (`bulk_loss_angle_rad`,
    `shear_loss_angle_rad`), the waited moduli (`bulk_waited_mN_per_m`, `shear_waited_mN_per_m`)
    and the linear response's |K*_w| (`linear_modulus_mN_per_m`)."""
    Kb, Ks = cortex.bulk.complex_modulus(frequency_hz), cortex.shear.complex_modulus(frequency_hz)
    bulk, shear = waited_moduli(cortex, waited_s)
    model = replace(shell, bulk_mN_per_m=bulk, shear_mN_per_m=shear, viscosity_Pa_s=None, frequency_hz=None)
    lin = linearise(model)
    lin.shell = model
    linear = complex_response(lin, model, Kb, Ks, frequency_hz)
    K = compress(model).derived["modulus_mN_per_m"] * linear / respond(lin, 0.0, frequency_hz).complex_modulus.real
    return {"modulus_mN_per_m": float(abs(K)), "loss_angle_rad": float(np.angle(K)),
            "bulk_loss_angle_rad": float(np.angle(Kb)), "shear_loss_angle_rad": float(np.angle(Ks)),
            "bulk_waited_mN_per_m": bulk, "shear_waited_mN_per_m": shear,
            "linear_modulus_mN_per_m": float(abs(linear))}
