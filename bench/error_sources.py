"""Where the remaining error comes from (issue 13, item 6): the synthetic
experiment's measurement errors switched on one at a time. Prints one JSON
object.

The forward model is the shipped emulator itself (within 0.05 % of the
solver, and instant), so what moves the medians is the error switched on and
the analysis, not the forward model. Per configuration and method: recovered
minus true median ν per frequency (true median over the included cells), the
included count, and (emulator) how often the 95 % interval holds the true ν.
Configurations: none; volume (SD 7.5 %); height offset (SD 0.5 µm); force
noise (0.2 nN); drift (±0.001 nN/s); blebbing (8 % of cells, with the others
off; the tension filter should exclude them); all.

    python bench/error_sources.py [SEED]        (default 6)
"""

import json
import sys
from pathlib import Path

sys.path = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

from analysis.afm import synth  # noqa: E402
from analysis.afm.analyze import analyze  # noqa: E402
from analysis.shipped import load  # noqa: E402

ALL = dict(synth.ERRORS)
ONLY = {"none": {}, "volume": {"volume_rel_sd"}, "height": {"height_offset_sd_um"},
        "force_noise": {"force_noise_nN"}, "drift": {"drift_nN_per_s"}, "blebbing": {"bleb_fraction"},
        "all": set(ALL)}


def emulator_forward(emu, bending="standard"):
    from solver.geometry import cell_radius

    def forward(volume, heights, bulk, shear, tension):
        h = heights / (2.0 * float(cell_radius(volume)))
        return emu.modulus(h, bulk, shear / bulk, tension, volume, bending)
    return forward


def main():
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from roundtrip import score
    seed = int(sys.argv[1]) if len(sys.argv) > 1 else 6
    cal, emu, _ = load()
    out = {"benchmark": "error_sources", "seed": seed, "cells": 85, "rows": []}
    for name, keep in ONLY.items():
        synth.ERRORS.update({k: (v if k in keep else 0.0) for k, v in ALL.items()})
        cells, truth = synth.generate(85, seed, errors=True, forward=emulator_forward(emu))
        row = {"errors_on": name}
        for method in ("emulator", "law"):
            table, _ = analyze(cells, cal, "standard", method=method, emulator=emu)
            s = score(table, truth)
            row[method] = {"n_included": s["n_included"], "coverage_95": s.get("coverage_95"),
                           "median_error": {f: round(v["median_nu"] - v["median_nu_true"], 4)
                                            for f, v in s["per_frequency"].items()}}
        out["rows"].append(row)
        print(json.dumps(row), file=sys.stderr, flush=True)
    synth.ERRORS.update(ALL)
    print(json.dumps(out))


if __name__ == "__main__":
    main()
