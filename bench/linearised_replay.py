"""The protocol-aware reading's linearised replay against the full one, and the reading's cost.
Prints one JSON object.

`accuracy`: on held-out protocols (none of them a test's), each cell's correction factors
c_j = K*_td,j / K*_r,j and Δγ_j (`analysis.afm.replayed.cell_correction`) by the linearised
replay (the default reading) and by the full replay (REPLAY resolution, `linearised=False`),
and with `--fine` also by the FINE simulation read by the segment fit (the synthetic
experiments' own resolution: the reference both approximate). Per case and over all: the
largest |c_lin|/|c_full| - 1, |arg c_lin - arg c_full| (rad) and |Δγ_lin - Δγ_full| (mN/m), the
CPU of one replay each way, and whether the issue's bounds hold (1 % in |K*|, 0.005 rad).
`--synth DIR` adds every cell of a time-domain synthetic experiment but its blebbing ones,
replayed with its true power laws and memory (truth.json); with `--fine` and an experiment made
without measurement errors (`afm synth --no-errors`) also against its recording, read by the
segment fit: the FINE simulation itself.

`speed`: `cortex afm analyze DIR --jobs 1` (the default, protocol-aware reading) on a
time-domain synthetic experiment, this checkout and, with `--reference`, another one, one after
the other (CPU: the child's rusage, user + system). Per cell and, extrapolated (labelled so),
for 100 cells at 4 frequencies: CPU per cell × 100 × 4 / (the experiment's frequencies).

    python bench/linearised_replay.py accuracy [--fine] [--synth DIR]
    python bench/linearised_replay.py speed DIR [--reference OLD_CHECKOUT]
"""

import argparse
import json
import math
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parents[1]
BOUNDS = {"modulus_rel": 0.01, "phase_rad": 0.005}

sys.path.insert(0, str(HERE))                  # studies/ is not installed
from studies.held_out import CASES  # noqa: E402


def _cell(name, volume, start, heights, freqs, periods, wait, bending, kb, ks, bb, bs, tension):
    """The case simulated at FINE as a recording (a cell with its protocol), its law and shell."""
    from analysis.afm.synth.time_domain import recording_cell
    from solver.model import Shell
    from solver.protocol import Protocol
    from solver.protocol_simulation import simulate
    from solver.time_domain import power_law_cortex
    shell = Shell(volume_um3=volume, h0_um=start, bulk_mN_per_m=kb, shear_mN_per_m=ks, tension_mN_per_m=tension,
                  bending=bending)
    cortex = power_law_cortex(kb, ks, bb, bs)
    rec = simulate(shell, cortex, Protocol.stepped(start, heights, freqs, periods, wait_s=wait))
    law = {"bulk_1s": kb, "shear_1s": ks, "bulk_beta": bb, "shear_beta": bs, "tension": tension}
    return recording_cell(rec, volume, name), law, shell, cortex


def _fine_factors(cell, shell, cortex, law):
    """c_j and Δγ_j of the FINE recording itself read by the segment fit (the reference)."""
    from analysis.afm.replayed import _relaxed
    from analysis.afm.recorded_protocol import protocol_of
    from analysis.afm.timeseries import segment_moduli
    from solver.protocol import Oscillate
    rows, protocol = segment_moduli(cell), protocol_of(cell)
    oscillations = [s for s in protocol.steps if isinstance(s, Oscillate)]
    out = []
    for row, osc in zip(rows, oscillations):
        K = row["modulus_mN_per_m"] * np.exp(1j * row["loss_angle_rad"]) / _relaxed(shell, cortex, row["mean_height_um"], osc)
        out.append((abs(K), float(np.angle(K)), row["tension_mN_per_m"] - law["tension"]))
    return np.array(out)


def _compare(a, b):
    return {"modulus_rel_max": float(np.max(np.abs(a[:, 0] / b[:, 0] - 1))),
            "phase_rad_max": float(np.max(np.abs(a[:, 1] - b[:, 1]))),
            "tension_shift_mN_per_m_max": float(np.max(np.abs(a[:, 2] - b[:, 2])))}


def _case(cell, law, bending, fine=None, memory=math.inf):
    from analysis.afm.replayed import cell_correction
    out, factors = {"segments": len(cell.oscillations())}, {}
    for name, lin in (("linearised", True), ("full", False)):
        t0 = time.process_time()
        f = cell_correction(cell, law, bending, linearised=lin, memory=memory)
        out[f"{name}_cpu_s"] = time.process_time() - t0
        if isinstance(f, str):
            return {**out, "error": f"{name}: {f}"}
        factors[name] = f
    out["linearised_vs_full"] = _compare(factors["linearised"], factors["full"])
    if fine is not None:
        out["linearised_vs_fine"] = _compare(factors["linearised"], fine)
        out["full_vs_fine"] = _compare(factors["full"], fine)
    return out


def accuracy(fine: bool, synth: Path | None) -> dict:
    cases = {}
    for case in CASES:
        cell, law, shell, cortex = _cell(*case)
        cases[case[0]] = _case(cell, law, case[7], _fine_factors(cell, shell, cortex, law) if fine else None)
    if synth is not None:
        from analysis.afm.formats import reader
        from solver.model import Shell
        from solver.time_domain import power_law_cortex
        made = json.loads((synth / "truth.json").read_text())
        truth, made_td = {c["cell_id"]: c for c in made["cells"]}, made["time_domain"]
        bending, memory = made_td["bending"], made_td.get("memory_s", math.inf)
        exact = fine and not made["errors"]
        for cell in reader.open(synth / "experiment.h5"):
            t = truth[cell.cell_id]
            if t.get("blebbing"):
                continue
            law = {"bulk_1s": t["bulk_1s_mN_per_m"], "shear_1s": t["shear_1s_mN_per_m"],
                   "bulk_beta": t["bulk_exponent"], "shear_beta": t["shear_exponent"], "tension": t["tension_mN_per_m"]}
            shell = Shell(volume_um3=cell.volume_um3, h0_um=cell.height_um[0], bulk_mN_per_m=law["bulk_1s"],
                          shear_mN_per_m=law["shear_1s"], tension_mN_per_m=law["tension"], bending=bending)
            cortex = power_law_cortex(law["bulk_1s"], law["shear_1s"], law["bulk_beta"], law["shear_beta"])
            cases[f"synth:{cell.cell_id}"] = _case(cell, law, bending, _fine_factors(cell, shell, cortex, law)
                                                   if exact else None, memory if memory is not None else math.inf)
    done = [c["linearised_vs_full"] for c in cases.values() if "linearised_vs_full" in c]
    worst = {k: max(c[k] for c in done) for k in done[0]}
    cpu = {k: float(np.mean([c[f"{k}_cpu_s"] for c in cases.values()])) for k in ("linearised", "full")}
    return {"bounds": BOUNDS, "cases": cases, "worst_linearised_vs_full": worst,
            "within_bounds": worst["modulus_rel_max"] <= BOUNDS["modulus_rel"]
            and worst["phase_rad_max"] <= BOUNDS["phase_rad"],
            "replay_cpu_s_mean": cpu, "replay_speedup": cpu["full"] / cpu["linearised"]}


def _analyze(checkout: Path, experiment: Path, out: Path) -> float:
    env = {**os.environ, "PYTHONPATH": str(checkout), "OPENBLAS_NUM_THREADS": "1"}
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run([sys.executable, "-c", "from cortex.cli import main; raise SystemExit(main())", "afm", "analyze",
                    str(experiment), "--out", str(out), "--jobs", "1"], env=env, cwd=checkout, check=False,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)


def speed(experiment: Path, reference: Path | None, work: Path) -> dict:
    truth = json.loads((experiment / "truth.json").read_text())
    cells = len(truth["cells"])
    frequencies = len(truth["cells"][0]["frequencies"])
    out: dict = {"experiment": str(experiment), "cells": cells, "frequencies": frequencies}
    for name, checkout in (("this", HERE), ("reference", reference)):
        if checkout is None:
            continue
        cpu = _analyze(checkout, experiment, work / name)
        summary = json.loads((work / name / "summary.json").read_text())
        out[name] = {"checkout": str(checkout), "cpu_s": cpu, "cpu_s_per_cell": cpu / cells,
                     "replays_per_cell": summary.get("protocol", {}).get("replays_per_cell"),
                     "extrapolated_cpu_s_100_cells_4_frequencies": cpu / cells * 100 * 4 / frequencies}
    if reference is not None:
        out["cpu_ratio"] = out["this"]["cpu_s"] / out["reference"]["cpu_s"]
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="what", required=True)
    a = sub.add_parser("accuracy")
    a.add_argument("--fine", action="store_true", help="also against the FINE recording itself")
    a.add_argument("--synth", type=Path, help="a time-domain synthetic experiment's folder")
    s = sub.add_parser("speed")
    s.add_argument("experiment", type=Path, help="a time-domain synthetic experiment's folder")
    s.add_argument("--reference", type=Path, help="another checkout of the project")
    s.add_argument("--work", type=Path, help="folder for the readings (default: a temporary one)")
    args = ap.parse_args()
    if args.what == "accuracy":
        result = accuracy(args.fine, args.synth)
    else:
        with tempfile.TemporaryDirectory() as tmp:
            result = speed(args.experiment, args.reference, args.work or Path(tmp))
    print(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
