"""The frequency-domain reading of a Prony-series cortex: the relaxed-state model (SPEC 10, 12).

The viscoelastic reading linearises about the relaxed droplet at the mean height
h_m = h0 - Δh/2 (no prestress left from the step) with the series' own complex moduli

    K_B* = K_B(iω),   K_S* = K_S(iω)        (`solver.prony.Prony.complex_modulus`, ω = 2π f),

that is the elastic shell with |K_B*|, |K_S*| compressed h0 → h_m (its secant modulus K_sec)
times the complex factor C(δ_B, δ_S) of `solver.viscoelastic.viscoelastic_keys`, δ = arg K*:

    K*(h_m) = K_sec C,   |K*| = `modulus_mN_per_m`,   δ = arg K* = `loss_angle_rad`.

What the time domain's segment fits (`solver.protocol_simulation`, SPEC 12) are compared with.
"""

from dataclasses import replace

import numpy as np

from solver.compression import compress
from solver.model import Shell
from solver.time_domain import Cortex
from solver.viscoelastic import viscoelastic_keys


def relaxed_state(shell: Shell, cortex: Cortex, frequency_hz: float, sparse: bool = False) -> dict[str, float]:
    """|K*| (`modulus_mN_per_m`) and loss angle (`loss_angle_rad`) of the relaxed-state model of
    `shell` (its moduli replaced by the cortex's) at `frequency_hz`, with the moduli's own loss
    angles (`bulk_loss_angle_rad`, `shear_loss_angle_rad`); `sparse`: the linear solves by sparse LU
    (`solver.viscous.respond`)."""
    Kb, Ks = cortex.bulk.complex_modulus(frequency_hz), cortex.shear.complex_modulus(frequency_hz)
    model = replace(shell, bulk_mN_per_m=abs(Kb), shear_mN_per_m=abs(Ks))
    delta_b, delta_s = float(np.angle(Kb)), float(np.angle(Ks))
    keys = viscoelastic_keys(model, compress(model).derived["modulus_mN_per_m"], frequency_hz, delta_b, delta_s,
                             sparse=sparse)
    return {"modulus_mN_per_m": float(keys["modulus_mN_per_m"]), "loss_angle_rad": float(keys["loss_angle_rad"]),
            "bulk_loss_angle_rad": delta_b, "shear_loss_angle_rad": delta_s}
