"""The viscoelastic cortex in the solver (SPEC 10, `solver.viscoelastic`)."""

import json
from dataclasses import replace

import numpy as np
import pytest

from conftest import cortex
from solver.model import Shell
from solver.viscoelastic import complex_response, correction, hessian_parts, relaxed
from solver.viscous import linearise, respond

# six cells over the physiological range: (h0 um, K_B, K_S, gamma_a mN/m)
CELLS = [(12.0, 25.0, 8.33, 1.5), (14.5, 25.0, 3.0, 0.5), (10.5, 20.0, 20.0, 3.0),
         (13.0, 30.0, 1.5, 1.0), (15.5, 15.0, 30.0, 2.0), (11.0, 40.0, 4.0, 0.3)]


def _real_modulus(shell):
    """The real solver's small-amplitude K at h_m (no loss angles, no viscosity), state re-solved."""
    sh = relaxed(shell)
    lin = linearise(sh)
    lin.shell = sh
    return respond(lin, 0.0, 1.0).complex_modulus.real


@pytest.mark.parametrize("h0, bulk, shear, tension", CELLS)
def test_first_order_expansion_matches_real_derivatives(h0, bulk, shear, tension):
    """Im K* = δ_B K_B ∂K/∂K_B + δ_S K_S ∂K/∂K_S for small loss angles, the derivatives by
    central differences of real solves (each its own equilibrium)."""
    shell = Shell(volume_um3=4300.0, h0_um=h0, bulk_mN_per_m=bulk, shear_mN_per_m=shear, tension_mN_per_m=tension)
    parts = hessian_parts(shell)
    db, ds, e = 0.01, 0.02, 1e-3
    K = complex_response(parts, db, ds, 1.0)
    dkb = (_real_modulus(replace(shell, bulk_mN_per_m=bulk * (1 + e)))
           - _real_modulus(replace(shell, bulk_mN_per_m=bulk * (1 - e)))) / (2 * e)
    dks = (_real_modulus(replace(shell, shear_mN_per_m=shear * (1 + e)))
           - _real_modulus(replace(shell, shear_mN_per_m=shear * (1 - e)))) / (2 * e)
    assert K.imag == pytest.approx(db * dkb + ds * dks, rel=0.02)
    assert abs(complex_response(parts, 0.0, 0.0, 1.0) - _real_modulus(shell)) < 1e-6 * abs(K)


def test_equal_angles_rotate_the_modulus_nearly():
    """With δ_B = δ_S = δ the moduli-weighted part of the Hessian turns by e^{iδ}; only γ_a
    (real) keeps K* from being K e^{iδ}: its phase stays within 0.02 rad of δ, and
    unequal angles give a phase between them."""
    for tension in (3.0, 0.3):
        shell = Shell(volume_um3=4300.0, h0_um=12.0, bulk_mN_per_m=25.0, shear_mN_per_m=8.33,
                      tension_mN_per_m=tension)
        parts = hessian_parts(shell)
        assert np.angle(correction(parts, 0.3, 0.3, 1.0)) == pytest.approx(0.3, abs=0.02)
        assert 0.1 < np.angle(correction(parts, 0.1, 0.5, 1.0)) < 0.5


def _compress(*extra):
    return cortex("compress", "--h0", "12", "--bulk", "25", "--shear", "8.33", "--tension", "1.5", *extra)


def test_cli_zero_angles_give_the_elastic_modulus_and_bad_input_exits_2():
    elastic = json.loads(_compress("--json").stdout)
    out = _compress("--json", "--frequency", "1", "--bulk-loss-angle", "0", "--shear-loss-angle", "0")
    ve = json.loads(out.stdout)
    assert ve["modulus_mN_per_m"] == pytest.approx(elastic["modulus_mN_per_m"], rel=1e-12)
    assert ve["loss_angle_rad"] == 0.0 and ve["loss_modulus_mN_per_m"] == 0.0
    lossy = json.loads(_compress("--json", "--frequency", "1", "--bulk-loss-angle", "0.1",
                                 "--shear-loss-angle", "0.3").stdout)
    assert 0.1 < lossy["loss_angle_rad"] < 0.3
    assert lossy["storage_modulus_mN_per_m"] ** 2 + lossy["loss_modulus_mN_per_m"] ** 2 == pytest.approx(
        lossy["modulus_mN_per_m"] ** 2)
    for bad in (("--frequency", "1", "--bulk-loss-angle", "0.1"), ("--bulk-loss-angle", "0.1", "--shear-loss-angle", "0"),
                ("--frequency", "1", "--bulk-loss-angle", "-0.1", "--shear-loss-angle", "0")):
        r = _compress(*bad)
        assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1


def test_viscous_interior_and_loss_angles_add_at_first_order():
    """With the Stokes interior (`solver.viscous.prepare`) the complex moduli's loss and the
    fluid's add to first order: arg C(δ, η) = arg C(δ, 0) + arg C(0, η) for small δ and ωη."""
    from solver.viscous import prepare
    shell = Shell(volume_um3=4300.0, h0_um=12.0, bulk_mN_per_m=25.0, shear_mN_per_m=8.33, tension_mN_per_m=1.5)
    lin = prepare(relaxed(shell))[0]
    parts = hessian_parts(shell, lin)
    both, angles, fluid = (np.angle(correction(parts, db, ds, 1.0, eta)) for db, ds, eta in
                           ((0.01, 0.02, 0.5), (0.01, 0.02, 0.0), (0.0, 0.0, 0.5)))
    assert fluid > 1e-3 and angles > 1e-3
    assert both == pytest.approx(angles + fluid, rel=0.01)
