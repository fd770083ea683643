"""The axisymmetric Stokes solver (solver/stokes.py, Taylor-Hood P2/P1 on
solver/meridian_mesh.py) against exact solutions: a manufactured flow built
from a harmonic function (Papkovich-Neuber: u = ∇(zφ) - 2φ e_z, p = 2η ∂_zφ,
φ = I0(kr) sin(kz)) in the droplet's interior, and the flow inside a sphere
with a prescribed surface velocity (a cubic flow, and the uniaxial squeeze),
with their convergence rates and dissipation."""

import numpy as np
import pytest
from scipy.special import iv
from skfem import Functional

from solver.geometry import meridian
from solver.meridian_mesh import mesh_points
from solver.stokes import Interior

K = 0.4   # 1/µm


def bessel_flow(x):
    r, z = x[0], x[1]
    return np.array([z * K * iv(1, K * r) * np.sin(K * z),
                     -iv(0, K * r) * np.sin(K * z) + z * K * iv(0, K * r) * np.cos(K * z)])


def bessel_pressure(x, eta):
    return 2 * eta * K * iv(0, K * x[0]) * np.cos(K * x[1])


def cubic_flow(x):
    """φ = z³ - (3/2) r² z: u = (-3 r z², 2 z³), p = η (6 z² - 3 r²)."""
    r, z = x[0], x[1]
    return np.array([-3 * r * z**2, 2 * z**3])


def cubic_pressure(x, eta):
    return eta * (6 * x[1] ** 2 - 3 * x[0] ** 2)


def errors(problem, u, p, flow, pressure, eta):
    """Relative L2 errors of the velocity and of the pressure (both minus their
    mean), by quadrature (dV = 2π r dr dz)."""
    uh = problem.ub.interpolate(u)
    ph = problem.pb.interpolate(p)

    @Functional
    def sq(w):
        ue, pe = flow(w.x), pressure(w.x, eta)
        dV = 2 * np.pi * w.x[0]
        return np.stack([((w.uh[0] - ue[0]) ** 2 + (w.uh[1] - ue[1]) ** 2) * dV, (ue[0] ** 2 + ue[1] ** 2) * dV,
                         w.ph * dV, pe * dV, dV, w.ph**2 * dV, pe**2 * dV, w.ph * pe * dV])

    parts = [Functional(lambda w, i=i: sq.form(w)[i]).assemble(problem.ub, uh=uh, ph=ph)
             for i in range(8)]
    eu, nu, mph, mpe, vol, php, pep, pp = parts
    mph, mpe = mph / vol, mpe / vol
    # ∫ ((ph - mph) - (pe - mpe))² = ∫ph² - 2∫ph pe + ∫pe² - vol (mph - mpe)²
    ep = php - 2 * pp + pep - vol * (mph - mpe) ** 2
    npe = pep - vol * mpe**2
    return np.sqrt(eu / nu), np.sqrt(ep / npe)


def droplet_outline(n):
    """The droplet at h = 10 µm (V = 4300 µm³), n segments, pole to equator."""
    r, z, _ = meridian(4300.0, 10.0, np.linspace(0, np.pi / 2, n + 1))
    disc = np.linspace(0.0, r[0], max(2, int(np.ceil(n * r[0] / np.hypot(np.diff(r), np.diff(z)).sum()))) + 1)
    return np.concatenate([disc[:-1], r]), np.concatenate([np.full(len(disc) - 1, z[0]), z])


def sphere_outline(n, radius=5.0):
    t = np.linspace(0, np.pi / 2, n + 1)
    r, z = radius * np.sin(t), radius * np.cos(t)
    r[0], z[-1] = 0.0, 0.0
    return r, z


def test_mesh_covers_the_outline_polygon():
    r, z = droplet_outline(60)
    vertices, tri = mesh_points(r, z, 0.5)
    assert np.array_equal(vertices[: len(r)], np.column_stack([r, z]))
    a, b, c = (vertices[tri[:, i]] for i in range(3))
    area = 0.5 * ((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))
    assert np.all(area > 0)
    rr, zz = np.r_[r, 0.0], np.r_[z, 0.0]
    polygon = 0.5 * abs(np.sum(rr * np.roll(zz, -1) - np.roll(rr, -1) * zz))
    assert area.sum() == pytest.approx(polygon, rel=1e-12)


def test_manufactured_flow_converges_at_the_taylor_hood_rates():
    eta, rows = 2.0, []
    for n in (12, 24, 48):
        r, z = droplet_outline(n)
        h = np.hypot(np.diff(r), np.diff(z)).max()
        problem = Interior.from_outline(r, z, h_max=h)
        u, p = problem.solve(bessel_flow, eta)
        rows.append((h,) + errors(problem, u, p, bessel_flow, bessel_pressure, eta))
    (h1, u1, p1), (h2, u2, p2), (h3, u3, p3) = rows
    rate_u, rate_p = np.log(u2 / u3) / np.log(h2 / h3), np.log(p2 / p3) / np.log(h2 / h3)
    assert rate_u > 2.6 and rate_p > 1.6, rows          # theory: 3 and 2
    assert u3 < 1e-4 and p3 < 3e-3, rows


def test_flow_inside_a_sphere_with_a_prescribed_surface_velocity():
    eta, a, rows = 0.5, 5.0, []
    exact_half = 0.5 * 2 * eta * np.pi * a**7 * 792 / 105     # ∫ 2η e:e dV over the half ball
    for n in (10, 20, 40):
        r, z = sphere_outline(n, a)
        problem = Interior.from_outline(r, z, h_max=a * np.pi / 2 / n)
        u, p = problem.solve(cubic_flow, eta)
        eu, ep = errors(problem, u, p, cubic_flow, cubic_pressure, eta)
        rows.append((n, eu, ep, problem.dissipation(u, eta) / exact_half - 1))
    (_, u1, p1, d1), (_, u2, p2, d2), (_, u3, p3, d3) = rows
    assert np.log2(u2 / u3) > 2.6 and np.log2(p2 / p3) > 1.6, rows
    # the dissipation of the inscribed polygon's domain: O(h²) below the ball's
    assert d1 < d2 < d3 < 0 and np.log2(d2 / d3) == pytest.approx(2.0, abs=0.2), rows
    assert abs(d3) < 5e-3


def test_uniaxial_squeeze_of_a_sphere_dissipates_3_eta_V_strain_rate_squared():
    # u = ε̇ (-r/2, z): e = diag(-1/2, 1, -1/2) ε̇, D = 2η (3/2) ε̇² V; linear, so exact in P2
    eta, rate = 3.0, 0.7
    r, z = sphere_outline(16)
    problem = Interior.from_outline(r, z, h_max=0.8)
    u, p = problem.solve(lambda x: rate * np.array([-0.5 * x[0], x[1]]), eta)
    volume = np.pi * np.sum(-np.diff(z) * (r[1:] ** 2 + r[1:] * r[:-1] + r[:-1] ** 2) / 3)
    assert problem.dissipation(u, eta) == pytest.approx(3 * eta * rate**2 * volume, rel=1e-10)  # half cell
    assert np.ptp(p) < 1e-8 * eta * rate          # a pure strain: uniform pressure
