"""The power-law shell's columns of an approach row of `cortex afm tension --power-law`
(`powerlaw_fit`: the ramp and the pause right after it read as one curve).

The pause is taken as a constant-height hold unless it looks like a constant-force one
(its height x drifts by more than FORCE_HOLD_DRIFT_UM between its first and last tenth
while its force stays within FORCE_HOLD_SDS noise SDs); `power_law_hold` says which
(none: no pause after the ramp). K̃_S is the given `--shear-ratio` (GIVEN), else the
oscillations' prior's K̃_S at the ramp's time scale taken as given (PRIOR,
`priors.Prior.shear_tilde`), else profiled (PROFILED, `powerlaw_shear`: its 95 % interval in
`power_law_shear_ratio_lo95`/`_hi95`; given: both the value); `power_law_shear_ratio_source`
says which. `power_law_model` says whether the reading's fit read the power-law table (`table`,
`powerlaw_tabled`) or simulated (`simulator`: a constant-force hold, or a fit outside the table).
A ramp without sample times, or one the fit cannot read, gets the reason in
`power_law_note` and no values.
"""

from typing import Any

import numpy as np

from analysis.afm.tension.powerlaw_fit import PowerLawFit, fit_ramp_hold
from analysis.afm.tension.powerlaw_shear import fit_ramp_hold_profiled
from analysis.afm.tension.priors import Prior
from analysis.afm.tension.ramp import baseline_noise
from analysis.calibration.powerlaw_table import PowerLawTable
from analysis.calibration.ramp_table import ShellTable
from common.errors import InputError, SolverError

FORCE_HOLD_DRIFT_UM = 0.02
FORCE_HOLD_SDS = 3.0
COLUMNS = ("power_law_tension_mN_per_m", "power_law_tension_lo95_mN_per_m", "power_law_tension_hi95_mN_per_m",
           "power_law_bulk_1s_mN_per_m", "power_law_bulk_1s_sd_mN_per_m", "power_law_exponent",
           "power_law_exponent_sd", "power_law_shear_ratio", "power_law_shear_ratio_lo95", "power_law_shear_ratio_hi95",
           "power_law_shear_ratio_source", "power_law_hold", "power_law_model", "power_law_note")
GIVEN, PRIOR, PROFILED = "given", "oscillation prior", "profiled"
TABLE, SIMULATOR = "table", "simulator"     # power_law_model: the tabled simulator or the simulator itself


def hold_kind(x_um: np.ndarray, force_nN: np.ndarray, noise_nN: float) -> str:
    """"height" or "force": how the pause was held (module doc)."""
    tenth = max(len(x_um) // 10, 1)
    drift = abs(float(np.mean(x_um[-tenth:]) - np.mean(x_um[:tenth])))
    change = abs(float(np.mean(force_nN[-tenth:]) - np.mean(force_nN[:tenth])))
    return "force" if drift > FORCE_HOLD_DRIFT_UM and change < FORCE_HOLD_SDS * noise_nN else "height"


def _fit(t: np.ndarray, x: np.ndarray, f: np.ndarray, end: int, radius_um: float, shear_tilde: float | None,
         hold: str, table: ShellTable | None, powerlaw: PowerLawTable | None) -> PowerLawFit:
    """The fit at the given K̃_S, or with it profiled (None); `table` the shell ramp table,
    `powerlaw` the power-law table."""
    if shear_tilde is None:
        return fit_ramp_hold_profiled(t, x, f, end, radius_um, hold, table, powerlaw)
    return fit_ramp_hold(t, x, f, end, radius_um, shear_tilde, hold, table, powerlaw)


def power_law_columns(ramp: tuple[np.ndarray, np.ndarray, np.ndarray],
                      pause: tuple[np.ndarray, np.ndarray, np.ndarray] | None,
                      radius_um: float, shear_tilde: float | None, prior: Prior | None = None,
                      table: ShellTable | None = None, powerlaw: PowerLawTable | None = None) -> dict[str, Any]:
    """The columns (COLUMNS) of one approach (t s, x µm, F nN) and the pause after it (or None),
    K̃_S `shear_tilde` given, else the oscillations' `prior`'s, else profiled (module doc);
    `table` the shell ramp table of the surrogate, `powerlaw` the power-law table of the tabled
    simulator (None: the shipped ones)."""
    t, x, f = ramp
    source = GIVEN if shear_tilde is not None else PRIOR if prior is not None else PROFILED
    shear = shear_tilde if shear_tilde is not None else prior.shear_tilde if prior is not None else None
    out: dict[str, Any] = {k: float("nan") for k in COLUMNS}
    out.update(power_law_shear_ratio_source=source, power_law_hold="none", power_law_model="", power_law_note="")
    if shear is not None:
        out.update(power_law_shear_ratio=shear, power_law_shear_ratio_lo95=shear, power_law_shear_ratio_hi95=shear)
    end = int(np.argmin(x)) + 1                          # the ramp up to its deepest sample
    t, x, f = t[:end], x[:end], f[:end]
    if pause is not None:
        kind = hold_kind(pause[1], pause[2], baseline_noise(f)[1])
        t, x, f = (np.r_[a, b] for a, b in zip((t, x, f), pause))
        out["power_law_hold"] = kind
    if not np.all(np.isfinite(t)):
        out.update(power_law_hold="none", power_law_note="no sample times")
        return out
    try:
        fit = _fit(t, x, f, end, radius_um, shear, out["power_law_hold"] if pause is not None else "height", table,
                   powerlaw)
    except (InputError, SolverError) as err:
        out.update(power_law_note=f"not read: {err}")
        return out
    lo, hi = fit.tension_interval_mN_per_m
    out.update(power_law_tension_mN_per_m=fit.tension_mN_per_m, power_law_tension_lo95_mN_per_m=lo,
               power_law_tension_hi95_mN_per_m=hi, power_law_bulk_1s_mN_per_m=fit.bulk_1s_mN_per_m,
               power_law_bulk_1s_sd_mN_per_m=fit.bulk_1s_sd_mN_per_m, power_law_exponent=fit.beta,
               power_law_exponent_sd=fit.beta_sd, power_law_model=TABLE if fit.tabled else SIMULATOR)
    if fit.shear_band is not None:
        out.update(power_law_shear_ratio=fit.shear_tilde, power_law_shear_ratio_lo95=fit.shear_band[0],
                   power_law_shear_ratio_hi95=fit.shear_band[1])
    return out
