"""Benchmark of `analysis.afm.analyze`: 100 synthetic cells recorded at all
four frequencies, errors on. The recordings come from the law forward model
(quick to make; the analysis does not depend on how they were made). Prints one JSON object;
target analyze_wall_s < 10 s."""

import json
import time

from analysis.afm import analyze as cell_analyses
from analysis.invert.method import choose
from analysis.afm.synth.cells import generate, law_forward
from analysis.calibration.law import Calibration
from analysis.synthetic import reference_law
import analysis.afm.synth.cells as synth


def main():
    synth.SUBSETS = (((0.02, 0.1, 1.0, 10.0), 1),)
    t0 = time.perf_counter()
    cells, _ = generate(100, seed=0, errors=True, forward=law_forward(reference_law()))
    t1 = time.perf_counter()
    table, segs = choose("law", Calibration({"standard": reference_law()}), None).analyze_cells(
        cells, "standard", None, cell_analyses)
    t2 = time.perf_counter()
    print(json.dumps({"cells": len(cells), "frequencies": 4, "segments": len(segs),
                      "samples": int(sum(len(c.time_s) for c in cells)),
                      "synth_wall_s": round(t1 - t0, 3), "analyze_wall_s": round(t2 - t1, 3),
                      "target_analyze_wall_s": 10.0}))


if __name__ == "__main__":
    main()
