"""Benchmark of `cortex afm analyze`, end to end: 100 synthetic cells recorded at
all four frequencies, errors on, the shipped calibration (emulator, every bending
variant, 95 % intervals, the viscoelastic reading, the population, figures, report).
The recordings come from the law forward model (quick to make) and are written to an
experiment file first, recorded as frequency-domain synthetic, so the command's default reads
them as that model makes them, in the relaxed state (the protocol-aware reading, its default for
measured and time-domain files, is timed by bench/time_domain_synth.py's recipe, docs/performance.md).

Each run is what the command runs (`analysis.calibration.file.load_calibration` of the shipped
calibration, then `analysis.afm.analyze_pipeline.run` with the command's default
settings) in this process, its steps timed by wrapping the functions the pipeline
calls: reading (the calibration file too), segment fits (the
curves), the selected variant's emulator fit, bootstrap intervals and summary
(with the median's bootstrap), the population answer, the viscoelastic reading,
the wait for the other two variants (inverted meanwhile in a forked process beside
this one, `common.beside`; `other_variants_wait`, and that process's CPU seconds,
`other_variants_cpu_s`), the figures, and the rest of the writing (tables and
report.md). Wall and CPU seconds of this process per step, best of --repeat runs
(by total wall), and one run of the
command as its own process (`cli_wall_s`, with the interpreter's start and the
imports). Prints one JSON object; target: cli_wall_s <= 15 s on 2 cores.

    .venv/bin/python bench/afm.py [--cells 100] [--repeat 3]
"""

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

import analysis.afm.synth.cells as synth
from analysis.afm.formats.h5 import write_experiment
from analysis.afm.provenance import FREQUENCY_DOMAIN
sys.path.insert(1, str(Path(__file__).resolve().parents[1]))   # `studies`, beside bench/ (not installed)
from studies.synthetic import reference_law  # noqa: E402

TARGET_S = 15.0
ROOT = Path(__file__).resolve().parent.parent


def _timers():
    """Wrap the functions the pipeline calls; returns {step: [wall_s, cpu_s]} filled as they run."""
    import analysis.afm.analyze_pipeline as pipeline
    import analysis.afm.population.answer as answer
    import analysis.afm.population.answer_figures as answer_figures
    import analysis.afm.population.figures as figures
    import analysis.invert.intervals as intervals
    import analysis.invert.method as method
    import common.beside as beside
    spent: defaultdict[str, list[float]] = defaultdict(lambda: [0.0, 0.0])

    def wrap(module, name, step):
        inner = getattr(module, name)

        def timed(*args, **kwargs):
            w, c = time.perf_counter(), time.process_time()
            try:
                return inner(*args, **kwargs)
            finally:
                spent[step][0] += time.perf_counter() - w
                spent[step][1] += time.process_time() - c
        setattr(module, name, timed)

    for module, name, step in ((pipeline, "open_cells", "read"), (pipeline, "measure", "segment_fits"),
                               (method, "invert_curves_emulator", "inversion_fit_selected"),
                               (intervals, "cell_intervals", "bootstrap_intervals_selected"),
                               (beside.Later, "result", "other_variants_wait"),
                               (pipeline, "summarise", "summaries_selected"), (answer, "answer", "population"),
                               (pipeline, "_viscoelastic", "viscoelastic"),
                               (figures, "figures", "figures"), (figures, "nu_intervals", "figures"),
                               (answer_figures, "population_figures", "figures"), (pipeline, "write", "write")):
        wrap(module, name, step)
    return spent


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cells", type=int, default=100)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    from analysis.afm.analyze_pipeline import Settings, run
    from analysis.calibration.file import load_calibration
    from analysis.invert.measurement_errors import MeasurementErrors
    synth.SUBSETS = (((0.02, 0.1, 1.0, 10.0), 1),)
    with tempfile.TemporaryDirectory() as tmp:
        cells, _ = synth.generate(args.cells, seed=0, errors=True, forward=synth.law_forward(reference_law()))
        data = Path(tmp) / "experiment.h5"
        write_experiment(data, cells, FREQUENCY_DOMAIN)
        spent = _timers()
        runs = []
        for i in range(args.repeat):
            spent.clear()
            w, c = time.perf_counter(), time.process_time()
            children = resource.getrusage(resource.RUSAGE_CHILDREN)
            file = load_calibration()
            spent["read"] = [time.perf_counter() - w, time.process_time() - c]    # + the recordings, below
            settings = Settings(method="emulator", errors=MeasurementErrors().check(), phase=True)
            run(str(data), file, Path(tmp) / f"an{i}", settings)
            spent["total"] = [time.perf_counter() - w, time.process_time() - c]
            after = resource.getrusage(resource.RUSAGE_CHILDREN)
            other_cpu = after.ru_utime + after.ru_stime - children.ru_utime - children.ru_stime
            runs.append(({k: v[:] for k, v in spent.items()}, other_cpu))
        best, other_cpu = min(runs, key=lambda r: r[0]["total"][0])
        best["report_and_tables"] = [best["write"][j] - best["figures"][j] for j in (0, 1)]
        del best["write"]
        t0 = time.perf_counter()
        subprocess.run([str(Path(sys.executable).parent / "cortex"), "afm", "analyze", str(data), "--out", str(Path(tmp) / "cli")],
                       check=True, cwd=ROOT, stdout=subprocess.DEVNULL)
        cli = time.perf_counter() - t0
    print(json.dumps({"cells": len(cells), "frequencies": 4, "repeat": args.repeat,
                      "steps_wall_s": {k: round(v[0], 3) for k, v in best.items()},
                      "steps_cpu_s": {k: round(v[1], 3) for k, v in best.items()},
                      "other_variants_cpu_s": round(other_cpu, 3),
                      "total_wall_s": round(best["total"][0], 3), "cli_wall_s": round(cli, 3),
                      "target_wall_s": TARGET_S}, indent=1))


if __name__ == "__main__":
    main()
