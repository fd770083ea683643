"""The waited-state model (`studies.waited_state`, SPEC 12) against the protocol simulated in time
on nodes of the bias map (`campaigns/protocol.toml`, `analysis.afm.synth.protocol_bias`), and its
reduction to the relaxed-state model for an elastic cortex."""

import pytest

from analysis.afm.synth.protocol_bias import SAMPLING
from analysis.afm.synth.time_domain import segment_fit
from campaign.protocol_grid import bias_protocol
from solver.geometry import cell_radius
from solver.model import Shell
from solver.protocol_simulation import simulate
from solver.relaxed_state import relaxed_state
from solver.time_domain import power_law_cortex
from studies.waited_state import waited_state, waited_time_s

V = 4300.0


def map_shell(h_tilde: float, ks_tilde: float, gamma_tilde: float) -> Shell:
    """A shell of the bias map's grid: h_m = 2 R_cell h̃, h0 = h_m + Δh/2, K_B(1 s) = 25 mN/m."""
    h0 = 2.0 * float(cell_radius(V)) * h_tilde + 0.25
    return Shell(volume_um3=V, h0_um=h0, bulk_mN_per_m=25.0, shear_mN_per_m=25.0 * ks_tilde,
                 tension_mN_per_m=25.0 * gamma_tilde, dh_um=0.5, thickness_um=0.2, bending="none")


def test_an_elastic_cortex_is_the_relaxed_state_model():
    """β = 0: K(t_w) = K* = K, so both models are the secant K_sec of h0 -> h0 - Δh, loss 0;
    t_w is the wait plus half the ramp (0.25 µm at 0.2 µm/s)."""
    shell = map_shell(0.7, 1.28, 0.032)
    cortex = power_law_cortex(25.0, 32.0, 0.0, 0.0)
    t_w = waited_time_s(bias_protocol(shell, 100.0, 1.0))
    assert t_w == pytest.approx(100.625)
    waited, relaxed = waited_state(shell, cortex, 1.0, t_w), relaxed_state(shell, cortex, 1.0)
    assert waited["modulus_mN_per_m"] == pytest.approx(relaxed["modulus_mN_per_m"], rel=1e-9)
    assert waited["loss_angle_rad"] == pytest.approx(0.0, abs=1e-12) == relaxed["loss_angle_rad"]
    assert waited["bulk_waited_mN_per_m"] == 25.0


# node (h̃, K̃_S, γ̃_a, β_B, β_S, T_w s, f Hz), the waited model's measured errors
# (|K*| td/model - 1, δ_td - δ_model), and the relaxed model's |K*| error (bench/waited_state.py)
NODES = [
    ((0.55, 0.16, 0.128, 0.1, 0.2, 100.0, 0.1), (+0.0013, -0.0044), +0.0093),   # map node 201
    ((0.7, 1.28, 0.032, 0.1, 0.2, 100.0, 1.0), (-0.0155, -0.0050), -0.0240),    # 842
    ((0.7, 1.28, 0.032, 0.4, 0.4, 100.0, 1.0), (+0.0202, +0.0081), -0.1040),    # 826
]


@pytest.mark.parametrize("node, waited_error, relaxed_error", NODES)
def test_waited_state_against_the_protocol_in_time(node, waited_error, relaxed_error):
    """The segment fit of the simulated recording against the waited-state model: |K*| within
    2.5 % and the loss angle within 0.009 rad (found up to 2.02 % and 0.0081 rad on these
    nodes; the rest of the gap is the time domain's contact label, docs/studies/waited-state.md:
    at β 0.4 each step's label settled at its history gives node 826's loss angle +0.0081 rad,
    as the history's share of the contact balance does, +0.0061 carried by extrapolation alone),
    where the relaxed-state model is 10 % off at β = 0.4. Each error is pinned to its measured
    value."""
    h_tilde, ks_tilde, gamma_tilde, beta_b, beta_s, wait_s, f = node
    shell = map_shell(h_tilde, ks_tilde, gamma_tilde)
    cortex = power_law_cortex(25.0, shell.shear_mN_per_m, beta_b, beta_s)
    protocol = bias_protocol(shell, wait_s, f)
    fit = segment_fit(simulate(shell, cortex, protocol, sampling=SAMPLING), V)
    model = waited_state(shell, cortex, f, waited_time_s(protocol))
    modulus_error = fit["modulus_mN_per_m"] / model["modulus_mN_per_m"] - 1.0
    loss_error = fit["loss_angle_rad"] - model["loss_angle_rad"]
    assert abs(modulus_error) < 0.025 and abs(loss_error) < 0.009
    assert (modulus_error, loss_error) == pytest.approx(waited_error, abs=5e-4)
    relaxed = relaxed_state(shell, cortex, f)["modulus_mN_per_m"]
    assert fit["modulus_mN_per_m"] / relaxed - 1.0 == pytest.approx(relaxed_error, abs=5e-4)
