"""`cortex afm tension FILES`: read -> analyse -> write (docs/tension.md).

read     every FILE on its own: an experiment (.h5/.hdf5) or single-cell CSV
         (heights are gaps, volumes their own), else an instrument file or a
         folder of them through `formats.instruments.read_recordings`
         (heights x = z + F/k - Z, `formats.instruments.wedge_height_um`, with
         Z the dish reference when one is given), each recording with its
         volume (`--volume`, `--volumes` via `formats.instruments.read_volumes`,
         or `--radius-um` R: V = 4πR³/3);
analyse  per recording, in order until its first retract: every approach ramp
         fitted by the selected model: `shell` (`shell_fit`: γ_a and K_B of the
         elastic cortex, window capped at the shell table's depth and
         `--max-depth-um`; intervals `shell_fit.shell_interval`; the apparent
         tensions of the droplet and small-deformation readings on the same
         window beside it; each model against the window's depth, `depths`),
         or a tension-only one (`ramp`, with the other for comparison, each on
         its own automatic window; the interval from the volume error,
         `pause.ramp_interval`), every pause's tension and pressure
         (`pause.pause_tension`) from its force over its last half, above the
         first fitted ramp's free baseline (the median force of its first 30 %,
         `ramp.baseline_noise`: the deflection with nothing touching), at
         its height: the recorded gap where the dish is known (native files,
         `--dish-height-um`, `--dish-curve`), else h = 2R - (x0 - x) from that
         ramp's contact x0, else the height channel (Z = 0);
write    `--out DIR`: tension.csv (one row per analysed part), one figure per
         recording (`report`), report.md, which also lists what was not
         analysed.

A file or recording that cannot be read or analysed is set aside with its
reason; if nothing is left, the first reason is the InputError (exit status 2,
nothing written); otherwise the command ends with status 1.
"""

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from analysis.afm.tension.depths import depth_flag, depth_rows
from analysis.afm.tension.ramp import MODELS, baseline_noise, fit_ramp, force_per_tension_um
from analysis.afm.tension.shell_fit import Fixed, fit_shell, shell_interval
from analysis.afm.tension.pause import ErrorModel, pause_tension, pressure_Pa, ramp_interval
from analysis.afm.tension.report import REPORT, TABLE, Analysed, file_names, write
from common.errors import InputError
from common.names import RAMP_MODELS
from solver.geometry import cell_radius

NATIVE = (".h5", ".hdf5", ".csv")


@dataclass(frozen=True)
class Options:
    """What to analyse with: the ramp model (and for the shell: K̃_S, K_B if known,
    the deepest deformation), one of the volume sources, the dish reference, the errors."""

    model: str = "shell"
    shear_tilde: float = Fixed().shear_tilde
    bulk_mN_per_m: float | None = None
    max_depth_um: float | None = None
    volume_um3: float | None = None
    volumes_csv: str | None = None
    radius_um: float | None = None
    dish_um: float | None = None
    dish_curve: str | None = None
    spring_constant_N_per_m: float | None = None
    errors: ErrorModel = ErrorModel()


@dataclass
class Trace:
    """One recording ready for the analysis: its parts (segment index, kind, t (s),
    F (nN), x (µm)); `dish_known` when x is the gap itself."""

    cell_id: str
    source: str
    volume_um3: float
    volume_source: str
    parts: list
    dish_known: bool


def _volume(cell_id, options, table):
    """(V, how it was obtained) for one recording from the options."""
    if table is not None:
        if cell_id not in table:
            raise InputError(f"{options.volumes_csv}: no volume for cell '{cell_id}'")
        volume, how = table[cell_id][:2]
        return volume, how
    if options.volume_um3 is not None:
        return options.volume_um3, "one value for every cell (--volume)"
    if options.radius_um is not None:
        return 4.0 * np.pi * options.radius_um ** 3 / 3.0, f"free-cell radius {options.radius_um:g} um (--radius-um)"
    raise InputError(f"no volume for cell '{cell_id}': give --volume UM3, --volumes TABLE.csv or --radius-um R")


def _native(path, options):
    """Traces of an experiment or single-cell CSV (their own volumes and gaps)."""
    if any(v is not None for v in (options.volume_um3, options.volumes_csv, options.radius_um, options.dish_um,
                                   options.dish_curve, options.spring_constant_N_per_m)):
        raise InputError(f"{path}: --volume(s), --radius-um, --dish-* and --spring-constant apply to instrument "
                         "files only; the experiment and CSV formats carry their own volumes and heights")
    if path.suffix.lower() == ".csv":
        from analysis.afm.formats.csvcell import read_csv_cell
        cells = [read_csv_cell(path)]
    else:
        from analysis.afm.formats.h5 import read_experiment
        cells = read_experiment(path)
    return [Trace(c.cell_id, str(path), c.volume_um3, c.volume_source,
                  [(i, s.kind, c.time_s[s.start:s.stop], c.force_nN[s.start:s.stop], c.height_um[s.start:s.stop])
                   for i, s in enumerate(c.segments)], True) for c in cells]


def _instrument(path, options, table, dish):
    """Traces of instrument files (`formats.instruments.read_recordings`): x = z + F/k - Z."""
    from analysis.afm.formats.instruments import read_recordings, wedge_height_um
    out = []
    for r in read_recordings([path], options.spring_constant_N_per_m):
        volume, how = _volume(r.cell_id, options, table)
        parts = [(i, s.kind, s.time_s, s.force_nN, wedge_height_um(s, r.spring_constant_N_per_m) - (dish or 0.0))
                 for i, s in enumerate(r.segments) if s.n_samples]
        out.append(Trace(r.cell_id, r.source or str(path), volume, how, parts, dish is not None))
    return out


def read(paths: Sequence[str | Path], options: Options) -> tuple[list[Trace], dict[str, str]]:
    """(traces, {file or cell: reason}) of FILES; InputError for bad options. The
    instrument readers (and pandas) are imported only for what needs them."""
    if options.model not in RAMP_MODELS:
        raise InputError(f"--model {options.model!r}: not one of {', '.join(RAMP_MODELS)}")
    for name, value in (("--volume", options.volume_um3), ("--radius-um", options.radius_um),
                        ("--spring-constant", options.spring_constant_N_per_m), ("--shear-ratio", options.shear_tilde),
                        ("--bulk-mN-per-m", options.bulk_mN_per_m), ("--max-depth-um", options.max_depth_um)):
        if value is not None and not (np.isfinite(value) and value > 0):
            raise InputError(f"{name} must be a positive number (got {value})")
    table, dish = None, options.dish_um
    if options.volumes_csv is not None:
        from analysis.afm.formats.instruments import read_volumes
        table = read_volumes(options.volumes_csv)
    if options.dish_curve is not None:
        from analysis.afm.formats.instruments import dish_from_curve
        dish = dish_from_curve(options.dish_curve)
    traces, skipped = [], {}
    for p in map(Path, paths):
        try:
            traces += _native(p, options) if p.is_file() and p.suffix.lower() in NATIVE else \
                _instrument(p, options, table, dish)
        except InputError as err:
            skipped[str(p)] = str(err) if str(p) in str(err) else f"{p}: {err}"
    seen: dict[str, str] = {}
    for t in traces:
        if t.cell_id in seen:
            raise InputError(f"cell id '{t.cell_id}' twice ({seen[t.cell_id]} and {t.source})")
        seen[t.cell_id] = t.source
    return traces, skipped


def _apparent(x, f, radius, model, cap):
    """The apparent tension of a tension-only `model` on deformations up to `cap` (NaN if it fails)."""
    try:
        return fit_ramp(x, f, radius, model, cap_um=cap).tension_mN_per_m
    except InputError:
        return float("nan")


def _shell_row(trace, index, x, f, options, radius):
    """The row and plot of one approach ramp by the shell (the droplet for comparison, on the same window)."""
    fixed = Fixed(options.shear_tilde, options.bulk_mN_per_m)
    fit = fit_shell(x, f, radius, fixed, cap_um=options.max_depth_um)
    t_lo, t_hi, k_lo, k_hi = shell_interval(fit, x, f, trace.volume_um3, fixed, options.errors)
    rows = depth_rows(x, f, radius, fit, fixed)
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
           "bulk_modulus_hi95_mN_per_m": k_hi, "shear_ratio": fit.shear_tilde,
           "tension_bulk_correlation": fit.correlation,
           "droplet_tension_mN_per_m": rows[-1].droplet_tension_mN_per_m,
           "small_deformation_tension_mN_per_m": rows[-1].small_deformation_tension_mN_per_m,
           "depth_flag": depth_flag(rows),
           "force_nN": float(fit.force_nN(fit.contact_um - fit.depth_um, radius)) - fit.baseline_nN,
           **_window(fit, radius), "compare_model": "droplet",
           "compare_tension_mN_per_m": cmp.tension_mN_per_m if cmp else float("nan"),
           "compare_contact_um": cmp.contact_um if cmp else float("nan"), "compare_r2": cmp.r2 if cmp else float("nan")}
    return row, ("approach", index, x, f, fit, cmp, rows)


def _window(fit, radius):
    """The row's columns of a fit's window and contact."""
    return {"height_um": 2.0 * radius - fit.depth_um, "h_tilde": 1.0 - fit.depth_um / (2.0 * radius),
            "height_reference": "contact point", "contact_um": fit.contact_um, "baseline_nN": fit.baseline_nN,
            "depth_um": fit.depth_um, "window_lo_um": fit.window_lo_um, "window_hi_um": fit.window_hi_um,
            "window_samples": int(fit.window.sum()), "r2": fit.r2}


def _ramp_row(trace, index, x, f, options, radius):
    """The row and plot of one approach ramp (the selected model, the other for comparison)."""
    if options.model == "shell":
        return _shell_row(trace, index, x, f, options, radius)
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
           "compare_contact_um": cmp.contact_um if cmp else float("nan"), "compare_r2": cmp.r2 if cmp else float("nan")}
    return row, ("approach", index, x, f, fit, cmp, None)


def _pause_row(trace, index, t, x, f, ramp, options, radius):
    """The row and plot of one pause: its last half's mean force and height;
    `ramp` (contact x0, free baseline force) of the first fitted ramp, or None."""
    last = slice(len(f) // 2, None)
    contact, base = ramp if ramp else (float("nan"), 0.0)
    force = float(np.mean(f[last])) - base
    xm = float(np.mean(x[last]))
    if trace.dish_known or ramp is None:
        depth, height = None, xm
        ref = "dish" if trace.dish_known else "height channel (Z = 0, no dish reference)"
    else:
        depth, height, ref = contact - xm, 2.0 * radius - (contact - xm), "contact point"
        if depth >= 2.0 * radius:
            raise InputError(f"pause {depth:.4g} um below the approach's contact point, deeper than the free "
                             f"cell's diameter {2 * radius:.4g} um (is the volume right?)")
    p = pause_tension(force, height, trace.volume_um3, depth_um=depth, errors=options.errors)
    row = {"part": "pause", "segment": index, "model": "droplet", "tension_mN_per_m": p.tension_mN_per_m,
           "tension_lo95_mN_per_m": p.tension_lo95_mN_per_m, "tension_hi95_mN_per_m": p.tension_hi95_mN_per_m,
           "pressure_Pa": p.pressure_Pa, "pressure_lo95_Pa": p.pressure_lo95_Pa, "pressure_hi95_Pa": p.pressure_hi95_Pa,
           "force_nN": force, "height_um": height, "h_tilde": p.h_tilde, "height_reference": ref,
           "contact_um": contact, "baseline_nN": base}
    return row, ("pause", index, t, f - base, force, None, None)


def analyse(trace: Trace, options: Options) -> Analysed:
    """Every approach ramp and pause of `trace` before its first retract; InputError
    (the recording's reason) if one cannot be analysed or there is none."""
    radius = float(cell_radius(trace.volume_um3))
    done, ramp = Analysed(rows=[], radius_um=radius), None
    for index, kind, t, f, x in trace.parts:
        if kind == "retract":
            break
        where = f"{kind} segment {index}"
        try:
            if kind == "approach":
                row, plot = _ramp_row(trace, index, x, f, options, radius)
                ramp = ramp or (plot[4].contact_um, baseline_noise(f)[0])
            elif kind == "pause":
                row, plot = _pause_row(trace, index, t, x, f, ramp, options, radius)
            else:
                continue
        except InputError as err:
            raise InputError(f"{where}: {err}") from None
        done.rows.append({"cell_id": trace.cell_id, **row, "volume_um3": trace.volume_um3, "radius_um": radius,
                          "volume_source": trace.volume_source, "source": trace.source})
        done.plots.append(plot)
    if not done.rows:
        raise InputError("no approach ramp or pause before the first retract")
    return done


def run(paths: Sequence[str | Path], options: Options = Options(), out: str | Path | None = None) -> dict[str, Any]:
    """Analyse FILES; with `out` write the table, figures and report there. Returns
    {"rows", "skipped", "table", "report"} (paths None without `out`); InputError
    (exit 2, nothing written) when nothing could be analysed."""
    from outputs.ownership import OutputDir
    traces, skipped = read(paths, options)
    folder = OutputDir(out) if out is not None else None        # refused now if not ours
    if folder is not None:
        folder.check([TABLE, REPORT] + list(file_names(t.cell_id for t in traces).values()))
    done = {}
    for t in traces:
        try:
            done[t.cell_id] = analyse(t, options)
        except InputError as err:
            skipped[t.cell_id] = f"{t.source}: {err}"
    if not done:
        more = f" (and {len(skipped) - 1} more not analysed)" if len(skipped) > 1 else ""
        raise InputError(next(iter(skipped.values()), "nothing to analyse") + more)
    rows = [r for a in done.values() for r in a.rows]
    table = report = None
    if folder is not None:
        table, report = write(folder, rows, done, skipped, options.model, options.errors)
    return {"rows": rows, "skipped": skipped, "table": table, "report": report}
