"""The per-cell inversion (SPEC 6): exact on curves made by the law, unbiased
under noise, and the published filters exclude what they should, with reasons."""

import numpy as np
import pytest

from analysis.calibration.law import Calibration, poisson, shear_ratio
from analysis.invert.inversion import invert_cell, invert_curves
from analysis.calibration.law_fits import modulus_law
from studies.synthetic import reference_law

LAW = reference_law("standard")
CAL = Calibration({"standard": LAW, "double": reference_law("double")})
H = np.array([0.73, 0.68, 0.63, 0.58, 0.53, 0.48])


def curve(nu, tension=1.5, bulk=25.0, h=H, law=LAW):
    """K(h~) of a cell with Poisson ratio nu according to the law."""
    alpha = law.alpha_of(shear_ratio(nu), tension / bulk)
    return modulus_law(h, bulk, alpha, law.lam)


@pytest.mark.parametrize("nu, tension, bulk", [(0.5, 1.5, 25.0), (0.25, 0.7, 25.0), (0.05, 2.9, 31.0),
                                               (0.43, 1.0, 18.0)])
def test_exact_curve_gives_exact_nu(nu, tension, bulk):
    r = invert_cell(H, curve(nu, tension, bulk), tension, CAL)
    assert r.excluded_reason is None
    assert r.nu == pytest.approx(nu, abs=1e-10)
    assert r.bulk_mN_per_m == pytest.approx(bulk, rel=1e-10)
    assert r.ks_tilde == pytest.approx(shear_ratio(nu), rel=1e-9)
    assert r.gamma_tilde == pytest.approx(tension / bulk, rel=1e-10)
    assert r.r2 == pytest.approx(1.0, abs=1e-12)
    assert r.n_heights == 5 and r.h_tilde_max == 0.73          # 0.48 is outside the window


def test_variant_is_selectable_and_a_law_works_directly():
    K = curve(0.3, law=CAL["double"])
    assert invert_cell(H, K, 1.5, CAL, bending="double").nu == pytest.approx(0.3, abs=1e-10)
    assert invert_cell(H, K, 1.5, CAL["double"]).nu == pytest.approx(0.3, abs=1e-10)
    assert abs(invert_cell(H, K, 1.5, CAL, bending="standard").nu - 0.3) > 1e-3


def test_unbiased_under_noise():
    """1 % noise on K, 2000 seeded cells: the median recovered ν is within
    3 standard errors (1.25 σ/√n) of the truth; the mean K_B too."""
    rng = np.random.default_rng(11)
    K = curve(0.4) * (1 + 0.01 * rng.standard_normal((2000, H.size)))
    out = invert_curves(np.tile(H, (2000, 1)), K, 1.5, CAL)
    ok = out[out["excluded_reason"].isna()]
    assert len(ok) > 1900
    se = 1.2533 * ok["nu"].std() / np.sqrt(len(ok))
    assert abs(ok["nu"].median() - 0.4) < 3 * se
    se_b = ok["bulk_mN_per_m"].std() / np.sqrt(len(ok))
    assert abs(ok["bulk_mN_per_m"].mean() - 25.0) < 3 * se_b


def test_heights_outside_the_window_do_not_matter():
    K = curve(0.25)
    junk_h = np.r_[H, 0.80, 0.45]
    junk_k = np.r_[K, 1e6, -1e6]
    a, b = invert_cell(H, K, 1.5, CAL), invert_cell(junk_h, junk_k, 1.5, CAL)
    assert a.nu == pytest.approx(b.nu, abs=1e-12) and a.n_heights == b.n_heights == 5
    nan_k = K.copy()
    nan_k[1] = np.nan                                             # a missing height is dropped
    assert invert_cell(H, nan_k, 1.5, CAL).n_heights == 4


def test_filter_needs_four_heights():
    r = invert_cell(H[:3], curve(0.4)[:3], 1.5, CAL)
    assert r.excluded_reason == "only 3 height(s) with 0.5 <= h~ <= 0.75 (need 4)"
    assert invert_cell(H[:4], curve(0.4)[:4], 1.5, CAL).excluded_reason is None


def test_filter_highest_height_above_068():
    h = np.array([0.675, 0.64, 0.6, 0.56, 0.52])
    r = invert_cell(h, curve(0.4, h=h), 1.5, CAL)
    assert r.excluded_reason == "highest h~ = 0.675 is not above 0.68"
    assert r.nu == pytest.approx(0.4, abs=1e-9)                  # still computed, for diagnostics


def test_filter_r2_unless_nu_above_07():
    """A zigzag as large as the trend: R² drops below 0.5 and ν stays < 0.7:
    excluded. The same curve without the zigzag passes."""
    h = np.linspace(0.5, 0.74, 8)
    K = curve(0.3, h=h)
    zigzag = np.array([1, -1] * 4) * np.ptp(K)
    r = invert_cell(h, K + zigzag, 1.5, CAL)
    assert r.r2 <= 0.5 and r.nu <= 0.7
    assert r.excluded_reason == f"R^2 = {r.r2:.2f} is not above 0.5 (and nu = {r.nu:.2f} <= 0.7)"
    assert invert_cell(h, K, 1.5, CAL).excluded_reason is None


def test_r2_exception_for_flat_curves_is_exercised():
    """Force the case: a curve whose fit gives ν > 0.7 and R² ≤ 0.5 passes."""
    h = np.linspace(0.5, 0.74, 6)
    flat = curve(0.9, h=h)
    bump = np.array([0.0, 0.3, -0.3, 0.3, -0.3, 0.0]) * np.ptp(flat) * 3
    r = invert_cell(h, flat + bump, 1.5, CAL)
    assert r.r2 <= 0.5
    assert r.nu > 0.7
    assert r.excluded_reason is None


def test_filter_nonpositive_bulk_and_tension():
    h = H[:5]
    r = invert_cell(h, -curve(0.4, h=h) - 5, 1.5, CAL)
    assert "K_B" in r.excluded_reason and "not positive" in r.excluded_reason
    r = invert_cell(h, curve(0.4, h=h), 0.0, CAL)
    assert r.excluded_reason == "active tension 0 mN/m is not positive"


def test_batched_equals_single_and_reasons_in_order():
    h = np.array([H, H, np.r_[H[:3], np.nan, np.nan, np.nan]])
    K = np.array([curve(0.1, tension=1.0), curve(0.45, tension=2.0), curve(0.3)])
    out = invert_curves(h, K, [1.0, 2.0, 1.5], CAL)
    assert list(out.columns) == ["nu", "ks_tilde", "bulk_mN_per_m", "alpha", "r2", "gamma_tilde",
                                 "n_heights", "h_tilde_max", "excluded_reason"]
    for i, tension in enumerate([1.0, 2.0]):
        one = invert_cell(h[i], K[i], tension, CAL)
        assert out.loc[i, "nu"] == one.nu
    assert out["excluded_reason"].tolist()[:2] == [None, None]
    assert out.loc[2, "excluded_reason"].startswith("only 3 height(s)")
    assert poisson(out.loc[0, "ks_tilde"]) == pytest.approx(0.1, abs=1e-10)


def test_one_implementation_per_method_and_the_part_each_needs():
    """`choose` builds the inversion a calibration file's parts serve, and refuses a file
    without the part the method needs with its one line."""
    from analysis.invert.method import INVERSIONS, EmulatorInversion, LawInversion, choose
    from analysis.calibration.file import load_calibration
    from common.errors import InputError
    from common.names import INVERSION_METHODS
    file = load_calibration()
    cal, emu = file.calibration, file.emulator
    assert tuple(INVERSIONS) == INVERSION_METHODS
    assert isinstance(choose("law", cal, None), LawInversion)
    assert isinstance(choose("emulator", None, emu), EmulatorInversion)
    assert choose("law", cal, emu).variants() == list(cal.laws)
    assert choose("emulator", cal, emu).variants() == list(emu.tables)
    with pytest.raises(InputError, match="no emulator tables"):
        choose("emulator", cal, None)
    with pytest.raises(InputError, match="no paper law"):
        choose("law", None, emu)
    with pytest.raises(InputError, match="method must be one of"):
        choose("spline", cal, emu)
