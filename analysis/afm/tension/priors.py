"""Priors for the shell reading of a ramp from the same recording's oscillations (SPEC 10, 11).

A recording that also holds oscillation segments has already told its cortex's moduli: the
viscoelastic reading of `cortex afm analyze` (`analysis.afm.analyze.measure` and `inverted`,
then `analysis.afm.rheology.per_frequency`, relaxed state, standard bending, the shipped
calibration or the bundle `--calibration` names, `calibration_parts`) gives per frequency
θ = (ln |K_B*|, ln K̃_S*, δ_B, δ_S) and its bootstrap draws. Per draw and for the point, the relaxation laws K_B(t) = K_B(1 s) t^-β_B and K_S(t) = K_S(1 s)
t^-β_S (`rheology.power_law`: the slope of ln |K*| in ln f, one frequency β = 2δ/π;
`rheology.modulus_1s`: K(1 s) = |K*(1 Hz)| / (Γ(1-β) (2π)^β)).

The ramp's time scale. An approach at constant speed v compresses the free sphere by δ = v t,
and its area strain grows like δ² (SPEC 11), so ε_A(t) = ε_A(T) (t/T)² up to the window's
depth d, reached after T = d / v. A power-law cortex's stress at T (Boltzmann superposition) is
∫_0^T K(T - s) dε_A(s) = K(T) ε_A(T) · 2/((1-β)(2-β)), so the modulus the elastic shell reads
from that ramp is its secant

    K_ramp = K(1 s) T^-β · 2/((1-β)(2-β))                      (`ramp_modulus`)

(β = 0: K itself), for the bulk and the shear modulus alike; K̃_S = K_S,ramp / K_B,ramp. d is the
depth of the shell fit's window (the droplet fit's, `ramp.fit_ramp`, capped as the shell's), v the
row's ramp speed (`pipeline._ramp_speed`); without a speed there is no prior.

Gaussian priors (`Prior`): K_B,ramp (mN/m), ln K̃_S and β_B, β_S, each centred on the point
reading with SD = (95 % interval's width) / (2 · 1.96) of the draws (percentile interval). In the
shell fit (`shell_fit._solve`) they are rows appended to the residual vector, σ (K_B - K_B,ramp)
/ sd_K and σ (ln K̃_S - ln K̃_S,ramp) / sd_lnS, σ the ramp's force noise (`ramp.baseline_noise`):
the fit's SSE / σ² is then -2 ln of the posterior, so the profile over K̃_S (`shell_shear`), the
elastic term's Λ and every interval read the posterior. β enters the elastic shell only through
K_ramp (its SD carried by the draws); it is kept for a fit that has β (a power-law ramp).
Limits: the relaxed-state reading (no protocol correction) and the t² strain are approximations;
a cortex that relaxes much during the ramp is not an elastic shell whatever its priors.
"""

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from analysis.afm.tension.pause import Z95

if TYPE_CHECKING:
    from analysis.afm.cell import Cell
    from analysis.calibration.file import CalibrationFile
    from analysis.invert.measurement_errors import MeasurementErrors

OSCILLATIONS, NONE = "oscillations", "none"
BENDING = "standard"


@dataclass(frozen=True)
class Laws:
    """A cell's relaxation laws from its oscillations: (ln K_B(1 s), β_B, ln K_S(1 s), β_S) of the
    point reading (`point`, shape (4,)) and of each bootstrap draw (`draws`, (M, 4))."""

    point: np.ndarray
    draws: np.ndarray


@dataclass(frozen=True)
class Prior:
    """The Gaussian priors of one ramp (module doc): K_B (mN/m) and K̃_S at the ramp's time scale
    `time_scale_s`, with the SD of K_B and of ln K̃_S, the exponents with their SDs, and the
    ramp's force noise σ (nN) that weighs the penalty."""

    bulk_mN_per_m: float
    bulk_sd_mN_per_m: float
    shear_tilde: float
    shear_log_sd: float
    bulk_exponent: float
    bulk_exponent_sd: float
    shear_exponent: float
    shear_exponent_sd: float
    time_scale_s: float
    noise_nN: float

    def penalty(self, bulk_mN_per_m: float, shear_tilde: float) -> np.ndarray:
        """The rows the fit's residual vector gains (nN): σ (K_B - K̄_B)/sd_K, σ (ln K̃_S - ln K̄_S)/sd."""
        return self.noise_nN * np.array([(bulk_mN_per_m - self.bulk_mN_per_m) / self.bulk_sd_mN_per_m,
                                         np.log(shear_tilde / self.shear_tilde) / self.shear_log_sd])


def ramp_modulus(k_1s: Any, beta: Any, time_s: float) -> Any:
    """K_ramp (mN/m) = K(1 s) T^-β · 2/((1-β)(2-β)): the secant modulus at T = `time_s` of a
    ramp whose strain grows as t² (module doc)."""
    beta = np.asarray(beta, float)
    return np.asarray(k_1s) * time_s ** -beta * 2.0 / ((1.0 - beta) * (2.0 - beta))


def _calibration() -> "CalibrationFile":
    """The shipped calibration bundle (read once, `calibration_parts.shipped_parts`): the default
    of `read_laws`."""
    from analysis.afm.tension.calibration_parts import shipped_parts
    return shipped_parts().oscillations


def read_laws(cell: "Cell", errors: "MeasurementErrors | None" = None,
              calibration: "CalibrationFile | None" = None) -> "Laws | str":
    """The `Laws` of `cell`'s oscillations (module doc), or why there are none; `errors` the volume's
    and height's (the oscillation reading's own count of draws); `calibration` the bundle whose
    emulator and complex-modulus table read them (None: the shipped one)."""
    from analysis.afm.analyze import inverted, measure
    from analysis.afm.rheology import modulus_1s, per_frequency, power_law
    from analysis.invert.measurement_errors import MeasurementErrors
    from analysis.invert.method import choose
    from common.errors import InputError
    errors = MeasurementErrors() if errors is None else MeasurementErrors(errors.volume_rel_sd, errors.height_sd_um)
    try:
        cal = _calibration() if calibration is None else calibration
        cal.require(("emulator", "viscoelastic_table"), "the oscillation priors (--no-oscillation-priors: off)")
        measured = measure([cell])
        table = inverted(measured, choose(cal.default_method, cal.calibration, cal.emulator, cal.where), BENDING,
                         errors)
        _, theta, th_m = per_frequency(table, measured.segments, cal.viscoelastic.emulator, BENDING,
                                       cal.viscoelastic.table, errors)
    except InputError as err:
        return f"oscillations not read: {err}"
    ok = np.isfinite(theta).all(axis=1)
    if not ok.any():
        reasons = table["excluded_reason"].dropna()
        return "oscillations not read: " + (str(reasons.iloc[0]) if len(reasons) else "no curve with 3 heights")
    log_f = np.log(table["frequency_hz"].to_numpy(float)[ok])
    out = []
    for th in (theta[ok][:, None, :], th_m[ok]):           # (frequencies, draws, 4)
        laws = []
        for y, delta in ((th[..., 0], th[..., 2]), (th[..., 0] + th[..., 1], th[..., 3])):
            beta, at_1hz = power_law(log_f, y, delta)
            laws += [np.log(modulus_1s(np.exp(at_1hz), beta)), beta]
        out.append(np.stack(laws, axis=-1))
    return Laws(point=out[0][0], draws=out[1][np.isfinite(out[1]).all(axis=1)])


def _sd(values: np.ndarray) -> float:
    """SD of a Gaussian with the 95 % percentile interval of `values`."""
    lo, hi = np.percentile(values, [2.5, 97.5])
    return float(max(hi - lo, 1e-12) / (2.0 * Z95))


def prior(laws: Laws, time_s: float, noise_nN: float) -> Prior:
    """The `Prior` of a ramp of time scale T = `time_s` (s) and force noise σ = `noise_nN` (nN)."""
    def at(th: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        kb = ramp_modulus(np.exp(th[..., 0]), th[..., 1], time_s)
        return kb, ramp_modulus(np.exp(th[..., 2]), th[..., 3], time_s) / kb
    kb, ks = at(laws.point)
    kb_m, ks_m = at(laws.draws)
    return Prior(bulk_mN_per_m=float(kb), bulk_sd_mN_per_m=_sd(kb_m), shear_tilde=float(ks),
                 shear_log_sd=_sd(np.log(ks_m)), bulk_exponent=float(laws.point[1]),
                 bulk_exponent_sd=_sd(laws.draws[:, 1]), shear_exponent=float(laws.point[3]),
                 shear_exponent_sd=_sd(laws.draws[:, 3]), time_scale_s=float(time_s), noise_nN=float(noise_nN))


def columns(p: "Prior | None", why: str = "") -> dict[str, Any]:
    """The row's columns of the priors: `prior_source` (OSCILLATIONS or NONE), the values
    (NaN without), and `prior_note` (why there is none; '' with one)."""
    nan = float("nan")
    return {"prior_source": OSCILLATIONS if p else NONE, "prior_note": "" if p else why,
            "prior_bulk_modulus_mN_per_m": p.bulk_mN_per_m if p else nan,
            "prior_bulk_modulus_sd_mN_per_m": p.bulk_sd_mN_per_m if p else nan,
            "prior_shear_ratio": p.shear_tilde if p else nan, "prior_shear_ratio_log_sd": p.shear_log_sd if p else nan,
            "prior_bulk_exponent": p.bulk_exponent if p else nan,
            "prior_bulk_exponent_sd": p.bulk_exponent_sd if p else nan,
            "prior_shear_exponent": p.shear_exponent if p else nan,
            "prior_shear_exponent_sd": p.shear_exponent_sd if p else nan,
            "prior_time_scale_s": p.time_scale_s if p else nan}


COLUMNS = tuple(columns(None))
