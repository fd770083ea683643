"""The droplet shape (solver/geometry.py, SPEC section 1) against independent
calculations: the sphere limit, a quadrature in r of the profile, force and
curvature balance, the outline from `profile()`/`meridian()`, bad input, and
the `cortex geometry` command."""

import json

import numpy as np
import pytest
from scipy.integrate import quad, simpson

from conftest import cortex
from common.errors import InputError
from solver.geometry import cell_radius, droplet, meridian, profile, sphere_height

VOLUMES = [500.0, 1500.0, 4300.0, 9000.0, 20000.0]          # µm³
H_TILDES = [0.3, 0.45, 0.6, 0.75, 0.9, 0.99, 0.999]


def integrate_in_r(R_c, R_eq):
    """Height, volume and free area of the shape with contact radius R_c and
    equator radius R_eq, integrating in r from R_c to R_eq (both halves).

    With H = R_eq / (R_eq² - R_c²) the first integral gives
    sin ψ = S(r) = H (r² - R_c²) / r; then dz/dr = S / sqrt(1 - S²) and
    ds/dr = 1 / sqrt(1 - S²). At the equator S -> 1 and 1 - S² vanishes like
    (R_eq - r): exactly, 1 - S = (R_eq - r)(H (r + R_eq) - 1) / r. So each
    integrand is a smooth function times (R_eq - r)^(-1/2), which QUADPACK's
    algebraic weight (weight="alg", wvar=(0, -1/2)) integrates to full accuracy.
    """
    H = R_eq / (R_eq**2 - R_c**2)

    def S(r):
        return H * (r * r - R_c * R_c) / r

    def root(r):   # sqrt((1 - S²) / (R_eq - r)), no cancellation
        return np.sqrt((H * (r + R_eq) - 1.0) / r * (1.0 + S(r)))

    opts = dict(weight="alg", wvar=(0.0, -0.5), epsabs=0.0, epsrel=1e-13, limit=200)
    half_h = quad(lambda r: S(r) / root(r), R_c, R_eq, **opts)[0]
    half_v = quad(lambda r: np.pi * r * r * S(r) / root(r), R_c, R_eq, **opts)[0]
    half_a = quad(lambda r: 2.0 * np.pi * r / root(r), R_c, R_eq, **opts)[0]
    return 2.0 * half_h, 2.0 * half_v, 2.0 * half_a


def gap(volume, h_tilde):
    return h_tilde * sphere_height(volume)


# -- the sphere limit -------------------------------------------------------

def test_free_sphere_at_full_height():
    V = 4300.0
    R = float(cell_radius(V))
    d = droplet(V, 2.0 * R)
    assert float(d.contact_radius_um) == pytest.approx(0.0, abs=1e-12 * R)
    assert float(d.equator_radius_um) == pytest.approx(R, rel=1e-13)
    assert float(d.mean_curvature_per_um) == pytest.approx(1.0 / R, rel=1e-13)
    assert float(d.surface_area_um2) == pytest.approx(4.0 * np.pi * R * R, rel=1e-13)
    assert float(d.force_per_tension_um) == pytest.approx(0.0, abs=1e-12 * R)


@pytest.mark.parametrize("V", [500.0, 4300.0, 20000.0])
def test_sphere_limit_is_approached_continuously(V):
    """R_c -> 0, H -> 1/R_cell, A -> 4π R_cell² as h -> 2 R_cell; the deviations
    shrink with 1 - h̃ (A is stationary at the sphere, so it converges fastest)."""
    R = float(cell_radius(V))
    eps = np.logspace(-2, -8, 7)
    d = droplet(V, (1.0 - eps) * 2.0 * R)
    k = d.contact_radius_um / R
    dH = d.mean_curvature_per_um * R - 1.0
    dA = d.surface_area_um2 / (4.0 * np.pi * R * R) - 1.0
    assert np.all(np.diff(k) < 0) and k[-1] < 1e-4
    assert np.all(k > 0) and np.all(dH > 0)
    assert np.all(np.diff(dH) < 0) and dH[-1] < 1e-8
    assert np.all(np.diff(dA[:4]) < 0) and np.all(dA[:4] > 0)
    assert np.all(dA < dH)                            # stationary: faster than H
    assert dA[0] < 1e-4 and np.all(np.abs(dA[4:]) < 1e-12)


# -- the solved shape against an independent integration in r ---------------

@pytest.mark.parametrize("V", VOLUMES)
def test_height_volume_area_by_quadrature_in_r(V):
    h = gap(V, np.array(H_TILDES))
    d = droplet(V, h)
    for i, h_i in enumerate(h):
        R_c, R_eq = float(d.contact_radius_um[i]), float(d.equator_radius_um[i])
        height, volume, free_area = integrate_in_r(R_c, R_eq)
        assert height == pytest.approx(h_i, rel=1e-10, abs=0)
        assert volume == pytest.approx(V, rel=1e-10, abs=0)
        assert free_area == pytest.approx(float(d.free_area_um2[i]), rel=1e-10, abs=0)
        assert float(d.surface_area_um2[i]) == pytest.approx(free_area + 2 * np.pi * R_c**2,
                                                              rel=1e-10)


def test_h_tilde_and_cell_radius():
    V, h = 4300.0, np.array([10.0, 12.0, 15.0])
    d = droplet(V, h)
    R = (3 * V / (4 * np.pi)) ** (1 / 3)
    np.testing.assert_allclose(d.cell_radius_um, R, rtol=1e-15)
    np.testing.assert_allclose(d.h_tilde, h / (2 * R), rtol=1e-15)
    # the experimentally relevant range of SPEC section 1
    assert 0.49 < d.h_tilde[0] < 0.5 and 0.74 < d.h_tilde[-1] < 0.75


# -- force and curvature balance --------------------------------------------

@pytest.mark.parametrize("V", VOLUMES)
def test_force_balance_at_the_equator(V):
    """Cut at the equator: the pressure ΔP = 2γH on the disc π R_eq², less the
    tension 2π R_eq γ pulling along the wall, is the force on a plate, 2γ H A_c."""
    d = droplet(V, gap(V, np.array(H_TILDES)))
    H, R_eq, A_c = d.mean_curvature_per_um, d.equator_radius_um, d.contact_area_um2
    gamma = 1.0                                     # mN/m: forces in nN
    pressure = 2.0 * gamma * H
    lhs = np.pi * R_eq**2 * pressure - 2.0 * np.pi * R_eq * gamma
    np.testing.assert_allclose(lhs, 2.0 * gamma * H * A_c, rtol=1e-11)
    np.testing.assert_allclose(d.force_per_tension_um, 2.0 * H * A_c, rtol=1e-14)
    np.testing.assert_allclose(A_c, np.pi * d.contact_radius_um**2, rtol=1e-14)


def test_mean_curvature_is_constant_along_the_meridian():
    """2H = κ1 + κ2 with κ1 = dψ/ds (finite differences of the outline) and
    κ2 = sin ψ / r, everywhere on the free surface."""
    V, h = 4300.0, 11.0
    d = droplet(V, h)
    psi = np.linspace(0.05, np.pi / 2 - 0.05, 200)
    step = 1e-5
    _, _, s_plus = meridian(V, h, psi + step)
    _, _, s_minus = meridian(V, h, psi - step)
    r, _, _ = meridian(V, h, psi)
    kappa1 = 2 * step / (s_plus - s_minus)
    np.testing.assert_allclose(0.5 * (kappa1 + np.sin(psi) / r),
                               float(d.mean_curvature_per_um), rtol=1e-7)


def test_area_grows_as_the_cell_is_flattened():
    for V in VOLUMES:
        h = gap(V, np.linspace(1.0, 0.3, 300))       # falling height
        d = droplet(V, h)
        assert np.all(np.diff(d.surface_area_um2) > 0)
        assert np.all(np.diff(d.contact_radius_um) > 0)
        assert np.all(np.diff(d.force_per_tension_um) > 0)


def test_broadcasting_matches_scalar_calls():
    V = np.array([[500.0], [4300.0]])
    ht = np.array([0.4, 0.7, 0.95])
    d = droplet(V, ht * sphere_height(V))
    assert d.surface_area_um2.shape == (2, 3)
    for i in range(2):
        for j in range(3):
            one = droplet(float(V[i, 0]), float(ht[j] * sphere_height(V[i, 0])))
            assert float(one.surface_area_um2) == pytest.approx(d.surface_area_um2[i, j],
                                                                 rel=1e-14)


# -- profile() and meridian() -----------------------------------------------

@pytest.mark.parametrize("V,h_tilde", [(500.0, 0.35), (4300.0, 0.6), (20000.0, 0.95)])
def test_profile_encloses_the_volume(V, h_tilde):
    h = float(gap(V, h_tilde))
    d = droplet(V, h)
    r, z = profile(V, h, n=4001)
    assert z[0] == pytest.approx(0.0, abs=1e-12 * h) and z[-1] == pytest.approx(h, rel=1e-12)
    assert np.all(np.diff(z) >= 0)
    assert r[0] == pytest.approx(float(d.contact_radius_um), rel=1e-12)
    assert r[-1] == pytest.approx(float(d.contact_radius_um), rel=1e-12)
    assert r.max() == pytest.approx(float(d.equator_radius_um), rel=1e-12)
    assert z[np.argmax(r)] == pytest.approx(h / 2, rel=1e-12)
    assert simpson(np.pi * r**2, x=z) == pytest.approx(V, rel=1e-6)


def test_meridian_ends_and_arc_length():
    V, h = 4300.0, 12.0
    d = droplet(V, h)
    psi = np.linspace(0.0, np.pi / 2, 4001)
    r, z, s = meridian(V, h, psi)
    assert (r[0], z[0], s[0]) == pytest.approx((float(d.contact_radius_um), h / 2, 0.0), abs=1e-12)
    assert (r[-1], z[-1]) == pytest.approx((float(d.equator_radius_um), 0.0), abs=1e-10)
    # arc length and free area by the trapezoid rule along the outline
    chord = np.hypot(np.diff(r), np.diff(z))
    assert s[-1] == pytest.approx(chord.sum(), rel=1e-6)
    area = 2 * np.trapezoid(2 * np.pi * r, s)
    assert area == pytest.approx(float(d.free_area_um2), rel=1e-6)


def test_profile_rejects_bad_input():
    with pytest.raises(InputError):
        profile(4300.0, 25.0)
    with pytest.raises(InputError):
        meridian(4300.0, 12.0, [0.1, 2.0])


# -- bad input ---------------------------------------------------------------

@pytest.mark.parametrize("V,h", [
    (4300.0, 0.0), (4300.0, -1.0), (4300.0, 20.3), (0.0, 10.0), (-5.0, 10.0),
    (float("nan"), 10.0), (4300.0, float("nan")), (float("inf"), 10.0), (4300.0, 0.2),
    (4300.0, [12.0, 25.0]),
])
def test_bad_input_raises_input_error(V, h):
    with pytest.raises(InputError):
        droplet(V, h)


def test_height_just_below_the_sphere_is_accepted():
    V = 4300.0
    top = float(sphere_height(V))
    assert top == pytest.approx(20.175452, abs=1e-6)     # 2 (3 V / 4π)^(1/3)
    assert float(droplet(V, top * (1 - 1e-9)).contact_radius_um) > 0


# -- the command line ---------------------------------------------------------

def test_cli_json_several_heights():
    heights = ["15", "12", "10"]
    done = cortex("geometry", "--volume", "4300", "--height", *heights, "--json")
    assert done.returncode == 0, done.stderr
    rows = [json.loads(line) for line in done.stdout.splitlines()]
    assert len(rows) == 3
    keys = {"height_um", "volume_um3", "contact_radius_um", "equator_radius_um",
            "mean_curvature_per_um", "surface_area_um2", "contact_area_um2",
            "force_per_tension_um", "h_tilde"}
    d = droplet(4300.0, [15.0, 12.0, 10.0])
    for i, row in enumerate(rows):
        assert set(row) == keys
        assert row["height_um"] == float(heights[i])
        assert row["volume_um3"] == 4300.0
        for key in keys - {"h_tilde"}:
            assert row[key] == pytest.approx(float(getattr(d, key)[i]), rel=1e-14)
        assert row["h_tilde"] == pytest.approx(float(d.h_tilde[i]), rel=1e-14)
    # the example of docs/cli.md
    assert rows[1]["force_per_tension_um"] == pytest.approx(31.1427, abs=1e-4)


def run_main(capsys, *args):
    """`cortex ARGS` in this process: (exit status, stdout, stderr)."""
    from cortex.cli import main
    try:
        status = main(list(args))
    except SystemExit as stop:                      # argparse usage errors
        status = stop.code
    out, err = capsys.readouterr()
    return status, out, err


def test_cli_table(capsys):
    status, out, err = run_main(capsys, "geometry", "--volume", "4300", "--height", "14", "11")
    assert status == 0, err
    lines = out.splitlines()
    assert len(lines) == 4 and "R_cell" in lines[0] and "[um]" in lines[1]
    d = droplet(4300.0, [14.0, 11.0])
    for line, A in zip(lines[2:], d.surface_area_um2):
        assert float(line.split()[5]) == pytest.approx(float(A), rel=1e-5)


@pytest.mark.parametrize("args", [
    ["--volume", "4300", "--height", "-1"],
    ["--volume", "4300", "--height", "12", "30"],
    ["--volume", "0", "--height", "12"],
    ["--volume", "nan", "--height", "12"],
    ["--volume", "4300", "--height", "0.3"],
    ["--volume", "4300", "--height", "twelve"],
    ["--height", "12"],
])
def test_cli_bad_input_is_one_line_and_exit_2(capsys, args):
    status, out, err = run_main(capsys, "geometry", *args)
    assert status == 2
    assert out == ""
    assert len(err.splitlines()) == 1, err
    assert err.startswith("cortex")


def test_cli_bad_input_exit_status_of_the_installed_command():
    done = cortex("geometry", "--volume", "4300", "--height", "12", "21")
    assert done.returncode == 2
    assert done.stdout == ""
    assert done.stderr.count("\n") == 1 and "exceeds the free sphere" in done.stderr
