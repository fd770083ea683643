"""`cortex afm analyze DATA --out DIR`: read -> fit -> write.

    read(data, calibration, settings)        the recordings (`formats.open`) and the
                                             inversion (`analysis.invert.method`) the
                                             calibration file (read once) serves;
                                             recordings without any oscillation
                                             segment are set aside (`skipped`);
    fit(recordings, settings)                every cell's curves, once
                                             (`analysis.afm.analyze.measure`), inverted
                                             with every bending variant (`Inversion.invert`),
                                             each variant's cells table and population
                                             summary (`analysis.afm.analyze`); the
                                             variants other than the selected one in a
                                             forked process beside this one (`common.beside`,
                                             one process where fork or a second CPU is
                                             missing), the same numbers;
    write(out, recordings, fitted, settings) the files below, figures and report.md
                                             (`analysis.afm.analyze_report`), read
                                             from the tables.

DIR gets cells.csv, segments.csv, summary.json (the selected variant),
population.json (the selected variant's population answer: per frequency the
random-effects fit, the paired tests, the trend; `analysis.afm.population.answer`),
cells_<variant>.csv and summary_<variant>.json for every variant, figures and
report.md, which also lists the recordings not analysed and, on stderr too, the cells that do
not look like plate confinement (`analysis.afm.confinement`). summary.json's
`tension_tolerance` is the tension filter's (`Settings.tension_tolerance`; null: lifted, inf);
its `calibration_parts`, and report.md's Calibration section, say where each part of the
calibration bundle came from (`CalibrationFile.sources`: a path or "shipped"). `Settings()`
is the command's defaults; the command only parses.

Recordings: one experiment (.h5/.hdf5), one single-cell CSV, or JPK or Bruker
NanoScope files and folders of them (`analysis.afm.formats.reader.open`, with the volume and dish
options of `cortex afm import`, `Settings.import_options`).

With the emulator (the default method where the calibration has one) every cell and frequency has a 95 %
interval of ν and K̃_S (`nu_lo95`, `nu_hi95`, `ks_lo95`, `ks_hi95` in cells.csv),
and every frequency's median ν a bootstrap 95 % interval (`median_nu_lo95`,
`median_nu_hi95` in the summaries); figure `nu_intervals.png`.

With `Settings.phase` (the command's default; `--no-phase` turns it off) the selected
variant's cells table also gets the viscoelastic columns per cell and frequency,
DIR/rheology.csv the power laws per cell, summary.json `viscoelastic` (the instrument
phase and the paired test), report.md a section (`analysis.afm.rheology`). With it and a
protocol-aware reading the segments are first corrected for the stress each cell keeps from its
earlier height steps (`analysis.afm.protocol_reading`), every variant reads the corrected segments,
segments.csv gains the correction's columns, summary.json `protocol` and report.md a section naming
the cells not corrected or not settled, and why. Its replays are kept in DIR/replays as they finish
(`analysis.afm.replay_store`): the same command run again into DIR reads them back, so a stopped
reading goes on where it stopped (summary.json's `protocol.replays_read_back`).

The reading follows the data's provenance (`analysis.afm.provenance`, `Settings.as_made`, the
default): a relaxed synthetic experiment (frequency-domain `afm synth`) in the relaxed state, exactly
as `Settings(as_made=False, wait_s=inf)`; a time-domain synthetic, a measured or an unknown one
protocol-aware with each recording's own waits. `as_made` False takes `Settings.wait_s` as given
(None: each recording's own waits; inf: the relaxed state). summary.json's `reading` and
`provenance`, and report.md, say which reading was used and why."""

from __future__ import annotations

import json
import math
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Sequence

import pandas as pd

from analysis.afm.analyze import TENSION_TOLERANCE, Measured, check_tolerance, inverted, measure, summarise
from analysis.afm.formats.reader import ImportOptions
from analysis.afm.formats.reader import open as open_cells
from analysis.afm.population.figures import FIGURES
from analysis.afm.protocol_factors import with_memory
from analysis.afm.fixed_point_span import widened
from analysis.afm.memory_span import spanned
from analysis.afm.protocol_reading import corrected, is_on
from analysis.afm.replay_store import NAME as REPLAYS, ReplayStore
from analysis.afm.confinement import warnings as confinement_warnings
from analysis.afm.protocol_reading import markdown as protocol_markdown
from analysis.afm.protocol_reading import summary as protocol_summary
from analysis.afm.provenance import Provenance, Reading, of_data, reading
from analysis.afm.provenance import markdown as made_markdown
from analysis.invert.method import Inversion, choose
from outputs.ownership import OutputDir
from common.beside import beside
from common.pool import usable_cores
from common.errors import InputError

if TYPE_CHECKING:
    from analysis.afm.cell import Cell
    from analysis.calibration.file import CalibrationFile
    from analysis.invert.measurement_errors import MeasurementErrors


NO_OSCILLATION = "no modulation (oscillation) segment"


@dataclass(frozen=True)
class Settings:
    """How to analyse: the selected bending variant, the inversion method,
    the error model of the emulator's intervals, how to read instrument files, the tension
    filter's tolerance (`analysis.afm.analyze`: published 0.1; inf lifts it; InputError if
    negative or NaN)."""

    bending: str = "standard"
    method: str | None = None    # None: the calibration's own (`CalibrationFile.default_method`)
    errors: MeasurementErrors | None = None
    import_options: ImportOptions = ImportOptions()
    phase: bool = True           # the viscoelastic reading (`analysis.afm.rheology`)
    lags: dict[float, float] | None = None     # instrument phase lag (rad) per frequency (Hz)
    lag_source: str | None = None
    tension_tolerance: float = TENSION_TOLERANCE
    as_made: bool = True          # read each experiment as its provenance says (`analysis.afm.provenance`)
    wait_s: float | None = None   # with as_made False: T_w (s), None each recording's own, inf the relaxed state
    jobs: int | None = None       # processes for the protocol-aware reading's replays (None: usable CPUs)
    memory_s: float | None = None  # the protocol-aware reading's τ_c (s): None from the data, inf the pure power law

    def __post_init__(self) -> None:
        check_tolerance(self.tension_tolerance)
        if self.as_made and self.wait_s is not None:
            raise InputError(f"a wait of {self.wait_s:g} s is given: it goes with as_made=False")
        if self.wait_s is not None and not self.wait_s >= 0:
            raise InputError(f"the wait must be a number of seconds >= 0, or inf (got {self.wait_s:g})")
        if self.memory_s is not None and not self.memory_s >= 0:
            raise InputError(f"the memory must be a number of seconds >= 0, or inf (got {self.memory_s:g})")
        if self.jobs is not None and self.jobs < 1:
            raise InputError(f"jobs must be >= 1 (got {self.jobs})")


@dataclass
class Recordings:
    """What `read` found: the cells to analyse, the skipped ones {id: reason},
    the data's name, the inversion, the calibration file (read once: its parts serve the
    inversion and the viscoelastic reading), and the variants to run (the selected one first)."""

    name: str
    cells: list[Cell]
    skipped: dict[str, str]
    inversion: Inversion
    method: str
    calibration: CalibrationFile
    variants: list[str]
    provenance: Provenance
    reading: Reading

    def protocol_aware(self, settings: Settings) -> bool:
        """Whether the viscoelastic reading corrects for the protocol (`analysis.afm.protocol_reading`)."""
        return settings.phase and is_on(self.reading.wait_s)


@dataclass
class Fitted:
    """Per variant: the cells table and the summary; the segments table."""

    tables: dict[str, pd.DataFrame] = field(default_factory=dict)
    sums: dict[str, dict[str, Any]] = field(default_factory=dict)
    segments: pd.DataFrame | None = None
    population: dict[str, Any] | None = None          # population.json (`analysis.afm.population.answer`)
    rheology: pd.DataFrame | None = None      # the viscoelastic reading's table, when on
    replays_read_back: int = 0                # replays read back from DIR/replays, kept there by a reading before


def _inversion(file: CalibrationFile, method: str, bending: str) -> Inversion:
    """The `method` inversion of the calibration file (`analysis.invert.method.choose`) with the
    bending variant `bending`; InputError if the file cannot serve them."""
    inversion = choose(method, file.calibration, file.emulator, file.where)
    variants = inversion.variants()
    if bending not in variants:
        raise InputError(f"{file.where}: no bending variant '{bending}' (has {', '.join(variants)})")
    return inversion


def read(data: str | Path | Sequence[str | Path], calibration: CalibrationFile,
         settings: Settings) -> Recordings:
    """`Recordings` of `data` (a path or a list of paths) with the inversion the
    calibration file (`analysis.calibration.file.load_calibration`) serves. InputError for bad input."""
    cells = open_cells(data, settings.import_options)
    provenance = of_data([data] if isinstance(data, (str, Path)) else data)
    method = settings.method or calibration.default_method
    inversion = _inversion(calibration, method, settings.bending)
    if settings.phase:
        calibration.require(("emulator", "viscoelastic_table"), "the viscoelastic reading (--no-phase: off)")
    skipped = {c.cell_id: NO_OSCILLATION for c in cells if not c.oscillations()}
    name = Path(data).name if isinstance(data, (str, Path)) else ", ".join(Path(d).name for d in data)
    variants = [settings.bending] + [v for v in inversion.variants() if v != settings.bending]
    return Recordings(name=name, cells=[c for c in cells if c.oscillations()], skipped=skipped,
                      inversion=inversion, method=method, calibration=calibration, variants=variants, provenance=provenance,
                      reading=reading(provenance, settings.wait_s, settings.as_made, settings.phase))



def _variants(measured: Measured, inversion: Inversion, variants: list[str], errors: MeasurementErrors | None,
              tension_tolerance: float) -> list[tuple[pd.DataFrame, dict[str, Any]]]:
    """Per variant of `variants`: its cells table and summary."""
    tables = [inverted(measured, inversion, v, errors, tension_tolerance) for v in variants]
    return [(t, summarise(t)) for t in tables]


def fit(rec: Recordings, settings: Settings, store: ReplayStore | None = None) -> Fitted:
    """Every cell of `rec` with every variant: a `Fitted`. The other variants are inverted in
    a process beside this one (`common.beside`: forked, where two CPUs serve) while this one
    inverts the selected variant and reads its population and viscoelastic behaviour: the
    numbers, and the first error, of one step after the other. The protocol-aware reading's
    replays are read back from `store` where a stopped reading left them, and kept there."""
    if settings.memory_s is not None and not rec.protocol_aware(settings):
        raise InputError(f"a memory is the protocol-aware reading's, and {rec.name} is read {rec.reading.label()} "
                         "(--wait-s recorded reads it protocol-aware)")
    measured, ends, widenings = measure(rec.cells), list[Measured](), dict[str, dict[str, float]]()
    if rec.protocol_aware(settings):
        measured, ends, widenings = corrected(
            measured, rec.cells, rec.inversion, rec.calibration.viscoelastic, settings.bending, settings.errors,
            rec.reading.wait_s, settings.lags, usable_cores() if settings.jobs is None else settings.jobs,
            memory_s=settings.memory_s, store=store)
    fitted = Fitted(segments=measured.segments, replays_read_back=store.read_back if store is not None else 0)
    selected, others = rec.variants[0], rec.variants[1:]
    tolerance = settings.tension_tolerance
    with beside(_variants, measured, rec.inversion, others, settings.errors, tolerance) as rest:
        [(fitted.tables[selected], fitted.sums[selected])] = _variants(measured, rec.inversion, [selected],
                                                                       settings.errors, tolerance)
        try:
            _readings(rec, settings, fitted)
        except Exception:
            rest.result()               # the other variants' error first, as in one step after the other
            raise
        for variant, (table, summary) in zip(others, rest.result()):
            fitted.tables[variant], fitted.sums[variant] = table, summary
    if ends and fitted.rheology is not None:
        fitted.rheology = spanned(fitted.rheology, [_at_end(rec, settings, end) for end in ends])
    if fitted.rheology is not None:
        fitted.rheology = widened(fitted.rheology, widenings)
    if rec.protocol_aware(settings):
        fitted.tables = {v: with_memory(t, measured.segments) for v, t in fitted.tables.items()}
    return fitted


def _at_end(rec: Recordings, settings: Settings, end: Measured) -> pd.DataFrame:
    """The rheology table of the segments corrected at the ends of each cell's memory interval
    (`analysis.afm.memory_span`)."""
    table = inverted(end, rec.inversion, settings.bending, settings.errors, settings.tension_tolerance)
    return _rheology(rec, settings, table, end.segments)[1]


def _rheology(rec: Recordings, settings: Settings, table: pd.DataFrame,
              segments: pd.DataFrame) -> tuple[pd.DataFrame, pd.DataFrame, dict[str, Any]]:
    """`analysis.afm.rheology.analyze` of the selected variant's `table` and its `segments` with the
    calibration file's complex forward model and the settings' errors and instrument phase."""
    from analysis.afm.rheology import analyze as rheology
    return rheology(table, segments, rec.calibration.viscoelastic, settings.bending, settings.errors, settings.lags,
                    settings.lag_source)


def _readings(rec: Recordings, settings: Settings, fitted: Fitted) -> None:
    """The selected variant's population answer and, when on, its viscoelastic reading, into `fitted`."""
    from analysis.afm.population.answer import answer
    fitted.population = answer(fitted.tables[settings.bending])
    if settings.phase:
        _viscoelastic(rec, settings, fitted)


def _viscoelastic(rec: Recordings, settings: Settings, fitted: Fitted) -> None:
    """The viscoelastic reading of the selected variant (`analysis.afm.rheology`) with the
    calibration file's complex forward model: its cells table gains the per-frequency
    columns; `fitted.rheology` = (table, summary)."""
    b = settings.bending
    table, rheo, summ = _rheology(rec, settings, fitted.tables[b], fitted.segments)
    fitted.tables[b] = table
    fitted.sums[b] = {**fitted.sums[b], "viscoelastic": summ}
    fitted.rheology = rheo


def _write(out: OutputDir, name: str, write: Callable[[Path], object]) -> Path:
    """`write(path)` for file `name` of the output folder `out` (`OutputDir`); its path."""
    with out.writing(name) as path:
        write(path)
    return path


def _json(document: dict[str, Any]) -> Callable[[Path], int]:
    return lambda p: p.write_text(json.dumps(document, indent=1) + "\n")


def _csv(table: pd.DataFrame) -> Callable[[Path], None]:
    return lambda p: table.to_csv(p, index=False)


def parts_markdown(calibration: CalibrationFile) -> str:
    """report.md's section: where each part of the calibration bundle came from (path or "shipped")."""
    rows = "".join(f"| {name} | {where} |\n" for name, where in calibration.sources.items())
    return f"\n## Calibration\n\n| part | from |\n|---|---|\n{rows}"


def write(out: OutputDir, rec: Recordings, fitted: Fitted, settings: Settings) -> Path:
    """The tables, summaries, figures and report.md into the `OutputDir` out; the report's path."""
    from analysis.afm.analyze import has_intervals
    from analysis.afm.analyze_report import markdown, markdown_skipped
    from analysis.afm.population.figures import figures, nu_intervals      # matplotlib: only now
    bending = settings.bending
    assert fitted.population is not None, "fit() gives the population answer"
    for variant in rec.variants:        # the selected one first (the manifest's order)
        _write(out, f"cells_{variant}.csv", _csv(fitted.tables[variant]))
        _write(out, f"summary_{variant}.json", _json(fitted.sums[variant]))
        if variant == bending:
            _write(out, "segments.csv", _csv(fitted.segments))
            _write(out, "cells.csv", _csv(fitted.tables[bending]))
    tolerance = settings.tension_tolerance if math.isfinite(settings.tension_tolerance) else None
    aware = ({"protocol": {**protocol_summary(fitted.segments, rec.reading.wait_s, settings.memory_s),
                           "replays_read_back": fitted.replays_read_back}} if rec.protocol_aware(settings) else {})
    made = {"reading": rec.reading.label(), "provenance": rec.provenance.to_dict()}
    parts = {"calibration_parts": rec.calibration.sources}
    _write(out, "summary.json", _json({"bending": bending, "method": rec.method, "tension_tolerance": tolerance,
                                       **parts, **made, **aware, **fitted.sums[bending]}))
    _write(out, "population.json", _json({"bending": bending, "method": rec.method, **fitted.population}))
    figs = figures(fitted.tables, fitted.sums, fitted.segments, out)
    if has_intervals(fitted.tables[bending]):
        figs.append(nu_intervals(fitted.tables[bending], out))
    from analysis.afm.population.answer_figures import population_figures
    figs += population_figures(fitted.tables[bending], fitted.population, out)
    text = markdown(rec.name, bending, rec.method, fitted.tables, fitted.sums, figs,
                    fitted.population) + made_markdown(rec.reading, rec.provenance) + parts_markdown(rec.calibration)
    text += markdown_skipped(None, rec.skipped)
    if aware:
        text += "\n".join(protocol_markdown(fitted.segments)) + "\n"
    for line in (odd := confinement_warnings(rec.cells)):
        print(line, file=sys.stderr)        # once the analysis stands: bad input keeps its one line
    if odd:
        text += "\n## Recordings that may not be plate confinement\n\n" + "".join(f"- {w}\n" for w in odd)
    if fitted.rheology is not None:
        from analysis.afm.rheology import markdown as rheology_markdown
        _write(out, "rheology.csv", _csv(fitted.rheology))
        text += rheology_markdown(fitted.rheology, fitted.sums[bending]["viscoelastic"])
    return _write(out, "report.md", lambda p: p.write_text(text))


def run(data: str | Path | Sequence[str | Path], calibration: CalibrationFile,
        out: str | Path, settings: Settings = Settings()) -> dict[str, Any]:
    """Analyse `data` (a path or a list of paths) into DIR `out` (read -> fit ->
    write) with the calibration file `calibration` (`analysis.calibration.file.load_calibration`, read
    once); the result has the report's path, the summary, the table and the
    skipped recordings."""
    from analysis.afm.analyze_report import markdown_skipped
    rec = read(data, calibration, settings)
    folder = OutputDir(out)                           # refused now if not ours
    from analysis.afm.population.answer_figures import POPULATION_FIGURES
    folder.check(["segments.csv", "cells.csv", "summary.json", "report.md", "nu_intervals.png", *FIGURES,
               "population.json", *POPULATION_FIGURES] + (["rheology.csv"] if settings.phase else [])
              + [f"{kind}_{v}.{ext}" for v in rec.variants for kind, ext in (("cells", "csv"), ("summary", "json"))])
    if not rec.cells:
        report = _write(folder, "report.md", lambda p: p.write_text(markdown_skipped(rec.name, rec.skipped)))
        return {"report": report, "summary": None, "table": None, "skipped": rec.skipped}
    store = ReplayStore(folder) if rec.protocol_aware(settings) else None
    fitted = fit(rec, settings, store)
    if fitted.replays_read_back:
        n = fitted.replays_read_back
        print(f"protocol: {n} replay{'s' if n > 1 else ''} read back from {folder.path / REPLAYS} "
              "(a reading there before replayed them)", file=sys.stderr)
    report = write(folder, rec, fitted, settings)
    return {"report": report, "summary": fitted.sums[settings.bending],
            "table": fitted.tables[settings.bending], "skipped": rec.skipped, "population": fitted.population}
