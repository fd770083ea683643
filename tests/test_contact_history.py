"""The history's share of the contact line's balance in the time-domain shell (SPEC 2, 12;
`solver.fast.contact.carry_history`, `history_share`, `TimeShell(contact_history=True)`): it is
the derivative of the step's energy in the contact label with the stored history carried by its
material, and switching it on moves an oscillation's |K*| and loss angle by what
docs/studies/contact-history.md records."""

import numpy as np
import pytest

from analysis.afm.synth.time_domain import recording_cell
from analysis.afm.timeseries import segment_moduli
from solver.fast import _follow_scale, _newton
from solver.fast.contact import carry_history, history_share
from solver.model import Shell
from solver.protocol import Protocol
from solver.protocol_simulation import simulate
from solver.time_domain import TimeShell, power_law_cortex

R_UM = 7.0
V = 4.0 / 3.0 * np.pi * R_UM**3


def _energy_and_balance(state, lag, history, h_um, label, start):
    """E*(l) at fixed label with the history carried to it, g_l and G_hist there."""
    u = start.copy()
    u[-2] = label
    dpa, dps = carry_history(label, lag.ref.zeta, lag.ref.xi, history, lag.terms)
    u, g, _, _ = _newton(lag, u, 0.5 * h_um, tol=1e-8)
    r0, z0 = lag.ref.positions(label)[:2]
    share = history_share(u, 0.5 * h_um, r0, z0, lag.N, lag.kc, lag.nd, dpa, dps)
    return lag.newton_system(u, 0.5 * h_um, hessian=False)[0], g[-2], share, u


def test_history_share_is_the_derivative_of_the_energy_in_the_label():
    """A power-law cortex (β_B 0.1, β_S 0.3) ramped 0.5 µm and oscillated a little: at labels
    either side of the solved one, g_l + G_hist is the central difference of E*(l) with the
    history carried (to 1e-5 of G_hist), and the history's share is of the order of the elastic
    one (found -0.086 against 0.090 below the solved label): not a correction to neglect."""
    shell = Shell(volume_um3=V, h0_um=9.0, bulk_mN_per_m=25.0, shear_mN_per_m=20.0, tension_mN_per_m=1.0)
    state = TimeShell(shell, power_law_cortex(25.0, 20.0, 0.1, 0.3), contact_history=True)
    for k in range(1, 11):
        state.advance(9.0 - 0.05 * k, 0.25)
    for k in range(5):
        state.advance(8.5 + 0.05 * np.sin(k), 0.1)
    h_um, dt_s = 8.55, 0.1
    lag = state._step_lagrangian(dt_s)
    _follow_scale(lag, shell, h_um)
    pa, ps = (ch.history(dt_s) for ch in state.channels)
    lag.terms = lag.terms._replace(pa=pa.copy(), ps=ps.copy())
    history = (state.labels(state._label), pa[lag.nd:].copy(), ps[lag.nd:].copy())
    start = state.u.copy()
    start[lag.N: -2] *= h_um / state.h_um
    shares = []
    for label in (state.u[-2] - 0.2, state.u[-2] + 0.1):
        _, g_l, share, u = _energy_and_balance(state, lag, history, h_um, label, start)
        eps = 1e-4
        plus, minus = (_energy_and_balance(state, lag, history, h_um, label + s, u)[0] for s in (eps, -eps))
        assert (plus - minus) / (2 * eps) == pytest.approx(g_l + share, abs=1e-5 * abs(share))
        shares.append((g_l, share))
    assert all(share < -0.5 * g_l < 0 for g_l, share in shares)


def _cell(radius_um, bulk_exponent, shear_exponent, contact_history, freqs=(0.1, 1.0, 10.0)):
    """A cell (γ_a 1 mN/m, K_B 25, K̃_S 0.8) stepped 0.5 µm to h̃ = 0.6 from its relaxed droplet,
    waited 100 s, oscillated 0.25 µm at 0.1, 1 and 10 Hz, 5 periods each (FINE), read by the
    segment fit."""
    volume = 4.0 / 3.0 * np.pi * radius_um**3
    h_m = 1.2 * radius_um
    shell = Shell(volume_um3=volume, h0_um=h_m + 0.5, bulk_mN_per_m=25.0, shear_mN_per_m=20.0,
                  tension_mN_per_m=1.0)
    protocol = Protocol.stepped(h_m + 0.5, (h_m,), freqs, (5,) * len(freqs), wait_s=100.0)
    cortex = power_law_cortex(25.0, 20.0, bulk_exponent, shear_exponent)
    return segment_moduli(recording_cell(simulate(shell, cortex, protocol, contact_history=contact_history), volume))


def test_the_history_share_moves_the_reading_by_what_the_study_records():
    """R 5 µm, β_B 0.1, β_S 0.3: switching the history's share on moves |K*| by +2.5e-4,
    +3.5e-4, +5.6e-4 (relative) and the loss angle by +0.00005, +0.000004, -0.00036 rad at 0.1,
    1, 10 Hz: within the 1 % and 0.005 rad asked, and not nothing (each step's label settled at
    its history brings the held balance within 0.0005 rad of the complete one; carried by
    extrapolation alone the loss angle moved by up to 0.0015 rad)."""
    off, on = (_cell(5.0, 0.1, 0.3, switch) for switch in (False, True))
    dK = [b["modulus_mN_per_m"] / a["modulus_mN_per_m"] - 1.0 for a, b in zip(off, on)]
    dd = [b["loss_angle_rad"] - a["loss_angle_rad"] for a, b in zip(off, on)]
    assert np.max(np.abs(dK)) < 1e-3
    assert np.max(np.abs(dd)) < 5e-4
    assert np.max(np.abs(dd)) > 1e-6                  # the switch acts


def test_with_the_history_share_a_high_exponent_cell_oscillates_cleanly():
    """R 7 µm, β_B = β_S = 0.4, the history's share on: the force follows a sinusoid at 0.1 and
    1 Hz (segment fit r² ≥ 0.99; found 0.9957, 0.9961; without the share the contact label's
    jumps take the 1 Hz fit down to 0.973). At 10 Hz the plate's upstroke outruns the cell: the
    force reaches zero at 8.55 µm and the plate would have to pull, which the shell refuses."""
    for row in _cell(7.0, 0.4, 0.4, True, (0.1, 1.0)):
        assert row["fit_r2_gamma"] >= 0.99
