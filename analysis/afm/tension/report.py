"""What `cortex afm tension --out DIR` writes: tension.csv (the rows, columns in
`COLUMNS`, units in their names), one figure per recording
(`tension_<cell_id>.png`: each approach ramp's force above its baseline against
the deformation x0 - x, the samples of the fit window marked, the fitted model
and the comparison model, the power-law shell's γ_a and β in its title where it
heads the row; for the shell model a panel of each model's tension against the
window's depth (`depths`); each pause's force over time with its fitted
relaxation, the relaxed force F_∞ and the mean of its last half) and report.md
(the table in short with each part's headline tension (`headline`), the window rule,
the power-law shell's readings, the elastic shell's, the tensions against depth with the
recordings whose active tension moves with it, each pause's relaxation and flag, what was
not analysed)."""

import re
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from analysis.invert.measurement_errors import MeasurementErrors
from analysis.afm.tension.depths import HOLDS, MOVES, NOT_TESTABLE
from analysis.afm.tension.priors import COLUMNS as PRIOR_COLUMNS
from analysis.afm.tension.powerlaw_row import COLUMNS as POWER_LAW_ROW_COLUMNS
from analysis.afm.tension.relaxation import COLUMNS as RELAXATION_COLUMNS
from analysis.afm.tension.relaxation import NONE

if TYPE_CHECKING:
    from outputs.ownership import OutputDir

TABLE, REPORT = "tension.csv", "report.md"
# the row's headline tension and the reading it is (`headline`); after "model" in tension.csv
HEADLINE = ("headline_tension_mN_per_m", "headline_tension_lo95_mN_per_m", "headline_tension_hi95_mN_per_m",
            "headline_reading")
POWER_LAW, ELASTIC = "power-law shell", "elastic shell (β = 0)"
COLUMNS = ("cell_id", "part", "segment", "model") + HEADLINE + ("tension_mN_per_m", "tension_lo95_mN_per_m",
           "tension_hi95_mN_per_m", "bulk_modulus_mN_per_m", "bulk_modulus_lo95_mN_per_m",
           "bulk_modulus_hi95_mN_per_m", "shear_ratio", "shear_ratio_lo95", "shear_ratio_hi95", "shear_ratio_source",
           "shear_ratio_identified", "elastic_term", "elastic_term_lr", "bimodal",
           "tension_bulk_correlation", "baseline_slope_nN_per_um", "baseline_slope_sd_nN_per_um", "droplet_tension_mN_per_m",
           "small_deformation_tension_mN_per_m", "depth_test", "depth_flag", "pressure_Pa", "pressure_lo95_Pa", "pressure_hi95_Pa", "force_nN",
           "height_um", "h_tilde", "height_reference", "contact_um", "baseline_nN", "depth_um", "window_lo_um",
           "window_hi_um", "window_samples", "r2", "compare_model", "compare_tension_mN_per_m",
           "compare_contact_um", "compare_r2", "volume_um3", "radius_um", "volume_source", "source", "ramp_speed_um_per_s", "ramp_speed_source",
           "warning", "shell_table_source", "shell_table_sha256", "prior_calibration_source",
           "powerlaw_table_source", "powerlaw_table_sha256") + PRIOR_COLUMNS          # the shell's priors from the recording's oscillations (`priors`)


def headline(row: dict[str, Any]) -> dict[str, Any]:
    """The row's headline tension (HEADLINE) and the reading it is: an approach's power-law γ_a with
    its interval where the power-law shell read it (POWER_LAW), else the row's model's tension
    (ELASTIC for the shell: the β = 0 reading; `power_law_note` says why); a pause's relaxed one."""
    if row["part"] == "approach" and np.isfinite(row.get("power_law_tension_mN_per_m", float("nan"))):
        keys, reading = ("power_law_tension_mN_per_m", "power_law_tension_lo95_mN_per_m",
                         "power_law_tension_hi95_mN_per_m"), POWER_LAW
    else:
        keys = ("tension_mN_per_m", "tension_lo95_mN_per_m", "tension_hi95_mN_per_m")
        reading = (ELASTIC if row["model"] == "shell" else row["model"]) if row["part"] == "approach" else \
            "pause relaxed force"
    return {**{h: row[k] for h, k in zip(HEADLINE, keys)}, HEADLINE[-1]: reading}


# a pause's relaxation (`relaxation`) and, for comparison, its last half's reading; after COLUMNS in tension.csv
PAUSE_COLUMNS = RELAXATION_COLUMNS + ("last_half_force_nN", "last_half_tension_mN_per_m")
# the power-law shell's reading of a ramp and its hold (by default, `powerlaw_row`); last in tension.csv
POWER_LAW_COLUMNS = POWER_LAW_ROW_COLUMNS


@dataclass
class Analysed:
    """The rows of one recording and what its figure shows: per part (kind, x or t,
    F, fit, comparison fit) and the cell's radius."""

    rows: list
    plots: list = field(default_factory=list)
    radius_um: float = float("nan")


def file_names(cell_ids: Iterable[str]) -> dict[str, str]:
    """{cell_id: its figure's file name}: tension_<cell_id>.png with characters outside
    [A-Za-z0-9._-] as '_', and -2, -3, ... after a name already taken."""
    names: dict[str, str] = {}
    taken: set[str] = set()
    for cell_id in cell_ids:
        stem, n = f"tension_{re.sub(r'[^A-Za-z0-9._-]', '_', cell_id)}", 1
        while (name := stem + (f"-{n}" if n > 1 else "") + ".png") in taken:
            n += 1
        names[cell_id] = name
        taken.add(name)
    return names


def _ramp_axes(ax: Any, plot: tuple[Any, ...], radius: float, row: dict[str, Any]) -> None:
    """The ramp, its window, the model's fit and the comparison; the row's headline in the title
    where it is the power-law shell's (whose curve this panel does not draw)."""
    _, index, x, f, fit, cmp, _ = plot
    depth = fit.contact_um - x
    base = fit.baseline_at(x)
    ax.plot(depth, f - base, ".", ms=2, color="0.7", label="data")
    ax.plot(depth[fit.window], (f - base)[fit.window], ".", ms=2, color="tab:blue", label="fit window")
    d = np.linspace(-fit.depth_um, fit.depth_um, 300)
    what = (f"γ_a = {fit.tension_mN_per_m:.3g}, K_B = {fit.bulk_mN_per_m:.3g} mN/m" if fit.model == "shell"
            else f"T = {fit.tension_mN_per_m:.3g} mN/m")
    ax.plot(d, fit.force_nN(fit.contact_um - d, radius) - fit.baseline_at(fit.contact_um - d), color="tab:red",
            label=f"{ELASTIC if fit.model == 'shell' else fit.model}: {what}, R² = {fit.r2:.4f}")
    if cmp is not None:
        ax.plot(d, cmp.force_nN(fit.contact_um - d, radius) - cmp.baseline_at(fit.contact_um - d), "--",
                color="tab:green",
                label=f"{cmp.model}: T = {cmp.tension_mN_per_m:.3g} mN/m, R² = {cmp.r2:.4f}")
    for edge in (-fit.depth_um, fit.depth_um):
        ax.axvline(edge, color="0.4", lw=0.8, ls=":")
    ax.set_xlim(-1.5 * fit.depth_um, 1.2 * max(fit.depth_um, np.max(depth)) if depth.size else 1.0)
    ax.set_xlabel("deformation x0 - x (um)")
    ax.set_ylabel("force above baseline (nN)")
    if row.get("headline_reading") == POWER_LAW:
        ax.set_title(f"approach (segment {index})\npower-law shell: γ_a = "
                     f"{_num(row, 'headline_tension_mN_per_m', '.3g')} [{_num(row, 'headline_tension_lo95_mN_per_m', '.3g')}, "
                     f"{_num(row, 'headline_tension_hi95_mN_per_m', '.3g')}] mN/m, "
                     f"β = {_num(row, 'power_law_exponent', '.2g')}", fontsize=9)
    else:
        ax.set_title(f"approach (segment {index})")
    ax.legend(fontsize=7, loc="upper left")


def _depth_axes(ax: Any, plot: tuple[Any, ...]) -> None:
    """Each model's tension against the window's depth (the shell's with its 95 % bar)."""
    _, index, _, _, fit, _, rows = plot
    d = np.array([r.depth_um for r in rows])
    g = np.array([r.tension_mN_per_m for r in rows])
    ax.errorbar(d, g, yerr=1.96 * np.array([r.tension_sd_mN_per_m for r in rows]), fmt="o-", color="tab:red",
                label=f"{ELASTIC}: γ_a")
    ax.plot(d, [r.droplet_tension_mN_per_m for r in rows], "s--", color="tab:green", label="droplet (apparent)")
    ax.plot(d, [r.small_deformation_tension_mN_per_m for r in rows], "^:", color="tab:purple",
            label="small-deformation (apparent)")
    ax.set_xlabel("window depth (um)")
    ax.set_ylabel("tension (mN/m)")
    ax.set_ylim(bottom=0)
    ax.set_title(f"tension against depth (segment {index})")
    ax.legend(fontsize=7, loc="upper left")


def _pause_axes(ax: Any, plot: tuple[Any, ...]) -> None:
    _, index, t, f, half, relax, _ = plot
    ax.plot(t, f, ".", ms=2, color="tab:blue")
    if relax.model != NONE:
        ax.plot(t, relax.force_nN(t - t[0]), color="tab:green", label=f"{relax.model}: {relax.time_s:.3g} s")
    ax.axhline(relax.relaxed_force_nN, color="tab:green", ls="--",
               label=f"relaxed F_inf: {relax.relaxed_force_nN:.3g} nN" + (" (flagged)" if relax.flag else ""))
    ax.axhline(half, color="tab:red", label=f"last half: {half:.3g} nN")
    ax.axvspan(t[len(t) // 2], t[-1], color="tab:red", alpha=0.08)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("force above baseline (nN)")
    ax.set_title(f"pause (segment {index})")
    ax.legend(fontsize=7, loc="best")


def figure(path: Path, cell_id: str, analysed: Analysed) -> None:
    """One recording's figure: a panel per analysed part."""
    from matplotlib.figure import Figure      # no pyplot: no figure manager to make and close
    panels = [(p, "part") for p in analysed.plots] + [(p, "depth") for p in analysed.plots if p[6] is not None]
    n = len(panels)
    fig = Figure(figsize=(4.6 * n, 3.6))
    axes = fig.subplots(1, n, squeeze=False)
    for ax, (plot, what) in zip(axes[0], panels):
        if what == "depth":
            _depth_axes(ax, plot)
        elif plot[0] == "approach":
            row: dict[str, Any] = next((r for r in analysed.rows
                                        if r["part"] == "approach" and r["segment"] == plot[1]), {})
            _ramp_axes(ax, plot, analysed.radius_um, row)
        else:
            _pause_axes(ax, plot)
    fig.suptitle(cell_id, fontsize=9)
    fig.subplots_adjust(left=0.14 / n ** 0.8, right=0.98, bottom=0.15, top=0.84, wspace=0.3)
    fig.savefig(path, dpi=80)


def _num(row: dict[str, Any], key: str, spec: str) -> str:
    """row[key] formatted, '—' where it is missing or NaN."""
    value = row.get(key, float("nan"))
    return "—" if value != value else format(value, spec)


def _shell_lines(rows: list[dict[str, Any]]) -> list[str]:
    """report.md's shell readings: γ_a, K_B and K_S/K_B with their 95 % intervals, what one ramp identifies."""
    ramps = [r for r in rows if r["part"] == "approach" and r["model"] == "shell"]
    if not ramps:
        return []
    lines = ["", "## Approach ramps: the elastic shell (the β = 0 reading)", "",
             "K_S/K_B given, or fitted over the ramp table's range by its profile likelihood: identified (its 95 % "
             "interval inside the range), bounded (one end inside) or not identified; where fitted, the intervals "
             "of γ_a and K_B hold every K_S/K_B of its interval. Priors: the Gaussian priors on K_B and K_S/K_B "
             "at the ramp's time scale T from the recording's own oscillations, or why none (see "
             f"docs/tension.md). Shell ramp table: {_table_used(ramps)}. Power-law table: "
             f"{_table_used(ramps, 'powerlaw_table')}.", "",
             "| cell | part | γ_a (mN/m) | 95 % | K_B (mN/m) | 95 % | K_S/K_B | 95 % | K_S/K_B is | elastic term (Λ) "
             "| priors |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in ramps:
        lines.append(f"| {r['cell_id']} | approach {r['segment']} | {_num(r, 'tension_mN_per_m', '.4g')} | "
                     f"[{_num(r, 'tension_lo95_mN_per_m', '.3g')}, {_num(r, 'tension_hi95_mN_per_m', '.3g')}] | "
                     f"{_num(r, 'bulk_modulus_mN_per_m', '.4g')} | [{_num(r, 'bulk_modulus_lo95_mN_per_m', '.3g')}, "
                     f"{_num(r, 'bulk_modulus_hi95_mN_per_m', '.3g')}] | {_num(r, 'shear_ratio', '.3g')} | "
                     f"[{_num(r, 'shear_ratio_lo95', '.3g')}, {_num(r, 'shear_ratio_hi95', '.3g')}] | "
                     f"{r['shear_ratio_identified']} | {r['elastic_term']} ({_num(r, 'elastic_term_lr', '.3g')}) | "
                     f"{_prior_cell(r)} |")
    return lines


def _power_law_lines(rows: list[dict[str, Any]]) -> list[str]:
    """report.md's power-law shell readings (`powerlaw_row`): γ_a with its interval, K_B(1 s) and β
    with their SDs, K_S/K_B and where it comes from, the hold, or why there is no reading."""
    ramps = [r for r in rows if r["part"] == "approach" and "power_law_hold" in r]
    if not ramps:
        return []
    lines = ["", "## Approach ramps: the power-law shell", "",
             "The approach at its recorded speed and the pause right after it (held at constant height or "
             "force, or none) read as one curve of the shell whose cortex relaxes as K(t) = K(1 s) t^-β (see "
             "docs/tension-power-law.md); the elastic shell below is its β = 0 case.", "",
             "| cell | part | γ_a (mN/m) | 95 % | K_B(1 s) (mN/m) | β | K_S/K_B | 95 % | K_S/K_B is | hold | note |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in ramps:
        lines.append(f"| {r['cell_id']} | approach {r['segment']} | {_num(r, 'power_law_tension_mN_per_m', '.4g')} | "
                     f"[{_num(r, 'power_law_tension_lo95_mN_per_m', '.3g')}, "
                     f"{_num(r, 'power_law_tension_hi95_mN_per_m', '.3g')}] | "
                     f"{_num(r, 'power_law_bulk_1s_mN_per_m', '.4g')} ± {_num(r, 'power_law_bulk_1s_sd_mN_per_m', '.2g')} | "
                     f"{_num(r, 'power_law_exponent', '.3g')} ± {_num(r, 'power_law_exponent_sd', '.2g')} | "
                     f"{_num(r, 'power_law_shear_ratio', '.3g')} | [{_num(r, 'power_law_shear_ratio_lo95', '.3g')}, "
                     f"{_num(r, 'power_law_shear_ratio_hi95', '.3g')}] | {r.get('power_law_shear_ratio_source', '')} | "
                     f"{r.get('power_law_hold', '')} | {r.get('power_law_note', '')} |")
    return lines


def _table_used(ramps: list[dict[str, Any]], part: str = "shell_table") -> str:
    """Which table the ramps read (`part`: shell_table, powerlaw_table): its source (a file, or
    shipped) and SHA-256."""
    used = sorted({(r.get(f"{part}_source", ""), r.get(f"{part}_sha256", "")) for r in ramps})
    return "; ".join(f"{src} (SHA-256 {sha}...)" for src, sha in used)


def _prior_cell(r: dict[str, Any]) -> str:
    """The shell table's priors: K_B ± sd and K_S/K_B ×/÷ e^sd at T, or none and why."""
    if r.get("prior_source") != "oscillations":
        return f"none ({r.get('prior_note', '')})"
    return (f"oscillations: K_B {_num(r, 'prior_bulk_modulus_mN_per_m', '.3g')} ± "
            f"{_num(r, 'prior_bulk_modulus_sd_mN_per_m', '.2g')} mN/m, K_S/K_B {_num(r, 'prior_shear_ratio', '.3g')} "
            f"×/÷ e^{_num(r, 'prior_shear_ratio_log_sd', '.2g')}, T {_num(r, 'prior_time_scale_s', '.3g')} s")


def _pause_lines(rows: list[dict[str, Any]]) -> list[str]:
    """report.md's pauses: the relaxation preferred, the relaxed and last-half readings, the flags."""
    pauses = [r for r in rows if r["part"] == "pause"]
    if not pauses:
        return []
    lines = ["", "## Pauses: the relaxed force", "",
             "γ above is read from the relaxed force F_inf of the relaxation the data prefer (exponential, power "
             "law or none, by BIC); the last half's mean force and its γ for comparison. A flagged pause cannot "
             "give F_inf (see docs/tension.md).", "",
             "| cell | part | pause (s) | relaxation | time (s) | F_inf (nN) | 95 % | last half (nN) | "
             "γ relaxed (mN/m) | γ last half (mN/m) |", "|---|---|---|---|---|---|---|---|---|---|"]
    for r in pauses:
        lines.append(f"| {r['cell_id']} | pause {r['segment']} | {_num(r, 'pause_duration_s', '.3g')} | "
                     f"{r['relaxation_model']} | {_num(r, 'relaxation_time_s', '.3g')} | "
                     f"{_num(r, 'relaxed_force_nN', '.4g')} | [{_num(r, 'relaxed_force_lo95_nN', '.4g')}, "
                     f"{_num(r, 'relaxed_force_hi95_nN', '.4g')}] | {_num(r, 'last_half_force_nN', '.4g')} | "
                     f"{_num(r, 'tension_mN_per_m', '.4g')} | {_num(r, 'last_half_tension_mN_per_m', '.4g')} |")
    flagged = [r for r in pauses if r["relaxation_flag"]]
    if flagged:
        lines += ["", "Flagged pauses:", ""] + [f"- {r['cell_id']} pause {r['segment']}: {r['relaxation_flag']}"
                                                for r in flagged]
    return lines


def depth_lines(done: dict[str, Analysed]) -> list[str]:
    """report.md's section of each shell-fitted ramp's tensions against the window's depth."""
    lines: list[str] = []
    for cell_id, analysed in done.items():
        for plot in analysed.plots:
            if plot[0] != "approach" or plot[6] is None:
                continue
            lines += ["", f"### {cell_id}, approach {plot[1]}: tension (mN/m) against the window's depth", "",
                      "| depth (um) | shell γ_a | 95 % | K_B (mN/m) | droplet T | small-deformation T |",
                      "|---|---|---|---|---|---|"]
            for r in plot[6]:
                h = 1.96 * r.tension_sd_mN_per_m
                lines.append(f"| {r.depth_um:.3g} | {r.tension_mN_per_m:.4g} | ±{h:.2g} | {r.bulk_mN_per_m:.4g} | "
                             f"{r.droplet_tension_mN_per_m:.4g} | {r.small_deformation_tension_mN_per_m:.4g} |")
            row: dict[str, Any] = next((r for r in analysed.rows
                                        if r["part"] == "approach" and r["segment"] == plot[1]), {})
            verdict, why = row.get("depth_test", HOLDS), row.get("depth_flag", "")
            lines += ["", f"**Flagged**: {why}." if verdict == MOVES else f"Across the windows: {why}."
                      if verdict == NOT_TESTABLE else "The active tension holds across the windows."]
    return (["", "## Tension against the window's depth"] + lines) if lines else []


def markdown(rows: list[dict[str, Any]], skipped: dict[str, str], model: str, errors: MeasurementErrors,
             figures: list[Path], done: dict[str, Analysed] | None = None) -> str:
    """report.md: the parts analysed, the rule of the window, what was left out."""
    lines = ["# Cortical tension", "",
             "The tension of each part is its headline reading: an approach ramp's active tension γ_a by the "
             "shell whose cortex relaxes as a power law (the ramp and the pause after it as one curve) where it "
             "was read, else the ramp model's; a pause's from its relaxed force. "
             f"Ramp model: **{model}** (shell: γ_a and the bulk modulus K_B of the elastic cortex, the β = 0 "
             "reading, with the droplet's apparent tension for comparison; droplet or small-deformation: the "
             "other for comparison). Volume errors: relative SD "
             f"{errors.volume_rel_sd:g}; height error SD {errors.height_sd_um:g} um; 95 % intervals. "
             "Fit window: deformations up to the deepest one reached (at most R), and as much baseline above "
             "the contact; see docs/tension.md.", "",
             "| cell | part | tension (mN/m) | 95 % | reading | model's T or γ (mN/m) | 95 % | ΔP (Pa) | h (um) | "
             "h̃ | contact (um) | R² | comparison T (mN/m) |", "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['cell_id']} | {r['part']} {r['segment']} | {_num(r, 'headline_tension_mN_per_m', '.4g')} | "
                     f"[{_num(r, 'headline_tension_lo95_mN_per_m', '.3g')}, "
                     f"{_num(r, 'headline_tension_hi95_mN_per_m', '.3g')}] | {r.get('headline_reading', '')} | "
                     f"{_num(r, 'tension_mN_per_m', '.4g')} | "
                     f"[{_num(r, 'tension_lo95_mN_per_m', '.3g')}, {_num(r, 'tension_hi95_mN_per_m', '.3g')}] | "
                     f"{_num(r, 'pressure_Pa', '.4g')} | {_num(r, 'height_um', '.4g')} | {_num(r, 'h_tilde', '.3f')} | "
                     f"{_num(r, 'contact_um', '.5g')} | {_num(r, 'r2', '.4f')} | "
                     f"{_num(r, 'compare_tension_mN_per_m', '.4g')} |")
    lines += _power_law_lines(rows)
    lines += _shell_lines(rows)
    lines += _pause_lines(rows)
    lines += depth_lines(done or {})
    warned = [r for r in rows if r.get("warning")]
    if warned:
        lines += ["", "## Warnings", ""] + [f"- {r['cell_id']} {r['part']} {r['segment']}: {r['warning']}"
                                             for r in warned]
    lines += ["", "Figures: " + ", ".join(f"[{p.name}]({p.name})" for p in figures), ""]
    if skipped:
        lines += ["## Not analysed", ""] + [f"- {k}: {v}" for k, v in skipped.items()] + [""]
    return "\n".join(lines)


def write(folder: "OutputDir", rows: list[dict[str, Any]], done: dict[str, Analysed], skipped: dict[str, str],
          model: str, errors: MeasurementErrors) -> tuple[Path, Path]:
    """tension.csv, the figures and report.md into the `OutputDir` folder; (table, report) paths."""
    with folder.writing(TABLE) as table:
        power_law = POWER_LAW_COLUMNS if any("power_law_hold" in r for r in rows) else ()
        pd.DataFrame(rows, columns=list(COLUMNS + PAUSE_COLUMNS + power_law)).to_csv(table, index=False)
    figures, names = [], file_names(done)
    for cell_id, analysed in done.items():
        with folder.writing(names[cell_id]) as path:
            figure(path, cell_id, analysed)
        figures.append(path)
    text = markdown(rows, skipped, model, errors, figures, done)
    with folder.writing(REPORT) as report:
        report.write_text(text)
    return table, report
