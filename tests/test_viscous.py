"""The shell around a viscous interior in the frequency domain (solver/viscous.py):
the η → 0 limit against the fast solver's own forces around the same mean
height, the energy balance (the flow's ∫ 2η e:e dV against the plate's mean
power), quasi-static Stokes (K* depends on ωη only), the mesh convergence of
K*, and bad input."""

from dataclasses import replace

import numpy as np
import pytest

from conftest import cortex as run_cortex
from solver import fast, viscous
from common.errors import InputError
from solver.geometry import droplet
from solver.model import Shell

SHELL = Shell(volume_um3=4300.0, h0_um=12.0, dh_um=0.5, bulk_mN_per_m=25.0, shear_mN_per_m=8.33,
              tension_mN_per_m=1.5)


@pytest.fixture(scope="module")
def prepared():
    return viscous.prepare(SHELL)


def fast_small_oscillation_modulus(shell, delta):
    """K from two fast-solver compressions of the stress-free droplet at h0 to
    h_m ± δ: (γ_eff(h_m - δ) - γ_eff(h_m + δ)) / ((A(h_m - δ) - A(h_m + δ)) / A(h_m))."""
    hm = shell.h0_um - 0.5 * shell.dh_um
    h = np.array([hm - delta, hm + delta])
    force = np.array([fast.solve(replace(shell, dh_um=shell.h0_um - x)).force_nN for x in h])
    d, dm = droplet(shell.volume_um3, h), droplet(shell.volume_um3, hm)
    gamma = force / d.force_per_tension_um
    return (gamma[0] - gamma[1]) / ((d.surface_area_um2[0] - d.surface_area_um2[1]) / dm.surface_area_um2)


def test_inviscid_limit_is_the_fast_solvers_modulus(prepared):
    lin, _ = prepared
    K0 = viscous.respond(lin, 0.0, 1.0).complex_modulus
    assert K0.imag == 0.0
    assert K0.real == pytest.approx(fast_small_oscillation_modulus(SHELL, 0.002), rel=1e-3)
    # a vanishing viscosity is continuous with it
    assert viscous.respond(lin, 1e-6, 1.0).complex_modulus == pytest.approx(K0, rel=1e-7)


@pytest.mark.parametrize("eta, f", [(1.0, 10.0), (10.0, 1.0), (0.05, 0.02)])
def test_energy_balance(prepared, eta, f):
    lin, fluid = prepared
    res = viscous.respond(lin, eta, f)
    velocity = viscous.flow(lin, fluid, res, f)
    # mean over a cycle of ∫ 2η e:e dV, both halves, in nN·µm/s (Pa·µm³/s = 1e-3 nN·µm/s)
    dissipation = 2 * 0.5 * eta * np.real(np.conj(velocity) @ (fluid.A @ velocity)) * 1e-3
    assert dissipation > 0 and res.plate_power > 0
    assert dissipation == pytest.approx(res.plate_power, rel=1e-2)
    assert res.dissipation == pytest.approx(dissipation, rel=1e-6)


def test_quasi_static_stokes_depends_on_omega_eta_only(prepared):
    lin, _ = prepared
    a = viscous.respond(lin, 1.0, 10.0).complex_modulus
    b = viscous.respond(lin, 10.0, 1.0).complex_modulus
    assert a == pytest.approx(b, rel=1e-9)
    # weak damping: K'' grows linearly with ωη, K' only at second order
    K0 = viscous.respond(lin, 0.0, 1.0).complex_modulus.real
    k1, k2 = (viscous.respond(lin, eta, 1.0).complex_modulus for eta in (1e-3, 2e-3))
    assert k2.imag / k1.imag == pytest.approx(2.0, rel=1e-4)
    assert abs(k1.real - K0) < 1e-3 * k1.imag
    assert 0 < np.angle(a) < np.pi / 2 and abs(a) > K0


def test_modulus_converges_with_the_fluid_mesh(prepared):
    lin, _ = prepared
    coarse = viscous.prepare(SHELL, h_max=1.0)[0]
    for eta in (1.0, 10.0):
        assert viscous.respond(coarse, eta, 10.0).complex_modulus == pytest.approx(
            viscous.respond(lin, eta, 10.0).complex_modulus, rel=1e-4)


@pytest.mark.parametrize("eta, f", [(-1.0, 1.0), (1.0, 0.0), (float("nan"), 1.0), (1.0, -2.0)])
def test_bad_viscosity_or_frequency(prepared, eta, f):
    with pytest.raises(InputError):
        viscous.respond(prepared[0], eta, f)


def cortex(*args):
    """`cortex compress` of one cell with ARGS added, run as a user runs it (the shared helper)."""
    return run_cortex("compress", "--h0", "12", "--bulk", "25", "--shear", "8.33", "--tension", "1.5", *args,
                      timeout=300)


def test_cli_compress_with_viscosity(prepared):
    import json
    done = cortex("--viscosity", "2", "--frequency", "5", "--json")
    assert done.returncode == 0, done.stderr
    row = json.loads(done.stdout)
    K = viscous.respond(prepared[0], 2.0, 5.0).complex_modulus
    assert row["modulus_mN_per_m"] == pytest.approx(abs(K), rel=1e-9)
    assert row["storage_modulus_mN_per_m"] == pytest.approx(K.real, rel=1e-9)
    assert row["loss_modulus_mN_per_m"] == pytest.approx(K.imag, rel=1e-9)
    assert row["loss_angle_rad"] == pytest.approx(np.angle(K), rel=1e-9)
    assert row["elastic_modulus_mN_per_m"] == pytest.approx(
        viscous.respond(prepared[0], 0.0, 5.0).complex_modulus.real, rel=1e-9)
    for key in ("force_nN", "area_strain", "compression_modulus_mN_per_m", "h_tilde", "converged"):
        assert key in row


@pytest.mark.parametrize("args", [("--viscosity", "-1", "--frequency", "1"),
                                  ("--viscosity", "1", "--frequency", "0"),
                                  ("--viscosity", "1"),
                                  ("--viscosity", "1", "--frequency", "1", "--solver", "explicit")])
def test_cli_bad_viscous_input_one_line_exit_2(args):
    done = cortex(*args, "--json")
    assert done.returncode == 2, done.stderr
    assert done.stdout == "" and len(done.stderr.strip().splitlines()) == 1


def test_no_slip_map_carries_exactly_the_shell_volume_change(prepared):
    # ∮ w·n dS of the fluid's boundary displacement (Σ of the divergence rows:
    # the P1 basis sums to one) equals half the shell polygon's volume change
    # -H_p,q δq / 2 for any δq, the slip of the relabelled nodes included
    lin, fluid = prepared
    n = lin.lag.size
    rng = np.random.default_rng(1)
    for _ in range(3):
        dq = rng.normal(size=n + 1) * 1e-3
        flux = (fluid.B[:, fluid.fixed] @ (lin.G @ dq)).sum()
        assert flux == pytest.approx(-0.5 * lin.H[n - 1] @ dq, rel=1e-7)   # H_p,zp: a difference
    only_l = np.zeros(n + 1)
    only_l[n - 2] = 1.0
    assert np.abs(lin.G @ only_l).max() > 0            # the slip is there, and carries no flux
    assert abs((fluid.B[:, fluid.fixed] @ (lin.G @ only_l)).sum()) < 1e-9 * np.abs(lin.G @ only_l).max()
