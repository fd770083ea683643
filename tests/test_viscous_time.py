"""The time-domain check of K*(ω) (solver/viscous_time.py): the linearised
viscous cell integrated in time for a sinusoidal gap, analysed as a recording
(SPEC 6: γ_eff = F / (2 H A_c), A from the droplet, least-squares sinusoid
fits), against the frequency-domain K*; and SPEC 2's half-cosine ramp, then
held, relaxing to the elastic force."""

import numpy as np
import pytest

from analysis.afm.timeseries import fit_sinusoid, shape_of
from solver import viscous
from common.errors import InputError
from solver.model import Shell
from studies import viscous_time

SHELL = Shell(volume_um3=4300.0, h0_um=12.0, dh_um=0.5, bulk_mN_per_m=25.0, shear_mN_per_m=8.33,
              tension_mN_per_m=1.5)


@pytest.fixture(scope="module")
def lin():
    return viscous.prepare(SHELL)[0]


@pytest.mark.parametrize("eta, f", [(10.0, 10.0), (1.0, 10.0), (10.0, 0.02)])
def test_sinusoid_in_time_gives_the_frequency_domain_modulus(lin, eta, f):
    K = viscous.respond(lin, eta, f).complex_modulus
    per_period, periods, amplitude = 400, 8, 0.05
    t = np.arange(periods * per_period + 1) / (per_period * f)
    dh = amplitude * np.sin(2 * np.pi * f * t)
    force = lin.force_nN + viscous_time.integrate(lin, eta, t, dh)
    last = t >= (periods - 4) / f                       # transients gone
    h = lin.h_mean_um + dh[last]
    g, area = shape_of(SHELL.volume_um3, h)
    fit = fit_sinusoid(t[last] - t[last][0], np.vstack([force[last] / g, area]), f)
    modulus = fit["amplitude"][0] / (fit["amplitude"][1] / fit["mean"][1])
    angle = np.angle(np.exp(1j * (fit["phase"][0] - fit["phase"][1])))
    assert modulus == pytest.approx(abs(K), rel=1e-2)
    assert angle == pytest.approx(np.angle(K), rel=1e-2, abs=1e-4)


def test_half_cosine_then_held_relaxes_to_the_elastic_force(lin):
    depth, f, eta = 0.01, 10.0, 10.0
    t = np.arange(0.0, 1.0, 1e-4)
    dh = viscous_time.half_cosine(t, depth, f)
    assert dh[0] == 0 and dh[-1] == -depth and np.all(np.diff(dh) <= 0)
    dF = viscous_time.integrate(lin, eta, t, dh)
    elastic = viscous.respond(lin, 0.0, f).force_amplitude_nN.real * depth
    assert dF[-1] == pytest.approx(elastic, rel=1e-3)
    # the interior resists the motion: while the plate moves, more force than elastic
    ramp = t <= 0.5 / f
    static = viscous.respond(lin, 0.0, f).force_amplitude_nN.real * -dh
    assert np.all(dF[ramp][1:] > static[ramp][1:])
    # without viscosity the force follows the gap at once
    assert viscous_time.integrate(lin, 0.0, t, dh)[:: 500] == pytest.approx(static[:: 500], rel=1e-6, abs=1e-9)


def test_bad_time_axis(lin):
    with pytest.raises(InputError):
        viscous_time.integrate(lin, 1.0, np.array([0.0, 0.1, 0.3]), np.zeros(3))
    with pytest.raises(InputError):
        viscous_time.integrate(lin, -1.0, np.linspace(0, 1, 5), np.zeros(5))


def test_published_protocol_in_time_equals_the_frequency_domain_answer(lin):
    # SPEC 2's half cosine down by 0.05 um in 0.05 s, held, back up, held: one
    # 0.5 s period; the time integration from rest, over its second period,
    # against the Fourier superposition of K*(omega) at every harmonic
    eta, f, depth, dt = 10.0, 10.0, 0.05, 1e-3
    t = np.arange(500) * dt
    down = viscous_time.half_cosine(t, depth, f)
    dh = np.where(t < 0.25, down, -depth - viscous_time.half_cosine(t - 0.25, depth, f))
    assert dh[0] == 0 and dh.min() == -depth and abs(dh[-1]) < 1e-15
    periodic = viscous_time.periodic_response(lin, eta, t, dh)
    timed = viscous_time.integrate(lin, eta, np.arange(1000) * dt, np.concatenate([dh, dh]))[500:]
    assert np.abs(timed - periodic).max() < 1e-2 * np.abs(periodic).max()
    # and the viscous force is not negligible here: far from the elastic one
    elastic = viscous_time.periodic_response(lin, 0.0, t, dh)
    assert np.abs(periodic - elastic).max() > 0.1 * np.abs(periodic).max()
