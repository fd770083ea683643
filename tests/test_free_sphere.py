"""The time-domain shell's robust step (`TimeShell.advance`) and the cortex that forgets
(`Prony.forgetting`, τ_c): the limits of issue 42 against the elastic solver and the droplet."""

from dataclasses import replace

import numpy as np
import pytest

from common.errors import InputError, SolverError
from solver.time_domain import power_law_cortex
from solver import fast
from solver.compression import compress
from solver.model import Shell
from solver.prony import Prony, fit_power_law
from solver.time_domain import Cortex, TimeShell

R = 6.8
V_SMALL = 4.0 * np.pi / 3.0 * R**3
SMALL = Shell(volume_um3=V_SMALL, h0_um=2 * R - 0.01, bulk_mN_per_m=25.0, shear_mN_per_m=8.33,
              tension_mN_per_m=0.5)                       # the small stiff cell
PAPER = Shell(volume_um3=4300.0, h0_um=12.5, bulk_mN_per_m=25.0, shear_mN_per_m=8.33, tension_mN_per_m=1.5)
ELASTIC = Cortex(Prony(25.0), Prony(8.33))
ELASTIC_STIFF = Cortex(Prony(50.0), Prony(100.0))


def _ramp(shell, cortex, depth_um, step_um, speed_um_per_s=1.0):
    """The force (nN) at each call of a ramp from shell.h0_um down by `depth_um` in calls of
    `step_um`, and the state."""
    state = TimeShell(shell, cortex)
    gaps = shell.h0_um - np.r_[np.arange(step_um, depth_um - 1e-9, step_um), depth_um]
    return np.array([state.advance(h, step_um / speed_um_per_s) for h in gaps]), state


@pytest.mark.parametrize("step_um", [0.05, 0.15, 0.7])
def test_beta_zero_is_the_elastic_solver_from_near_the_free_sphere(step_um):
    """The issue's cell (R 6.8 µm, γ_a 0.5, K_B 25, K_S 8.33) pressed from 2R - 0.01 µm to
    1.4 µm deep in calls of 0.05, 0.15 (plain steps failed after 2-3 of either) and 0.7 µm: every
    call finds its equilibrium, and the force after the first call and at 1.4 µm is
    `solver.compress`'s to 0.1 % (found at most 8.3e-6)."""
    forces, state = _ramp(SMALL, ELASTIC, 1.4, step_um)
    assert state.h_um == pytest.approx(SMALL.h0_um - 1.4)
    for depth, force in ((step_um, forces[0]), (1.4, forces[-1])):
        assert force == pytest.approx(compress(replace(SMALL, dh_um=depth)).solution.force_nN, rel=1e-3)


def test_beta_zero_is_the_elastic_solver_at_a_paper_height():
    """h0 12.5 → 12 µm (V 4300 µm³) in one call: compress's force to 0.1 % (found 7e-8)."""
    force = TimeShell(PAPER, ELASTIC).advance(12.0, 2.5)
    assert force == pytest.approx(compress(PAPER).solution.force_nN, rel=1e-3)


STIFF_SMALL = Shell(volume_um3=4.0 * np.pi / 3.0 * 5.0**3, h0_um=10.0 - 0.01, bulk_mN_per_m=50.0,
                    shear_mN_per_m=100.0, tension_mN_per_m=0.2)   # the grid's worst β = 0 corner


def test_beta_zero_ramp_ends_where_compress_does_where_the_contact_has_two_minima():
    """R 5 µm, γ_a 0.2, K_B 50, K̃_S 2 pressed from 2R - 0.01 µm in calls of 0.25 µm: at δ 0.76
    and 1.01 µm E*(l) has two admissible minima (the label where the free surface touches the
    plate, which a continued step reaches first, and a lower one above it, compress's); the
    time-domain force and the elastic continuation's are compress's to 0.1 % (found 4e-11 and
    2e-8; 4.7e-3 on the touching label)."""
    forces, _ = _ramp(STIFF_SMALL, ELASTIC_STIFF, 1.0, 0.25)
    lag = fast.problem(STIFF_SMALL)
    u, h, step, last = fast.reference_state(lag), STIFF_SMALL.h0_um, None, None
    for depth, force in zip((0.25, 0.5, 0.75, 1.0), forces):
        u, _, step, last = fast.advance(lag, STIFF_SMALL, u, h, STIFF_SMALL.h0_um - depth, step, last)
        h = STIFF_SMALL.h0_um - depth
        if depth >= 0.75:
            expected = compress(replace(STIFF_SMALL, dh_um=depth)).solution.force_nN
            assert force == pytest.approx(expected, rel=1e-3)
            assert fast.plate_force_nN(lag, u, h) == pytest.approx(expected, rel=1e-3)


def test_the_contact_search_keeps_the_lower_of_two_admissible_labels():
    """At δ 0.76 µm of that cell, the search from just above the touching label (where E*(l)
    falls towards it) ends there (G = dE*/dl > 0, held by the plate); `lowest_contact` also finds the minimum with G = 0 above
    it, 0.07 higher in log ψ_c, its free surface below the plate and E* lower (by 2.8e-4
    mN/m·µm²), and keeps that."""
    shell = replace(STIFF_SMALL, dh_um=0.75)
    lag, zp = fast.problem(shell), 0.5 * shell.h1_um
    lowest, _ = fast.lowest_contact(lag, shell, fast.equilibrium(shell)[1], zp)
    start = lowest.copy()
    start[-2] -= 0.065
    touching, _ = fast._contact(lag, start, zp, retreat=True)
    assert lag.newton_system(touching, zp, hessian=False)[1][-2] > 1e-3 * lag.force_scale
    assert fast._gap(lag, touching, zp) == pytest.approx(0.0, abs=1e-5)
    assert abs(lag.newton_system(lowest, zp, hessian=False)[1][-2]) < 1e-6 * lag.force_scale
    assert fast._gap(lag, lowest, zp) < -1e-4 and lowest[-2] - touching[-2] > 0.05
    assert fast.equilibrium_energy(lag, lowest, zp) < fast.equilibrium_energy(lag, touching, zp) - 1e-4
    again, _ = fast.lowest_contact(lag, shell, start, zp)
    assert again[-2] == pytest.approx(lowest[-2], abs=1e-4)


def _maxwell(dh_um=0.5):
    """A cortex of one Maxwell element beside a spring (τ 1 s) and the shell, bending fixed."""
    cortex = Cortex(Prony(10.0, (15.0,), (1.0,)), Prony(3.0, (5.33,), (1.0,)))
    shell = replace(PAPER, dh_um=dh_um, bending_pN_um=PAPER.bending_stiffness * 1000.0)
    return cortex, shell


def test_a_maxwell_element_is_instant_then_relaxed():
    """A step h0 → h1 in 1e-4 s (≪ τ) pushes with K_∞ + K_1 (the elastic solver at 25, 8.33),
    a hold of 1e4 s (≫ τ) after it with K_∞ (10, 3): both within 1 % (found 6e-6 and 2e-7)."""
    cortex, shell = _maxwell()
    state = TimeShell(shell, cortex)
    instant = state.advance(shell.h1_um, 1e-4)
    assert instant == pytest.approx(compress(replace(shell, bulk_mN_per_m=25.0, shear_mN_per_m=8.33)
                                             ).solution.force_nN, rel=0.01)
    relaxed = state.advance(shell.h1_um, 1e4)
    assert relaxed == pytest.approx(compress(replace(shell, bulk_mN_per_m=10.0, shear_mN_per_m=3.0)
                                             ).solution.force_nN, rel=0.01)
    assert relaxed < 0.95 * instant


def test_memory_cuts_the_power_law_off_exactly():
    """fit_power_law with τ_c: K_0 t^-β e^{-t/τ_c} to the uncut fit's relative error (4e-4),
    K_∞ turned into a Maxwell element of time τ_c; τ_c = inf the same series as without it;
    τ_c <= 0 refused."""
    t = np.logspace(-2, 3, 41)
    plain = fit_power_law(0.2, 25.0)
    cut = fit_power_law(0.2, 25.0, memory_s=30.0)
    assert cut.prony.infinity == 0.0 and cut.elements == plain.elements + 1
    assert np.allclose(cut.prony.relaxation(t), 25.0 * t**-0.2 * np.exp(-t / 30.0), rtol=4e-4, atol=0)
    assert fit_power_law(0.2, 25.0, memory_s=np.inf) == plain
    assert power_law_cortex(25.0, 8.33, 0.1, 0.3, memory_s=np.inf) == power_law_cortex(25.0, 8.33, 0.1, 0.3)
    assert fit_power_law(0.0, 25.0, memory_s=5.0).prony == Prony(0.0, (25.0,), (5.0,))
    separate = power_law_cortex(25.0, 8.33, 0.1, 0.3, memory_s=30.0, shear_memory_s=5.0)
    assert separate.shear == fit_power_law(0.3, 8.33, memory_s=5.0).prony
    for bad in (0.0, -1.0, np.nan):
        with pytest.raises(InputError, match="memory"):
            fit_power_law(0.2, 25.0, memory_s=bad)


def test_memory_zero_is_the_relaxed_state_and_infinity_todays_model():
    """τ_c → 0 (1e-6 s, steps of 0.1 s): the force of h0 → h1 is the relaxed shell's (tension
    only, the elastic solver at moduli 1e-9; no bending, which stays elastic) to 1e-4 (found
    5e-7). τ_c 1e7 s gives the force of τ_c = inf to 1e-5 (found 2e-8); inf pushes 1.25 times
    harder than the relaxed state."""
    shell = replace(PAPER, bending="none")
    forces = {}
    for memory in (1e-6, 1e7, np.inf):
        cortex = power_law_cortex(25.0, 8.33, 0.2, 0.2, memory_s=memory)
        forces[memory] = _ramp(shell, cortex, 0.5, 0.1, speed_um_per_s=0.2)[0][-1]
    relaxed = compress(replace(shell, bulk_mN_per_m=1e-9, shear_mN_per_m=1e-9)).solution.force_nN
    assert forces[1e-6] == pytest.approx(relaxed, rel=1e-4)
    assert forces[1e7] == pytest.approx(forces[np.inf], rel=1e-5)
    assert forces[np.inf] > 1.2 * forces[1e-6]


@pytest.mark.parametrize("radius, tension, bulk, ks, beta", [
    (5.0, 0.2, 50.0, 2.0, 0.4), (10.0, 2.0, 5.0, 0.1, 0.0), (5.0, 0.2, 50.0, 0.1, 0.2)])
def test_ramps_from_the_free_sphere_reach_half_the_diameter(radius, tension, bulk, ks, beta):
    """Corners of the physiological range (stiffest and softest): from 2R - 0.01 µm to h = R at
    1 µm/s in calls of 0.5 µm, every call finds its equilibrium; at β = 0 the last force is the
    elastic solver's to 0.1 %."""
    shell = Shell(volume_um3=4.0 * np.pi / 3.0 * radius**3, h0_um=2 * radius - 0.01, bulk_mN_per_m=bulk,
                  shear_mN_per_m=ks * bulk, tension_mN_per_m=tension)
    depth = shell.h0_um - radius
    forces, state = _ramp(shell, power_law_cortex(bulk, ks * bulk, beta, beta), depth, 0.5)
    assert state.h_um == pytest.approx(radius) and np.all(np.diff(forces) > 0)
    if beta == 0.0:
        assert forces[-1] == pytest.approx(compress(replace(shell, dh_um=depth)).solution.force_nN, rel=1e-3)


def test_a_step_that_never_finds_an_equilibrium_leaves_the_state_as_it_was(monkeypatch):
    """Where every sub-step fails, advance halves down to its smallest fraction, then raises
    SolverError with the state (gap, unknowns, history) untouched."""
    cortex = power_law_cortex(25.0, 8.33, 0.2, 0.2)
    state = TimeShell(PAPER, cortex)
    state.advance(12.3, 1.0)
    before = state.saved()

    def never(self, *args, **kwargs):
        raise SolverError("never")
    monkeypatch.setattr(TimeShell, "_equilibrium", never)
    with pytest.raises(SolverError, match="no equilibrium"):
        state.advance(12.0, 1.0)
    assert state.h_um == before[1] and np.array_equal(state.u, before[0])
    assert np.array_equal(state.channels[0].viscous, before[-1][0][1])
