"""One node of the protocol's bias map (SPEC 12): a simulated recording read by the segment fit,
against the relaxed-state frequency-domain model.

A node (`campaign.protocol_grid.BiasNode`) is a shell (K_B, K_S its moduli at 1 s, γ_a,
mean height h_m = h0 - Δh/2), the exponents (β_B, β_S) and its protocol (T_w, f). The cortex
relaxes as

    K_B(t) = K_B (t/1 s)^-β_B,   K_S(t) = K_S (t/1 s)^-β_S

(Prony series, `solver.time_domain.power_law_cortex`, 2 elements a decade); the protocol
(`campaign.protocol_grid.bias_protocol`, simulated by `solver.protocol_simulation.simulate`
at its FINE resolution, 100 Hz and at least 20 samples a period) ramps Δh_m = Δh/2 from h0 to
h_m, holds T_w and oscillates 5 periods of 0.5 µm peak to peak at f. The segment fit (`analysis.afm.synth.time_domain.segment_fit`) gives
|K*|_td and δ_td; the relaxed-state model (`solver.relaxed_state`) |K*|_model and δ_model. The
node's bias:

    modulus_ratio = |K*|_td / |K*|_model,   loss_angle_error_rad = δ_td - δ_model.

A node is one task of the kind `KIND` (`campaign.kinds`; a campaign file's
`[campaign] task = "analysis.afm.synth.protocol_bias:protocol_bias"`): its parameters the shell's and
the protocol's (`campaign.protocol_grid.PROTOCOL_PARAMS`), its own results PROTOCOL_RESULTS beside the
compression's columns it fills (`modulus_mN_per_m`, `loss_angle_rad`, `gamma_eff_mN_per_m`,
`h_tilde`, `h_mean_um`, `wall_s`).
"""

from typing import Any

from analysis.afm.synth.time_domain import segment_fit
from campaign.kinds import Kind, register
from campaign.protocol_grid import PROTOCOL_PARAMS
from solver.protocol_simulation import Sampling, simulate
from solver.relaxed_state import relaxed_state
from solver.time_domain import power_law_cortex

SAMPLING = Sampling(sample_hz=100.0, approach_hz=100.0, min_samples_per_period=20)

PROTOCOL_RESULTS = {"model_modulus_mN_per_m": "mN/m", "model_loss_angle_rad": "rad", "bulk_loss_angle_rad": "rad",
                    "shear_loss_angle_rad": "rad", "modulus_ratio": "1", "loss_angle_error_rad": "rad",
                    "solves": "1"}          # a node's own results (column -> unit)
PROTOCOL_UNITS = dict(zip(PROTOCOL_PARAMS, ("1", "1", "s", "Hz")))   # its protocol's parameters


def node_results(node: Any) -> dict[str, float]:
    """The recording of `node` (a `BiasNode`) and its bias: `modulus_mN_per_m`, `loss_angle_rad`,
    `gamma_eff_mN_per_m` (mean γ_eff), `h_tilde` of the segment fit; the model's
    `model_modulus_mN_per_m`, `model_loss_angle_rad`, `bulk_loss_angle_rad`, `shear_loss_angle_rad`;
    `modulus_ratio`, `loss_angle_error_rad`; `solves` (equilibrium solves)."""
    shell = node.shell
    cortex = power_law_cortex(shell.bulk_mN_per_m, shell.shear_mN_per_m, node.bulk_exponent, node.shear_exponent)
    rec = simulate(shell, cortex, node.protocol, sampling=SAMPLING)
    fit = segment_fit(rec, shell.volume_um3)
    model = relaxed_state(shell, cortex, node.frequency_hz)
    modulus, loss = float(fit["modulus_mN_per_m"]), float(fit["loss_angle_rad"])
    return {"modulus_mN_per_m": modulus, "loss_angle_rad": loss,
            "gamma_eff_mN_per_m": float(fit["tension_mN_per_m"]), "h_tilde": float(fit["h_tilde"]),
            "h_mean_um": shell.h0_um - 0.5 * shell.dh_um,
            "model_modulus_mN_per_m": model["modulus_mN_per_m"], "model_loss_angle_rad": model["loss_angle_rad"],
            "bulk_loss_angle_rad": model["bulk_loss_angle_rad"], "shear_loss_angle_rad": model["shear_loss_angle_rad"],
            "modulus_ratio": modulus / model["modulus_mN_per_m"],
            "loss_angle_error_rad": loss - model["loss_angle_rad"],
            "solves": float(rec.steps)}


KIND = register(Kind("protocol_bias", 1, PROTOCOL_RESULTS, node_results, PROTOCOL_UNITS,
                     doc="one recording of the protocol in time, read against the relaxed-state model (SPEC 12)"))
