"""The carried-state correction (`analysis.afm.carried`, `solver.carried_state`) given the truth,
on an experiment simulated in time (SPEC 10 and 12). Prints one JSON object.

Each cell's segments are corrected with its true moduli (truth.json: |K_B*|, δ_B, |K_S*|, δ_S
per frequency) and true γ_a, then read by the published relaxed-state reading (the emulator
inversion, filter lifted, and the viscoelastic reading). Per reading, `raw` (the segments as
recorded) and `corrected`: over the cells with exponents the median error of β_B and β_S and
the share of 95 % intervals holding the truth, the median error of ln K̃_S over the curves, and
the median tension deviation (the published filter excludes a cell above 0.1).

This is the correction at its best (no estimate of the moduli in the loop): a reading built on
it can do no better.

    cortex afm synth --time-domain --cells 40 --jobs 2 --out EXP
    python bench/carried_state.py EXP [N_CELLS]
"""

import json
import math
import sys
from typing import Any

import numpy as np
import pandas as pd

from analysis.afm.analyze import Measured, inverted, measure, measured_of
from analysis.afm.analyze_pipeline import Settings, read
from analysis.afm.carried import correct
from analysis.afm.rheology import analyze as rheology
from analysis.calibration.file import load_calibration


def true_moduli(cells: list[Any], truth: dict[str, Any]) -> pd.DataFrame:
    """`correct`'s moduli table from the truth."""
    rows = []
    for c in cells:
        t = truth[c.cell_id]
        for f, v in t["frequencies"].items():
            rows.append({"cell_id": c.cell_id, "frequency_hz": float(f), "bulk_abs": v["bulk_mN_per_m"],
                         "bulk_delta": v["bulk_loss_angle_rad"], "shear_abs": v["shear_mN_per_m"],
                         "shear_delta": v["shear_loss_angle_rad"], "tension": t["tension_mN_per_m"],
                         "volume": c.volume_um3})
    return pd.DataFrame(rows)


def reading(measured: Measured, rec: Any, truth: dict[str, Any]) -> dict[str, Any]:
    """The relaxed-state reading of `measured` against the truth."""
    table = inverted(measured, rec.inversion, "standard", None, math.inf)
    table, rheo, _ = rheology(table, measured.segments, rec.calibration.viscoelastic, "standard")
    out: dict[str, Any] = {"cells_with_exponents": len(rheo)}
    for name in ("bulk", "shear"):
        true = rheo["cell_id"].map(lambda c: truth[c][f"{name}_exponent"])
        lo, hi = rheo[f"{name}_exponent_lo95"], rheo[f"{name}_exponent_hi95"]
        out[f"{name}_exponent_median_error"] = float(np.median(rheo[f"{name}_exponent"] - true))
        out[f"{name}_exponent_interval_coverage"] = float(((lo <= true) & (true <= hi)).mean())
    ks = [np.log(r.ks_tilde / truth[r.cell_id]["frequencies"][f"{r.frequency_hz:g}" if
                                                            f"{r.frequency_hz:g}" in truth[r.cell_id]["frequencies"]
                                                            else str(r.frequency_hz)]["ks_tilde"])
          for r in table.itertuples() if np.isfinite(r.ks_tilde)]
    out["ln_ks_tilde_median_error"] = float(np.median(ks))
    out["tension_deviation_median"] = float(np.median(list(measured.deviation.values())))
    return out


def main() -> None:
    exp = sys.argv[1]
    n = int(sys.argv[2]) if len(sys.argv) > 2 else None
    with open(f"{exp}/truth.json") as fh:
        truth_doc = json.load(fh)
    truth = {c["cell_id"]: c for c in truth_doc["cells"]}
    rec = read(f"{exp}/experiment.h5", load_calibration(None), Settings(phase=True))
    cells = rec.cells[:n]
    raw = measure(cells)
    segments = correct(raw.segments, cells, true_moduli(cells, truth), "standard", None, progress=False)
    volumes = {c.cell_id: c.volume_um3 for c in cells}
    fixed = measured_of(segments.assign(volume_um3=segments["cell_id"].map(volumes)), raw.order)
    print(json.dumps({"cells": len(cells), "wait_s": truth_doc["time_domain"]["wait_s"],
                      "history": truth_doc["time_domain"]["history"],
                      "raw": reading(raw, rec, truth), "corrected": reading(fixed, rec, truth)}, indent=1))


if __name__ == "__main__":
    main()
