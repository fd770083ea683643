"""`cortex afm tension FILES`: read -> analyse -> write (docs/tension.md).

read     every FILE on its own by the one reader, `formats.open`: an experiment
         (.h5/.hdf5) or single-cell CSV (heights are gaps, volumes their own), else
         an instrument file or a folder of them (heights x = z + F/k - Z, with Z
         the dish reference when one is given, else the height channel, left for
         the contact point, `ImportOptions.contact_heights`), each recording with
         its volume (`--volume`, `--volumes` or `--radius-um` R: V = 4πR³/3);
analyse  per recording, in order until its first retract: every approach ramp
         fitted by the selected model: `shell` (`shell_fit`: γ_a and K_B of the
         elastic cortex at the given K_S/K_B, or `shell_shear` with K_S/K_B fitted
         by its profile; where the recording holds oscillations, with the
         Gaussian priors on K_B and K_S/K_B at the ramp's time scale that their
         viscoelastic reading gives (`priors`; `_laws` once per recording,
         its heights from the first ramp's contact without a dish reference,
         `_ramp_prior` per ramp; off with Options.oscillation_priors False),
         window capped at the shell table's depth and
         `--max-depth-um`; the shell ramp table and the priors' calibration those
         of `Options.calibration` (`calibration_parts`: `--calibration`'s, else the
         shipped ones), the one table every fit of the shell reads; intervals
         `shell_fit.shell_interval`; the apparent
         tensions of the droplet and small-deformation readings on the same
         window beside it; each model against the window's depth, `depths`),
         or a tension-only one (`ramp`, with the other for comparison, each on
         its own automatic window; the interval from the volume error,
         `pause.ramp_interval`), with the ramp's speed and where it comes from
         (`_ramp_speed`: recorded times, `--ramp-speed-um-per-s` for a recording
         without them, or unknown) and a warning where `--max-depth-um` is deeper
         than the data (`_depth_warning`); by default (Options.power_law None)
         the shell's rows also get the power-law shell's reading of the ramp
         and the pause after it (`powerlaw_row`), every model's with
         `--power-law` (True), none with `--no-power-law` (False), a
         tension-only model's row the reason (`_power_law`); each row's
         headline tension (`headline`: the power-law γ_a where read, else the
         row's own model's, the elastic shell's the β = 0 reading); every pause's tension and pressure
         (`pause.pause_tension`) from its relaxed force (`relaxation`; the
         last half's mean force beside it for comparison), above the
         first fitted ramp's free baseline (the median force of its first 30 %,
         `ramp.baseline_noise`: the deflection with nothing touching), at
         its height: the recorded gap where the dish is known (native files,
         `--dish-height-um`, `--dish-curve`), else h = 2R - (x0 - x) from that
         ramp's contact x0, else the height channel (Z = 0), each the last
         half's mean;
         Recordings are analysed in two halves, the later in a forked process
         beside this one (`common.beside`) where there are two CPUs.
write    `--out DIR`: tension.csv (one row per analysed part), one figure per
         recording (`report`), report.md, which also lists what was not
         analysed.

A file or recording that cannot be read or analysed is set aside with its
reason; if nothing is left, the first reason is the InputError (exit status 2,
nothing written); otherwise the command ends with status 1.
"""

from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from analysis.afm.cell import Cell
from analysis.afm.formats.reader import ImportOptions
from analysis.afm.formats.reader import open as open_cells
from analysis.afm.tension.calibration_parts import TensionCalibration, shipped_parts
from analysis.afm.tension.shell_ramp import resolve
from analysis.afm.tension.depths import depth_rows, depth_test
from analysis.afm.tension.priors import Laws, Prior, prior, read_laws
from analysis.afm.tension.priors import columns as prior_columns
from analysis.afm.tension.powerlaw_row import COLUMNS as POWER_LAW_COLUMNS
from analysis.afm.tension.powerlaw_row import power_law_columns
from analysis.afm.tension.ramp import MODELS, baseline_noise, contact_guess, fit_ramp, force_per_tension_um
from analysis.afm.tension.shell_fit import NOT_SIGNIFICANT, Fixed, ShellFit, fit_shell, shell_interval
from analysis.afm.tension.shell_shear import fit_unknown_shear, identification
from analysis.afm.tension.pause import TENSION_ERRORS, pause_tension, pressure_Pa, ramp_interval
from analysis.afm.tension.relaxation import fit_relaxation, relaxation_columns
from analysis.afm.tension.report import REPORT, TABLE, Analysed, file_names, headline, write
from analysis.calibration.powerlaw_table import PowerLawTable
from analysis.calibration.ramp_table import ShellTable
from analysis.invert.measurement_errors import MeasurementErrors
from common.beside import beside
from common.errors import InputError
from common.names import RAMP_MODELS
from solver.geometry import cell_radius

MIN_FREE = 10            # samples above the contact to read a ramp's speed from
TIMES_FROM_SPEED = "times from --ramp-speed-um-per-s (samples taken evenly in time)"


@dataclass(frozen=True)
class Options:
    """What to analyse with: the ramp model (and for the shell: whether the recording's
    oscillations give it priors, K̃_S, K_B if known, the deepest deformation), how to read the files (one of the volume sources, the dish reference; heights
    refer to the approach's contact point without one), the errors, and the calibration parts
    (`calibration_parts`: the shell ramp table, the priors' bundle, the power-law table; None: the
    shipped ones)."""

    model: str = "shell"
    oscillation_priors: bool = True           # the shell's priors from the recording's oscillations (`priors`)
    shear_tilde: float | None = None          # None: unknown, fitted (`shell_shear`)
    bulk_mN_per_m: float | None = None
    max_depth_um: float | None = None
    ramp_speed_um_per_s: float | None = None   # of ramps whose files hold no sample times
    power_law: bool | None = None             # the power-law shell's ramp-and-hold reading (`powerlaw_row`):
                                              # None with the shell model, True with every model, False none
    import_options: ImportOptions = ImportOptions(contact_heights=True, untimed_ramps=True)
    errors: MeasurementErrors = TENSION_ERRORS
    calibration: TensionCalibration | None = None

    @property
    def table(self) -> ShellTable | None:
        """The shell ramp table every fit reads (None: the shipped one, `shell_ramp.resolve`)."""
        return None if self.calibration is None else self.calibration.table

    @property
    def powerlaw_table(self) -> PowerLawTable | None:
        """The power-law table the power-law reading reads (None: the shipped one, `powerlaw_tabled.resolve`)."""
        return None if self.calibration is None else self.calibration.powerlaw


@dataclass
class Trace:
    """One recording ready for the analysis: its parts (segment index, kind, t (s),
    F (nN), x (µm)); `dish_known` when x is the gap itself; `cell` the recording itself when it
    holds oscillation segments (the shell's priors, `priors`), else None."""

    cell_id: str
    source: str
    volume_um3: float
    volume_source: str
    parts: list[tuple[int, str, np.ndarray, np.ndarray, np.ndarray]]
    dish_known: bool
    timed: bool = True
    cell: Cell | None = None


def _trace(cell: Cell) -> Trace:
    """A cell (`formats.open`) as the analysis takes it: its segments' samples in order."""
    parts = [(i, s.kind, cell.time_s[s.start:s.stop], cell.force_nN[s.start:s.stop], cell.height_um[s.start:s.stop])
             for i, s in enumerate(cell.segments)]
    return Trace(cell.cell_id, cell.source, cell.volume_um3, cell.volume_source, parts, cell.dish_known, cell.timed,
                 cell if cell.oscillations() else None)


def read(paths: Sequence[str | Path], options: Options) -> tuple[list[Trace], dict[str, str]]:
    """(traces, {file or cell: reason}) of FILES, each read on its own by `formats.open`;
    InputError for bad options (the volume table and the dish curve are read first)."""
    if options.model not in RAMP_MODELS:
        raise InputError(f"--model {options.model!r}: not one of {', '.join(RAMP_MODELS)}")
    for name, value in (("--shear-ratio", options.shear_tilde), ("--bulk-mN-per-m", options.bulk_mN_per_m),
                        ("--max-depth-um", options.max_depth_um), ("--ramp-speed-um-per-s", options.ramp_speed_um_per_s)):
        if value is not None and not (np.isfinite(value) and value > 0):
            raise InputError(f"{name} must be a positive number (got {value})")
    reading = options.import_options.check()
    if reading.volumes_csv is not None:
        from analysis.afm.formats.instruments import read_volumes
        read_volumes(reading.volumes_csv)
    if reading.dish_curve is not None:
        from analysis.afm.formats.instruments import dish_from_curve
        reading = replace(reading, dish_um=dish_from_curve(reading.dish_curve), dish_curve=None)
    traces, skipped = [], {}
    for p in map(Path, paths):
        try:
            traces += [_trace(c) for c in open_cells([p], reading)]
        except InputError as err:
            skipped[str(p)] = str(err) if str(p) in str(err) else f"{p}: {err}"
    seen: dict[str, str] = {}
    for t in traces:
        if t.cell_id in seen:
            raise InputError(f"cell id '{t.cell_id}' twice ({seen[t.cell_id]} and {t.source})")
        seen[t.cell_id] = t.source
    return traces, skipped


def _apparent(x: np.ndarray, f: np.ndarray, radius: float, model: str, cap: float | None) -> float:
    """The apparent tension of a tension-only `model` on deformations up to `cap` (NaN if it fails)."""
    try:
        return fit_ramp(x, f, radius, model, cap_um=cap).tension_mN_per_m
    except InputError:
        return float("nan")


def _no_laws(trace: Trace, options: Options) -> str:
    """Why the recording gives the shell no priors before any reading ('' where it may)."""
    if not options.oscillation_priors:
        return "--no-oscillation-priors"
    return "" if trace.cell is not None else "no oscillation segment in the recording"


def _laws(trace: Trace, options: Options, contact_um: float, radius: float) -> Laws | str:
    """The relaxation laws of the recording's oscillations for the shell's priors (`priors.read_laws`),
    or why there are none. Without a dish reference the heights are the wedge's x: the gaps are
    h = 2R - (x0 - x) from the first ramp's contact x0 = `contact_um`, as for the pauses."""
    cell = trace.cell
    assert cell is not None, "_no_laws first"
    if not trace.dish_known:
        cell = replace(cell, height_um=cell.height_um + (2.0 * radius - contact_um))
    return read_laws(cell, options.errors, None if options.calibration is None else options.calibration.oscillations)


def _ramp_prior(trace: Trace, laws: Laws | str | None, t: np.ndarray, x: np.ndarray, f: np.ndarray,
                options: Options, radius: float) -> tuple[tuple[Prior | None, str], Laws | str]:
    """((the ramp's priors, '') or (None, why), the recording's laws, read at its first ramp when
    `laws` is None, `_laws`): the laws at the ramp's time scale T = d / v (`priors`; d the depth of
    the shell's window, the droplet fit's, v the ramp's speed)."""
    laws = laws if laws is not None else (_no_laws(trace, options) or None)
    if isinstance(laws, str):
        return (None, laws), laws
    cap = resolve(options.table).max_depth * radius
    cap = cap if options.max_depth_um is None else min(cap, options.max_depth_um)
    drop = fit_ramp(x, f, radius, "droplet", cap_um=cap)
    laws = _laws(trace, options, drop.contact_um, radius) if laws is None else laws
    if isinstance(laws, str):
        return (None, laws), laws
    speed = _ramp_speed(t, x, drop.contact_um, options.ramp_speed_um_per_s)["ramp_speed_um_per_s"]
    if not (np.isfinite(speed) and speed > 0 and drop.depth_um > 0):
        return (None, "the ramp's speed is unknown: no time scale to read the oscillations' moduli at"), laws
    return (prior(laws, drop.depth_um / speed, baseline_noise(f)[1]), ""), laws


def _shell_row(trace: Trace, index: int, x: np.ndarray, f: np.ndarray, options: Options, radius: float,
               ramp_prior: tuple[Prior | None, str] = (None, "")) -> tuple[dict[str, Any], tuple[Any, ...]]:
    """The row and plot of one approach ramp by the shell (the droplet for comparison, on the same
    window), with the priors `ramp_prior` (`_ramp_prior`: the prior or None and why)."""
    pr = ramp_prior[0]
    if options.shear_tilde is not None:
        fit = fit_shell(x, f, radius, Fixed(options.shear_tilde, options.bulk_mN_per_m, pr, options.table),
                        cap_um=options.max_depth_um)
    else:
        fit = fit_unknown_shear(x, f, radius, options.bulk_mN_per_m, cap_um=options.max_depth_um, prior=pr,
                                table=options.table)
    # the volume refits and nested windows: at the fit's K̃_S, on the same table
    fixed = Fixed(fit.shear_tilde, options.bulk_mN_per_m, pr, options.table)
    t_lo, t_hi, k_lo, k_hi = shell_interval(fit, x, f, trace.volume_um3, fixed, options.errors)
    rows = depth_rows(x, f, radius, fit, fixed)
    verdict, why = depth_test(rows)
    try:
        cmp = fit_ramp(x, f, radius, "droplet", cap_um=fit.depth_um)
    except InputError:
        cmp = None
    g = fit.tension_mN_per_m
    row = {"part": "approach", "segment": index, "model": "shell", "tension_mN_per_m": g,
           "tension_lo95_mN_per_m": t_lo, "tension_hi95_mN_per_m": t_hi,
           "pressure_Pa": float(pressure_Pa(g, 1.0 / radius)), "pressure_lo95_Pa": float(pressure_Pa(t_lo, 1.0 / radius)),
           "pressure_hi95_Pa": float(pressure_Pa(t_hi, 1.0 / radius)),
           "bulk_modulus_mN_per_m": fit.bulk_mN_per_m, "bulk_modulus_lo95_mN_per_m": k_lo,
           "bulk_modulus_hi95_mN_per_m": k_hi, **_shear_columns(fit), "elastic_term": fit.elastic_term,
           "elastic_term_lr": fit.elastic_lr, "bimodal": fit.bimodal,
           "tension_bulk_correlation": fit.correlation, "baseline_slope_nN_per_um": fit.baseline_slope_nN_per_um,
           "baseline_slope_sd_nN_per_um": fit.baseline_slope_sd_nN_per_um,
           "droplet_tension_mN_per_m": rows[-1].droplet_tension_mN_per_m,
           "small_deformation_tension_mN_per_m": rows[-1].small_deformation_tension_mN_per_m,
           "depth_test": verdict, "depth_flag": why,
           "force_nN": float(fit.force_nN(fit.contact_um - fit.depth_um, radius)) - fit.baseline_nN,
           **_window(fit, radius), "compare_model": "droplet",
           "compare_tension_mN_per_m": cmp.tension_mN_per_m if cmp else float("nan"),
           "compare_contact_um": cmp.contact_um if cmp else float("nan"), "compare_r2": cmp.r2 if cmp else float("nan"),
           **prior_columns(*ramp_prior), **table_columns(options)}
    row["warning"] = _depth_warning(options.max_depth_um, fit, x, resolve(options.table).max_depth, radius)
    return row, ("approach", index, x, f, fit, cmp, rows)


def table_columns(options: Options) -> dict[str, str]:
    """The row's columns of the calibration parts it read (`TensionCalibration.columns`)."""
    return (options.calibration if options.calibration is not None else shipped_parts()).columns()


def _depth_warning(max_depth_um: float | None, fit: Any, x: np.ndarray, table_depth: float | None = None,
                   radius: float = float("nan")) -> str:
    """The warning when `--max-depth-um` exceeds the depth the ramp reaches below its contact (or
    the shell table's deepest δ/R `table_depth` times R), '' otherwise: the window ends there, not at the option."""
    if max_depth_um is None:
        return ""
    reached = float(fit.contact_um - np.min(x))
    if reached < max_depth_um:
        why = f"the ramp reaches {reached:.3g} um below its contact"
    elif table_depth is not None and table_depth * radius < max_depth_um:
        why = f"the shell table ends at {table_depth * radius:.3g} um (δ/R = {table_depth:.2g})"
    else:
        return ""
    return f"--max-depth-um {max_depth_um:g} exceeds the depth of the data: {why}; the window is {fit.depth_um:.3g} um deep"


def _shear_columns(fit: ShellFit) -> dict[str, Any]:
    """The row's K̃_S: given, or fitted with its 95 % interval and whether the ramp identifies
    it (`shell_shear`; no value where the droplet was returned: the force does not depend on it)."""
    if fit.shear_band is None:
        return {"shear_ratio": fit.shear_tilde, "shear_ratio_lo95": fit.shear_tilde,
                "shear_ratio_hi95": fit.shear_tilde, "shear_ratio_source": "given", "shear_ratio_identified": "given"}
    value = float("nan") if fit.elastic_term == NOT_SIGNIFICANT else fit.shear_tilde
    return {"shear_ratio": value, "shear_ratio_lo95": fit.shear_band[0], "shear_ratio_hi95": fit.shear_band[1],
            "shear_ratio_source": "fitted", "shear_ratio_identified": identification(fit)}


def _window(fit: Any, radius: float) -> dict[str, Any]:
    """The row's columns of a fit's window and contact."""
    return {"height_um": 2.0 * radius - fit.depth_um, "h_tilde": 1.0 - fit.depth_um / (2.0 * radius),
            "height_reference": "contact point", "contact_um": fit.contact_um, "baseline_nN": fit.baseline_nN,
            "depth_um": fit.depth_um, "window_lo_um": fit.window_lo_um, "window_hi_um": fit.window_hi_um,
            "window_samples": int(fit.window.sum()), "r2": fit.r2}


def _ramp_row(trace: Trace, index: int, x: np.ndarray, f: np.ndarray, options: Options, radius: float,
              ramp_prior: tuple[Prior | None, str] = (None, "")) -> tuple[dict[str, Any], tuple[Any, ...]]:
    """The row and plot of one approach ramp (the selected model, the other for comparison; the
    shell with `ramp_prior`)."""
    if options.model == "shell":
        return _shell_row(trace, index, x, f, options, radius, ramp_prior)
    fit = fit_ramp(x, f, radius, options.model, cap_um=options.max_depth_um)
    other = next(m for m in MODELS if m != options.model)
    try:
        cmp = fit_ramp(x, f, radius, other, cap_um=options.max_depth_um)
    except InputError:
        cmp = None
    t_lo, t_hi, p_lo, p_hi = ramp_interval(fit, x, f, trace.volume_um3, options.errors)
    row = {"part": "approach", "segment": index, "model": options.model, "tension_mN_per_m": fit.tension_mN_per_m,
           "tension_lo95_mN_per_m": t_lo, "tension_hi95_mN_per_m": t_hi,
           "pressure_Pa": float(pressure_Pa(fit.tension_mN_per_m, 1.0 / radius)),
           "pressure_lo95_Pa": p_lo, "pressure_hi95_Pa": p_hi,
           "droplet_tension_mN_per_m": _apparent(x, f, radius, "droplet", fit.depth_um),
           "small_deformation_tension_mN_per_m": _apparent(x, f, radius, "small-deformation", fit.depth_um),
           "force_nN": fit.tension_mN_per_m * float(force_per_tension_um(fit.model, fit.depth_um, radius)),
           **_window(fit, radius), "compare_model": other,
           "compare_tension_mN_per_m": cmp.tension_mN_per_m if cmp else float("nan"),
           "compare_contact_um": cmp.contact_um if cmp else float("nan"), "compare_r2": cmp.r2 if cmp else float("nan"),
           "warning": _depth_warning(options.max_depth_um, fit, x)}
    return row, ("approach", index, x, f, fit, cmp, None)


def _above_contact(x: np.ndarray, contact_um: float) -> np.ndarray:
    """The samples above the contact, where the cantilever's bending does not change (all of them
    if fewer than MIN_FREE): where a ramp's speed is read."""
    free = x > contact_um
    return free if free.sum() >= MIN_FREE else np.ones_like(free)


def _ramp_speed(t: np.ndarray, x: np.ndarray, contact_um: float, given: float | None) -> dict[str, Any]:
    """The row's approach speed (µm/s) and where it comes from: the recorded times (the slope of x
    over the samples above the contact, where the cantilever's bending does not change; all
    samples if fewer than MIN_FREE), else `--ramp-speed-um-per-s`, else unknown (NaN)."""
    if np.all(np.isfinite(t)) and t.size > 1:
        use = _above_contact(x, contact_um)
        return {"ramp_speed_um_per_s": float(abs(np.polyfit(t[use], x[use], 1)[0])), "ramp_speed_source": "recorded"}
    if given is not None:
        return {"ramp_speed_um_per_s": float(given), "ramp_speed_source": "--ramp-speed-um-per-s"}
    return {"ramp_speed_um_per_s": float("nan"), "ramp_speed_source": "unknown"}


def _pause_row(trace: Trace, index: int, t: np.ndarray, x: np.ndarray, f: np.ndarray,
               ramp: tuple[float, float] | None, options: Options, radius: float
               ) -> tuple[dict[str, Any], tuple[Any, ...]]:
    """The row and plot of one pause: the relaxed force F_∞ of its relaxation
    (`relaxation.fit_relaxation`; NaN tension where F_∞ ≤ 0, flagged) and, for
    comparison, its last half's mean; the height the last half's mean; `ramp`
    (contact x0, free baseline force) of the first fitted ramp, or None."""
    last = slice(len(f) // 2, None)
    contact, base = ramp if ramp else (float("nan"), 0.0)
    half = float(np.mean(f[last])) - base
    xm = float(np.mean(x[last]))
    if trace.dish_known or ramp is None:
        depth, height = None, xm
        ref = "dish" if trace.dish_known else "height channel (Z = 0, no dish reference)"
    else:
        depth, height, ref = contact - xm, 2.0 * radius - (contact - xm), "contact point"
        if depth >= 2.0 * radius:
            raise InputError(f"pause {depth:.4g} um below the approach's contact point, deeper than the free "
                             f"cell's diameter {2 * radius:.4g} um (is the volume right?)")
    p_half = pause_tension(half, height, trace.volume_um3, depth_um=depth, errors=options.errors)
    relax = fit_relaxation(t, f - base)
    force = relax.relaxed_force_nN
    p = pause_tension(force, height, trace.volume_um3, depth_um=depth, errors=options.errors,
                      force_sd_nN=relax.relaxed_force_sd_nN) if force > 0 else None
    keys = ("tension_mN_per_m", "tension_lo95_mN_per_m", "tension_hi95_mN_per_m", "pressure_Pa",
            "pressure_lo95_Pa", "pressure_hi95_Pa")
    row = {"part": "pause", "segment": index, "model": "droplet",
           **{k: getattr(p, k) if p else float("nan") for k in keys}, "force_nN": force, "height_um": height,
           "h_tilde": p_half.h_tilde, "height_reference": ref, "contact_um": contact, "baseline_nN": base,
           **relaxation_columns(relax), "last_half_force_nN": half,
           "last_half_tension_mN_per_m": p_half.tension_mN_per_m}
    return row, ("pause", index, t, f - base, half, relax, None)


def analyse(trace: Trace, options: Options) -> Analysed:
    """Every approach ramp and pause of `trace` before its first retract; InputError
    (the recording's reason) if one cannot be analysed or there is none."""
    radius = float(cell_radius(trace.volume_um3))
    done, ramp = Analysed(rows=[], radius_um=radius), None
    laws: Laws | str | None = None
    for k, (index, kind, t, f, x) in enumerate(trace.parts):
        if kind == "retract":
            break
        where = f"{kind} segment {index}"
        try:
            if kind == "approach":
                pr: tuple[Prior | None, str] = (None, "")
                if options.model == "shell":
                    pr, laws = _ramp_prior(trace, laws, t, x, f, options, radius)
                row, plot = _ramp_row(trace, index, x, f, options, radius, pr)
                row.update(_ramp_speed(t, x, plot[4].contact_um, options.ramp_speed_um_per_s))
                ramp = ramp or (plot[4].contact_um, baseline_noise(f)[0])
                row.update(_power_law(trace, k, options, radius, pr[0]))
            elif kind == "pause":
                row, plot = _pause_row(trace, index, t, x, f, ramp, options, radius)
            else:
                continue
        except InputError as err:
            raise InputError(f"{where}: {err}") from None
        row.update(headline(row))
        done.rows.append({"cell_id": trace.cell_id, **row, "volume_um3": trace.volume_um3, "radius_um": radius,
                          "volume_source": trace.volume_source, "source": trace.source})
        done.plots.append(plot)
    if not done.rows:
        raise InputError("no approach ramp or pause before the first retract")
    return done


def _power_law(trace: Trace, k: int, options: Options, radius: float, ramp_prior: Prior | None) -> dict[str, Any]:
    """The power-law shell's columns of the approach `trace.parts[k]` and the pause after it
    (`powerlaw_row`) with the calibration columns, where Options.power_law asks for them (module
    doc): {} with False, only the reason in `power_law_note` for a tension-only model by default or
    where the fit breaks down numerically (the elastic reading stays the row's)."""
    if options.power_law is False:
        return {}
    if options.power_law is None and options.model != "shell":
        return _power_law_missing(f"not read with --model {options.model} (--power-law reads it)")
    _, _, t, f, x = trace.parts[k]
    after = trace.parts[k + 1] if k + 1 < len(trace.parts) else None
    pause = (after[2], after[4], after[3]) if after is not None and after[1] == "pause" else None
    note = ""
    try:
        if not np.all(np.isfinite(t)) and options.ramp_speed_um_per_s is not None:
            t, pause, note = even_times(x, f, options.ramp_speed_um_per_s), None, TIMES_FROM_SPEED
        columns = power_law_columns((t, x, f), pause, radius, options.shear_tilde, ramp_prior, options.table,
                                    options.powerlaw_table)
    except InputError as err:
        return _power_law_missing(f"not read: {err}")
    except (ValueError, ArithmeticError, np.linalg.LinAlgError) as err:
        return _power_law_missing(f"not read: {type(err).__name__}: {err}")
    if note:
        columns["power_law_note"] = "; ".join(n for n in (note, columns["power_law_note"]) if n)
    return {**columns, **table_columns(options)}


def even_times(x: np.ndarray, f: np.ndarray, speed_um_per_s: float) -> np.ndarray:
    """Sample times (s) of a ramp whose file holds none, sampled evenly in time (a piezo ramp):
    t_i = i Δt, Δt = |dx/di| / v, dx/di the slope of x against the sample index above the
    contact (`contact_guess`, `_above_contact`), v `--ramp-speed-um-per-s`: the speed
    `_ramp_speed` would read from recorded times."""
    use = _above_contact(x, contact_guess(x, f)[0])
    index = np.arange(x.size, dtype=float)
    per_sample = abs(float(np.polyfit(index[use], x[use], 1)[0]))
    if not per_sample > 0:
        raise InputError("a ramp whose height does not move has no speed to time it by")
    return index * per_sample / speed_um_per_s


def _power_law_missing(why: str) -> dict[str, Any]:
    """The power-law columns of a ramp without that reading: NaN, and why in `power_law_note`."""
    return {**{c: float("nan") for c in POWER_LAW_COLUMNS}, "power_law_shear_ratio_source": "",
            "power_law_hold": "none", "power_law_model": "", "power_law_note": why}


def _analyse_all(traces: list[Trace], options: Options) -> tuple[dict[str, Analysed], dict[str, str]]:
    """({cell: analysed}, {cell: reason it could not be}) of `traces`, in order."""
    done, skipped = {}, {}
    for t in traces:
        try:
            done[t.cell_id] = analyse(t, options)
        except InputError as err:
            skipped[t.cell_id] = f"{t.source}: {err}"
    return done, skipped


def _analyse_beside(traces: list[Trace], options: Options) -> tuple[dict[str, Analysed], dict[str, str]]:
    """`_analyse_all`, the later half of the traces in a forked process beside this one
    (`common.beside`, where there are two CPUs): the same values, in the same order."""
    if len(traces) < 2:
        return _analyse_all(traces, options)
    half = (len(traces) + 1) // 2
    with beside(_analyse_all, traces[half:], options) as rest:
        done, skipped = _analyse_all(traces[:half], options)
        more, more_skipped = rest.result()
    return {**done, **more}, {**skipped, **more_skipped}


def run(paths: Sequence[str | Path], options: Options = Options(), out: str | Path | None = None) -> dict[str, Any]:
    """Analyse FILES; with `out` write the table, figures and report there. Returns
    {"rows", "skipped", "table", "report"} (paths None without `out`); InputError
    (exit 2, nothing written) when nothing could be analysed. The calibration parts are read
    first (`Options.calibration`, else the shipped ones)."""
    from outputs.ownership import OutputDir
    if options.calibration is None and (options.model == "shell" or options.power_law):
        options = replace(options, calibration=shipped_parts())
    traces, skipped = read(paths, options)
    folder = OutputDir(out) if out is not None else None        # refused now if not ours
    if folder is not None:
        folder.check([TABLE, REPORT] + list(file_names(t.cell_id for t in traces).values()))
    done, failed = _analyse_beside(traces, options)
    skipped.update(failed)
    if not done:
        more = f" (and {len(skipped) - 1} more not analysed)" if len(skipped) > 1 else ""
        raise InputError(next(iter(skipped.values()), "nothing to analyse") + more)
    rows = [r for a in done.values() for r in a.rows]
    table = report = None
    if folder is not None:
        table, report = write(folder, rows, done, skipped, options.model, options.errors)
    return {"rows": rows, "skipped": skipped, "table": table, "report": report}
