"""The approach ramp from the free sphere (`solver.ramp`) against known truth:
the droplet for a tension-dominated shell, single compressions, a finer mesh."""

import numpy as np
import pytest

from common.errors import InputError
from solver.compression import compress
from solver.droplet_table import force_per_tension_um
from solver.model import Shell
from solver.ramp import RESOLUTION, reference_height_um, ramp_forces_nN


def volume(radius):
    return 4.0 * np.pi / 3.0 * radius**3


def test_a_tension_dominated_shell_gives_the_droplet_force():
    # K_B = K_S = 0.003 gamma_a, no bending: F = 2 gamma_a H A_c of the droplet at h = 2R - delta
    R, gamma = 5.0, 1.0
    x = np.array([0.01, 0.03, 0.1, 0.3, 0.6, 1.0])
    F = ramp_forces_nN(volume(R), x * R, 0.003, 0.003, gamma, "none")
    droplet = gamma * force_per_tension_um(volume(R), 2.0 * R - x * R)
    assert np.all(np.abs(F[1:] / droplet[1:] - 1.0) < 0.005), F / droplet - 1.0
    assert abs(F[0] / droplet[0] - 1.0) < 0.01


def test_a_tension_only_shell_is_the_droplet():
    R, x = 5.0, np.array([0.01, 0.5])
    F = ramp_forces_nN(volume(R), x * R, 0.0, 0.0, 1.5, "none")
    np.testing.assert_allclose(F, 1.5 * force_per_tension_um(volume(R), 2.0 * R - x * R), rtol=1e-12)


def test_the_ramp_equals_single_compressions_from_the_sphere():
    R, bulk, shear, gamma = 5.0, 5.0, 0.5, 2.0
    x = np.array([0.02, 0.05, 0.3, 1.0])
    F = ramp_forces_nN(volume(R), x * R, bulk, shear, gamma, "double")
    h0 = reference_height_um(volume(R))
    for depth, force in zip(x * R, F):
        single = compress(Shell(volume_um3=volume(R), h0_um=h0, dh_um=depth - (2.0 * R - h0),
                                bulk_mN_per_m=bulk, shear_mN_per_m=shear, tension_mN_per_m=gamma,
                                bending="double", resolution=RESOLUTION))
        assert single.solution.force_nN == pytest.approx(force, rel=5e-4)


def test_a_compression_just_below_the_sphere_converges():
    # once "no admissible equilibrium": V = 1317.1 um3 (2R = 13.60004 um), from h0 = 13.6 um to 13 um
    s = Shell(volume_um3=1317.1, h0_um=13.6, dh_um=0.6, bulk_mN_per_m=10.0, shear_mN_per_m=5.0,
              tension_mN_per_m=0.5)
    c = compress(s)
    two_r = reference_height_um(1317.1) / (1.0 - 1e-6)
    ramp = ramp_forces_nN(1317.1, [two_r - 13.0], 10.0, 5.0, 0.5, resolution=1.0)
    assert c.solution.force_nN == pytest.approx(ramp[0], rel=1e-3)
    assert c.derived["volume_error"] < 1e-9


def test_a_finer_mesh_changes_the_force_by_under_half_a_percent():
    R = 10.0
    x = np.array([0.01, 0.03, 0.1, 0.3, 1.0])
    args = (volume(R), x * R, 5.0, 10.0, 0.2, "standard")
    coarse, fine = ramp_forces_nN(*args), ramp_forces_nN(*args, resolution=2.0 * RESOLUTION)
    assert np.all(np.abs(fine / coarse - 1.0) < 0.005), fine / coarse - 1.0


@pytest.mark.parametrize("radius, gamma, bulk, ks, bending", [
    (10.0, 0.2, 50.0, 2.0, "standard"), (5.0, 2.0, 5.0, 0.1, "none"), (5.0, 2.0, 5.0, 2.0, "double")])
def test_corners_of_the_physiological_range_converge_to_delta_R(radius, gamma, bulk, ks, bending):
    x = np.geomspace(0.005, 1.0, 20)
    F = ramp_forces_nN(volume(radius), x * radius, bulk, ks * bulk, gamma, bending)
    assert np.all(np.isfinite(F)) and np.all(np.diff(F) > 0) and F[0] > 0
    # deeper than the droplet: the elastic shell pushes back at least with its tension
    assert np.all(F > gamma * force_per_tension_um(volume(radius), 2.0 * radius - x * radius))


@pytest.mark.parametrize("depths", [[0.5, 0.4], [0.5, 10.0], [0.0, 0.5], [], [np.nan]])
def test_bad_depths_are_refused(depths):
    with pytest.raises(InputError):
        ramp_forces_nN(volume(5.0), depths, 5.0, 5.0, 1.0)
