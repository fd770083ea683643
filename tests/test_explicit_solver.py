"""The explicit reference scheme (solver.explicit, solver.explicit.surface_forces):
its forces are the energy's gradient and the (corrected) SPEC force densities,
and its compressions reproduce the droplet force, hold the volume and satisfy
the force balance across the equator."""

import numpy as np
import pytest

from solver import explicit
from solver.explicit import surface_forces as sf
from common.errors import SolverError
from solver.geometry import droplet
from solver.model import Shell


def _ellipsoid(t, a=6.0, c=5.0):
    return a * np.sin(t) * (1 + 0.05 * np.cos(t) ** 2), c * np.cos(t)


def _spec_density(t, R0, gamma, KB, KS, B, H0):
    """SPEC section 2 force densities on the smooth surface _ellipsoid, stretched
    from the sphere of radius R0 (same parameter t), by finite differences:
    tension -2γH n; bending B(2Δ(H-H0) + 4(2H²-K_G)(H-H0) - 4H(H-H0)²) n;
    stretching -(2H n - ∇)σ1 + (σ1 - σ2)/r e_r in Cauchy tensions
    σ1 = τ1/λ2, σ2 = τ2/λ1 (i.e. ∇·σ). Returns (r, z) components."""
    T = np.linspace(0.0, np.pi / 2, 1001)
    d = lambda f: np.gradient(f, T, edge_order=2)
    r, z = _ellipsoid(T)
    with np.errstate(all="ignore"):
        sp = np.hypot(d(r), d(z))
        psi = np.arctan2(-d(z), d(r))
        k1, k2 = d(psi) / sp, np.sin(psi) / r
        H, KG = 0.5 * (k1 + k2), k1 * k2
        lam1, lam2 = sp / R0, r / (R0 * np.sin(T))
        e1, e2 = lam1 - 1, lam2 - 1
        s1 = ((KB + KS) * e1 + (KB - KS) * e2) / lam2
        s2 = ((KB - KS) * e1 + (KB + KS) * e2) / lam1
        ft = d(r * s1) / sp / r - s2 * np.cos(psi) / r
        u = H - H0
        fn = -(s1 * k1 + s2 * k2) - 2 * gamma * H + B * (
            2 * d(r * d(u) / sp) / sp / r + 4 * (2 * H**2 - KG) * u - 4 * H * u**2)
    fr = ft * np.cos(psi) + fn * np.sin(psi)
    fz = -ft * np.sin(psi) + fn * np.cos(psi)
    return np.column_stack([np.interp(t, T, fr), np.interp(t, T, fz)])


@pytest.mark.parametrize("moduli", [(1.0, 0, 0, 0), (0, 25, 8.33, 0), (0, 0, 0, 0.1),
                                    (1.5, 25, 10, 0.1)])
def test_nodal_forces_are_the_spec_force_densities(moduli):
    gamma, KB, KS, B = moduli
    n, R0 = 300, 5.8
    t = np.linspace(0.0, np.pi / 2, n + 1)
    r, z = _ellipsoid(t)
    r0, z0 = R0 * np.sin(t), R0 * np.cos(t)
    l0, _ = sf.elements(r0, z0)
    gE, gV = np.zeros((n + 1, 2)), np.zeros((n + 1, 2))
    A = sf.gradients(r, z, sf.Reference(l0, 0.5 * (r0[1:] + r0[:-1]), np.full(n + 1, 1 / R0)),
                     sf.Material(gamma, KB, KS, B), gE, gV)
    inner = slice(40, 260)      # away from the pole (flat-plate closure) and the equator
    f_mesh = (-gE / A[:, None])[inner]
    f_spec = _spec_density(t, R0, gamma, KB, KS, B, 1 / R0)[inner]
    assert np.abs(f_mesh - f_spec).max() < 2e-3 * np.abs(f_spec).max()
    # the pressure's force is p n: ∂V/∂x per area is the normal
    psi = np.arctan2(-np.gradient(z, t), np.gradient(r, t))[inner]
    g = (2 * gV / (2 * A[:, None]))[inner]
    assert np.allclose(g, np.column_stack([np.sin(psi), np.cos(psi)]), atol=1e-4)


def test_forces_are_minus_the_energy_gradient_on_a_small_mesh():
    shell = Shell(4300, 12, 25, 10, 1.5, bending="double")
    r0, z0, kind, _ = explicit.mesh(Shell(4300, 12, 25, 10, 1.5, resolution=0.08))
    rng = np.random.default_rng(1)
    r = r0 * (1 + 0.01 * rng.standard_normal(r0.size))
    r[0] = 0.0
    z = z0 + 0.02 * rng.standard_normal(z0.size)
    z[-1] = 0.0
    l0, _ = sf.elements(r0, z0)
    rb0 = 0.5 * (r0[1:] + r0[:-1])
    H0 = sf.mean_curvature(r0, z0) + 0.03
    args = (sf.Reference(l0, rb0, H0), sf.Material(1.5, 25.0, 10.0, shell.bending_stiffness * 5))
    gE, gV = np.zeros((r.size, 2)), np.zeros((r.size, 2))
    sf.gradients(r, z, *args, gE, gV)
    eps = 1e-6
    for i in range(1, r.size):
        for c, x in ((0, r), (1, z)):
            if c == 1 and i == r.size - 1:
                continue
            x[i] += eps
            ep, vp = sf.energy(r, z, *args), sf.half_volume(r, z)
            x[i] -= 2 * eps
            em, vm = sf.energy(r, z, *args), sf.half_volume(r, z)
            x[i] += eps
            assert gE[i, c] == pytest.approx((ep - em) / (2 * eps), rel=1e-5, abs=1e-6)
            assert gV[i, c] == pytest.approx((vp - vm) / (2 * eps), rel=1e-6, abs=1e-6)


@pytest.mark.parametrize("point", [(15, 25, 3, "none"), (10, 8.33, 3, "standard"),
                                   (12, 8.33, 1.5, "double")])
def test_resolution_refines_every_element_alike(point):
    """Resolution r divides the whole element-size function by r (contact band,
    grading and far field alike), as Richardson extrapolation assumes: at the
    same reference arc length the elements are 1/r as long as at resolution 1."""
    h0, ks, g, bending = point

    def elements(res):
        r0, z0, kind, ds_min = explicit.mesh(Shell(4300, h0, 25, ks, g, bending=bending,
                                                   resolution=res))
        l = np.hypot(np.diff(r0), np.diff(z0))
        S = np.concatenate([[0.0], np.cumsum(l)])
        return 0.5 * (S[1:] + S[:-1]), l, np.count_nonzero(kind == sf.PLATE), ds_min

    S1, l1, plate1, ds1 = elements(1.0)
    for res in (2.0, 4.0):
        S, l, plate, ds = elements(res)
        ratio = np.interp(S1, S, l) * res / l1
        assert 0.97 < ratio.min() and ratio.max() < 1.03
        assert ds == pytest.approx(ds1 / res)
        assert plate == pytest.approx(res * plate1, abs=res + 1)


def test_tension_only_gives_the_droplet_force_and_keeps_the_volume():
    shell = Shell(4300, 12, 0.0, 0.0, 3.0, bending="none")
    sol = explicit.solve(shell)
    d1 = droplet(4300, shell.h1_um)
    expected = 3.0 * float(d1.force_per_tension_um)      # 2 γ_a H(h1) A_c(h1)
    assert sol.converged
    assert sol.force_nN == pytest.approx(expected, rel=1e-3)
    assert abs(sol.volume_um3 - 4300) / 4300 < 1e-5
    assert sol.area_um2 == pytest.approx(float(d1.surface_area_um2), rel=1e-3)
    assert sol.r_um[0] == 0.0 and sol.z_um[-1] == 0.0
    assert sol.z_um[0] == pytest.approx(shell.h1_um / 2)


def test_elastic_compression_balances_across_the_equator():
    """Upper half cut at the mid-plane: F_tot = p π R_eq² - 2π R_eq (γ_a + σ1),
    σ1 = τ1/λ2 the Cauchy meridional tension of the last element (no bending)."""
    KB, KS, gamma = 25.0, 8.33, 3.0
    shell = Shell(4300, 10, KB, KS, gamma, bending="none")
    sol, p, (r0, z0) = explicit.relax(shell)
    l, _ = sf.elements(sol.r_um, sol.z_um)
    l0, _ = sf.elements(r0, z0)
    e1, e2 = l[-1] / l0[-1] - 1, sol.lambda2[-1] - 1
    sigma1 = ((KB + KS) * e1 + (KB - KS) * e2) / (1 + e2)
    Req = sol.r_um[-1]
    balance = p * np.pi * Req**2 - 2 * np.pi * Req * (gamma + sigma1)
    assert sol.force_nN == pytest.approx(balance, rel=5e-4)
    assert abs(sol.volume_um3 - 4300) / 4300 < 1e-5
    # compressed: stretched everywhere, plate force above the tension-only one
    assert np.all(sol.lambda1 > 1.0) and np.all(sol.lambda2[1:] > 1.0)
    assert sol.force_nN > gamma * float(droplet(4300, shell.h1_um).force_per_tension_um)


def test_unsettled_run_raises(monkeypatch):
    monkeypatch.setattr(explicit, "MAX_TIMES", 0.5)
    with pytest.raises(SolverError, match="did not settle"):
        explicit.solve(Shell(4300, 12, 0.0, 0.0, 3.0, bending="none"))


@pytest.mark.slow
def test_plate_force_is_minus_the_energy_derivative():
    """Virtual work: F_tot = dE_total/dΔh at fixed volume, from three compressions."""
    energies, forces = {}, {}
    for dh in (0.48, 0.5, 0.52):
        sol, _, (r0, z0) = explicit.relax(Shell(4300, 15, 25, 25, 3, bending="none", dh_um=dh))
        l0, _ = sf.elements(r0, z0)
        energies[dh] = 2 * sf.energy(sol.r_um, sol.z_um, sf.Reference(l0, 0.5 * (r0[1:] + r0[:-1]),
                                     sf.mean_curvature(r0, z0)), sf.Material(3.0, 25.0, 25.0, 0.0))
        forces[dh] = sol.force_nN
    assert forces[0.5] == pytest.approx((energies[0.52] - energies[0.48]) / 0.04, rel=1e-3)
    # and F_tot varies smoothly with the compression (no jumps with the contact position)
    assert forces[0.52] - forces[0.5] == pytest.approx(forces[0.5] - forces[0.48], rel=0.05)
