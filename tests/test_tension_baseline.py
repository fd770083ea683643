"""The tilted baseline and the honest identifiability of a ramp's reading: elastic
ramps made by the solver (`synth.shell_ramp`) with a known baseline tilt added give
back γ_a and the tilt within their 95 % intervals; a tension-only droplet's tilt
is taken out by the shell's droplet valley; the nested-window test uses the
variance of the difference of nested fits and says when it cannot test."""

import numpy as np
import pytest

from analysis.afm.tension.depths import HOLDS, MOVES, NOT_TESTABLE, DepthRow, depth_test
from analysis.afm.tension.pause import Z95
from analysis.afm.tension.ramp import fit_ramp
from analysis.afm.tension.shell_fit import SIGNIFICANT, Fixed, fit_shell, shell_interval
from studies.tension_synth import droplet_force_nN, shell_ramp as elastic_ramp
from analysis.invert.measurement_errors import MeasurementErrors

NO_VOLUME_ERROR = MeasurementErrors(volume_rel_sd=0.0)


def _tilted(radius, gamma, bulk, shear, tilt, seed):
    """An elastic ramp to 0.14 R with the baseline tilt `tilt` (nN/µm against x) added about its contact."""
    x, f = elastic_ramp(radius, gamma, bulk, shear * bulk, 0.14 * radius, n=6000, noise_nN=0.02, seed=seed)
    return x, f + 3.0 + tilt * (x - 2.0 * radius)


@pytest.mark.parametrize("radius,gamma,bulk,shear,tilt,seed", [
    (6.8, 0.5, 15.0, 1.0 / 3.0, 0.12, 1),
    (8.0, 1.5, 30.0, 0.5, -0.15, 2),
    (5.5, 0.3, 8.0, 0.2, 0.08, 3),
])
def test_elastic_ramps_with_a_tilt_give_back_the_tension_and_the_tilt(radius, gamma, bulk, shear, tilt, seed):
    x, f = _tilted(radius, gamma, bulk, shear, tilt, seed)
    fixed = Fixed(shear_tilde=shear)
    fit = fit_shell(x, f, radius, fixed)
    lo, hi, k_lo, k_hi = shell_interval(fit, x, f, 4.0 * np.pi * radius ** 3 / 3.0, fixed, NO_VOLUME_ERROR)
    assert fit.elastic_term == SIGNIFICANT
    assert lo <= gamma <= hi and k_lo <= bulk <= k_hi, (fit.tension_mN_per_m, lo, hi, fit.bulk_mN_per_m)
    assert abs(fit.tension_mN_per_m / gamma - 1.0) < 0.1
    s, sd = fit.baseline_slope_nN_per_um, fit.baseline_slope_sd_nN_per_um
    assert 0.0 < sd < 0.05 and abs(s - tilt) <= Z95 * sd, (s, sd)
    assert fit.baseline_nN == pytest.approx(3.0, abs=0.01) and not fit.bimodal


def test_a_tilt_added_moves_only_the_slope():
    """The same elastic ramp read with a tilt of 0.14 nN/µm and with none: one γ_a within its
    interval, the slopes apart by the tilt within their SD."""
    radius, gamma, bulk, shear = 6.8, 0.8, 20.0, 0.5
    x, f = _tilted(radius, gamma, bulk, shear, 0.14, 4)
    level = f - 0.14 * (x - 2.0 * radius)
    fixed = Fixed(shear_tilde=shear)
    tilted, flat = fit_shell(x, f, radius, fixed), fit_shell(x, level, radius, fixed)
    assert tilted.tension_mN_per_m == pytest.approx(flat.tension_mN_per_m, abs=Z95 * flat.tension_sd_mN_per_m)
    assert tilted.baseline_slope_nN_per_um - flat.baseline_slope_nN_per_um == pytest.approx(
        0.14, abs=Z95 * flat.baseline_slope_sd_nN_per_um)


def test_a_tilted_droplet_is_read_as_the_droplet():
    """A droplet (T = 1 mN/m, R 7 µm) with a tilt of -0.15 nN/µm: the shell returns the droplet
    (K_B = 0) within 1 % of T and the tilt within 0.01 nN/µm; the level tension-only
    reading (the published one) is off by the tilt."""
    radius, tension, tilt = 7.0, 1.0, -0.15
    rng = np.random.default_rng(5)
    x = 2.0 * radius - np.linspace(-0.14 * radius, 0.14 * radius, 6000)
    f = droplet_force_nN(4.0 * np.pi * radius ** 3 / 3.0, tension, x) + tilt * (x - 2 * radius)
    f += 0.02 * rng.standard_normal(x.size)
    shell = fit_shell(x, f, radius)
    assert shell.bulk_mN_per_m == 0.0 and shell.tension_mN_per_m == pytest.approx(tension, rel=0.01)
    assert shell.baseline_slope_nN_per_um == pytest.approx(tilt, abs=0.01)
    assert abs(fit_ramp(x, f, radius, "droplet").tension_mN_per_m / tension - 1.0) > 0.02
    lo, hi, _, k_hi = shell_interval(shell, x, f, 4.0 * np.pi * radius ** 3 / 3.0, Fixed(), NO_VOLUME_ERROR)
    assert lo <= tension <= hi and k_hi > 0.0


def test_a_shallow_ramp_of_a_soft_cell_is_bimodal_and_its_interval_spans_both_valleys():
    """R 7 µm, γ_a 1, K_B 3 mN/m (K̃_S 1/3), 0.03 nN noise. Pressed to 0.05 R the droplet's valley
    (K_B = 0, γ_a 1.23) and the shell's are both in the 95 % set (Λ 3.2 ≤ 3.84) and apart by more
    than the shell's Z95 · sd: `bimodal`, the droplet reported with intervals that hold both
    (γ_a about [0.3, 2.1], K_B [0, 17]). The same cell pressed to 0.14 R chooses the shell
    (Λ 12.6), is not bimodal, and its narrow interval holds γ_a and K_B."""
    radius, gamma, bulk, fixed = 7.0, 1.0, 3.0, Fixed(shear_tilde=1.0 / 3.0)
    read = {}
    for depth in (0.05, 0.14):
        x, f = elastic_ramp(radius, gamma, bulk, bulk / 3.0, depth * radius, n=1500, noise_nN=0.03, seed=2)
        fit = fit_shell(x, f + 3.0, radius, fixed)
        read[depth] = fit, shell_interval(fit, x, f + 3.0, 4.0 * np.pi * radius ** 3 / 3.0, fixed, NO_VOLUME_ERROR)
    (shallow, (lo, hi, k_lo, k_hi)), (deep, (dlo, dhi, dk_lo, dk_hi)) = read[0.05], read[0.14]
    assert shallow.bimodal and shallow.elastic_term != SIGNIFICANT and shallow.bulk_mN_per_m == 0.0
    assert lo < gamma < shallow.tension_mN_per_m < hi and k_lo <= bulk <= k_hi
    assert hi - lo > 1.0                                       # both valleys, not one
    assert not deep.bimodal and deep.elastic_term == SIGNIFICANT
    assert dlo <= gamma <= dhi and dk_lo <= bulk <= dk_hi and dhi - dlo < 0.5


def _row(depth, gamma, sd):
    return DepthRow(depth, gamma, sd, 10.0, float("nan"), float("nan"))


def test_nested_windows_are_tested_by_their_difference():
    """γ_a 1.0 ± 0.1 (SD) on the full window, 1.3 ± 0.15 on a nested shallower one: their
    independent-sum test (±0.35) would pass it; the difference's SD is sqrt(0.15² - 0.1²) =
    0.11, so 0.3 is beyond its 95 % and the tension moves."""
    full = _row(0.5, 1.0, 0.1)
    assert depth_test([_row(0.3, 1.3, 0.15), full])[0] == MOVES
    assert depth_test([_row(0.3, 1.1, 0.15), full]) == (HOLDS, "")


def test_shallow_windows_without_information_are_not_testable():
    """The real ramps' case: shallow windows ±2 to ±4.7 mN/m (95 %) around γ_a ≈ 1: no change of
    γ_a by its whole value could show, so the test says so instead of 'holds'."""
    rows = [_row(0.19, 2.37, 2.4), _row(0.28, 2.37, 1.2), _row(0.37, 0.94, 0.9), _row(0.47, 1.11, 0.3)]
    verdict, why = depth_test(rows)
    assert verdict == NOT_TESTABLE and why.startswith("not testable")
    rows[2] = _row(0.37, 1.0, 0.32)               # an informative window that agrees: it holds
    assert depth_test(rows)[0] == HOLDS


def test_an_export_without_times_is_timed_by_its_speed():
    """A piezo ramp sampled evenly in time at 3 µm/s (the piezo's height z evenly spaced), the
    gap x = z - F/k slowing in contact (k 0.078 N/m = 78 nN/µm): the times built from
    `--ramp-speed-um-per-s` (the slope of x per sample above the contact over the speed) are the
    piezo's own, to 1e-9 s."""
    from analysis.afm.tension.pipeline import even_times
    radius, speed, k = 6.8, 3.0, 78.0
    x, f = elastic_ramp(radius, 1.0, 10.0, 10.0 / 3.0, 0.1 * radius, n=20000, noise_nN=0.0)
    z = x - f / k                                # the piezo's height at each gap (x = z + F/k): falls monotonically
    base = np.linspace(z[0], z[-1], 1200)        # sampled evenly in z, so evenly in time
    gap, force = np.interp(-base, -z, x), np.interp(-base, -z, f)
    t = (base[0] - base) / speed
    steps = -np.diff(gap)
    assert steps[-1] < 0.97 * steps[0]           # the gap moves slower in contact
    assert even_times(gap, force, speed) == pytest.approx(t, abs=1e-9)
