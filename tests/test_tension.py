"""Cortical tension from ramps and pauses (SPEC 11) on curves of known truth:
tension-only droplets made with the project's exact geometry plus noise."""

from dataclasses import replace

import numpy as np
import pytest

from analysis.afm.formats.instruments import wedge_height_um
from analysis.afm.tension.ramp import fit_ramp, force_per_tension_um
from analysis.afm.tension.pause import TENSION_ERRORS, pause_tension, pressure_Pa, ramp_interval
from analysis.afm.tension.pipeline import Options, Trace, analyse
from solver.droplet_table import mean_curvature_per_um, unit_area, unit_shape
from common.errors import InputError
from solver.geometry import cell_radius, droplet
from studies.tension_synth import droplet_force_nN, droplet_recording

DEPTHS_H_TILDE = (0.95, 0.9, 0.8, 0.7, 0.6, 0.5)


def _ramp(rec):
    a = rec.segments[0]
    return wedge_height_um(a, rec.spring_constant_N_per_m), a.force_nN


def test_the_table_is_the_exact_droplet():
    rng = np.random.default_rng(3)
    depth = np.exp(rng.uniform(np.log(1e-8), np.log(1.6), 4000))
    exact = droplet(4.0 * np.pi / 3.0, 2.0 - depth)
    g, h = unit_shape(depth)
    np.testing.assert_allclose(g, exact.force_per_tension_um, rtol=1e-6)
    np.testing.assert_allclose(h, exact.mean_curvature_per_um, rtol=1e-6)
    np.testing.assert_allclose(unit_area(depth), exact.surface_area_um2, rtol=1e-6)
    g, h = unit_shape(np.array([0.0, -0.3]))
    assert list(g) == [0.0, 0.0] and list(h) == [1.0, 1.0]          # no contact: no force, the free sphere
    assert list(unit_area(np.array([0.0, -0.3]))) == [4.0 * np.pi] * 2
    d = droplet(4300.0, 12.0)                                       # and at a cell's scale (SPEC 1)
    assert mean_curvature_per_um(4300.0, 12.0) == pytest.approx(float(d.mean_curvature_per_um), rel=1e-7)


@pytest.mark.parametrize("h_tilde", DEPTHS_H_TILDE)
@pytest.mark.parametrize("volume, tension", [(4300.0, 1.5), (2500.0, 1.0)])
def test_droplet_ramps_give_back_the_tension_within_1_percent(h_tilde, volume, tension):
    radius = float(cell_radius(volume))
    depth = 2.0 * radius * (1.0 - h_tilde)
    for seed in range(3):
        rec = droplet_recording(volume, tension, depth, noise_nN=0.02, height_noise_um=0.001, baseline_nN=2.5,
                                seed=seed)
        x, f = _ramp(rec)
        fit = fit_ramp(x, f, radius, "droplet")
        assert fit.tension_mN_per_m == pytest.approx(tension, rel=0.01)
        assert fit.contact_um == pytest.approx(2.0 * radius, abs=0.05)       # the dish is at x = 0
        assert fit.baseline_nN == pytest.approx(2.5, abs=0.02)
        assert fit.depth_um == pytest.approx(min(depth, radius), rel=0.02)     # the window: to the bottom, ≤ R
        assert fit.r2 > 0.99


def test_the_small_deformation_formula_is_biased_low_and_less_so_deeper():
    """Fitted to exact droplet ramps (contact free), π T δ (1 + 5δ/4R) gives T
    too small, by less the deeper the ramp, and puts the contact ever lower
    (docs/studies/tension-ramps.md's table)."""
    volume, tension = 4300.0, 1.0
    radius = float(cell_radius(volume))
    ratios, contacts = [], []
    for h_tilde in DEPTHS_H_TILDE:
        rec = droplet_recording(volume, tension, 2.0 * radius * (1.0 - h_tilde), noise_nN=0.02, seed=1)
        x, f = _ramp(rec)
        fit = fit_ramp(x, f, radius, "small-deformation")
        ratios.append(fit.tension_mN_per_m / tension)
        contacts.append(fit.contact_um - 2.0 * radius)
    assert all(r < 0.8 for r, h in zip(ratios, DEPTHS_H_TILDE) if h >= 0.6)
    assert np.all(np.diff(ratios) > 0)
    assert np.all(np.diff(contacts) < 0) and contacts[-1] < -1.0


def test_a_pause_gives_back_tension_and_pressure():
    volume, tension = 4300.0, 1.2
    radius = float(cell_radius(volume))
    for h_tilde in (0.9, 0.75, 0.6, 0.5):
        h = 2.0 * radius * h_tilde
        force = float(droplet_force_nN(volume, tension, np.array([h]))[0])
        p = pause_tension(force, h, volume)
        assert p.tension_mN_per_m == pytest.approx(tension, rel=1e-6)
        # ΔP = 2 γ H with γ in mN/m and H in 1/µm is 10³ Pa per unit
        H = float(droplet(volume, h).mean_curvature_per_um)
        assert p.pressure_Pa == pytest.approx(2.0 * tension * 1e-3 * H * 1e6, rel=1e-6)
        assert p.tension_lo95_mN_per_m < tension < p.tension_hi95_mN_per_m
        assert p.pressure_lo95_Pa < p.pressure_Pa < p.pressure_hi95_Pa
    exact = pause_tension(force, h, volume, errors=replace(TENSION_ERRORS, volume_rel_sd=0.0, height_sd_um=0.0))
    assert exact.tension_lo95_mN_per_m == pytest.approx(tension) == exact.tension_hi95_mN_per_m
    # the free sphere: the Laplace pressure 2T/R
    assert pressure_Pa(1.0, 1.0 / 10.0) == pytest.approx(200.0)


def test_interval_widths_follow_the_errors():
    volume, h = 4300.0, 12.0
    force = float(droplet_force_nN(volume, 1.0, np.array([h]))[0])
    vol_only = pause_tension(force, h, volume, errors=replace(TENSION_ERRORS, height_sd_um=0.0))
    both = pause_tension(force, h, volume)
    width = lambda p: p.tension_hi95_mN_per_m - p.tension_lo95_mN_per_m  # noqa: E731
    assert 0 < width(vol_only) < width(both)
    # 0.3 um below the free sphere a 0.5 um height error reaches past it: no upper end
    top = 2.0 * float(cell_radius(volume))
    shallow = pause_tension(float(droplet_force_nN(volume, 1.0, np.array([top - 0.3]))[0]), top - 0.3, volume)
    assert shallow.tension_mN_per_m == pytest.approx(1.0, rel=1e-6) and shallow.tension_hi95_mN_per_m == np.inf


@pytest.mark.parametrize("h_tilde", (0.9, 0.7, 0.5))
def test_a_recording_pause_height_from_the_contact_point(h_tilde):
    """JPK-like recording without a dish reference (its height channel offset by
    30 µm): the pause's gap comes from the ramp's contact point, 2R - (x0 - x)."""
    volume, tension = 3500.0, 0.8
    radius = float(cell_radius(volume))
    rec = droplet_recording(volume, tension, 2.0 * radius * (1.0 - h_tilde), noise_nN=0.02, baseline_nN=4.0,
                            seed=2)
    parts = [(i, s.kind, s.time_s, s.force_nN, wedge_height_um(s, rec.spring_constant_N_per_m) + 30.0)
             for i, s in enumerate(rec.segments)]
    done = analyse(Trace("c", "synthetic", volume, "known", parts, dish_known=False), Options(model="droplet"))
    ramp, pause = done.rows
    assert (ramp["part"], pause["part"]) == ("approach", "pause")
    assert pause["height_reference"] == "contact point"
    assert pause["height_um"] == pytest.approx(2.0 * radius * h_tilde, abs=0.05)
    assert pause["tension_mN_per_m"] == pytest.approx(tension, rel=0.01)
    assert ramp["tension_lo95_mN_per_m"] <= ramp["tension_mN_per_m"] <= ramp["tension_hi95_mN_per_m"]
    assert ramp["compare_model"] == "small-deformation" and ramp["compare_tension_mN_per_m"] > 0


def test_the_ramp_interval_is_the_volume_error():
    volume, tension = 4300.0, 1.0
    radius = float(cell_radius(volume))
    x, f = _ramp(droplet_recording(volume, tension, radius * 0.5, noise_nN=0.02, seed=4))
    fit = fit_ramp(x, f, radius)
    lo, hi, _, _ = ramp_interval(fit, x, f, volume)
    assert lo < fit.tension_mN_per_m < hi
    lo0, hi0, _, _ = ramp_interval(fit, x, f, volume, replace(TENSION_ERRORS, volume_rel_sd=0.0))
    assert lo0 == pytest.approx(fit.tension_mN_per_m, rel=1e-6) and hi0 == pytest.approx(lo0, rel=1e-9)


def test_bad_ramps_and_pauses_are_input_errors():
    volume = 4300.0
    radius = float(cell_radius(volume))
    x, f = _ramp(droplet_recording(volume, 0.0, 3.0, noise_nN=0.02))        # no tension: no force, no contact
    with pytest.raises(InputError, match="without contact"):
        fit_ramp(x, f, radius)
    with pytest.raises(InputError, match="without force"):
        pause_tension(-0.1, 12.0, volume)
    with pytest.raises(InputError, match="no contact"):
        pause_tension(5.0, 2.0 * radius + 0.1, volume)
    with pytest.raises(InputError, match="unknown ramp model"):
        force_per_tension_um("hertz", 1.0, radius)
