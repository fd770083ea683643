"""Benchmark of `cortex afm tension`: 100 synthetic recordings of tension-only
droplets (approach ramp of 1000 samples to depths from h̃ = 0.95 to 0.5, a
500-sample pause, a retract; noise 0.02 nN), written as one native experiment
and analysed by the installed command, once without and once with --out (the
figures). Prints one JSON object; target: the analysis of 100 recordings
(`cortex afm tension EXP.h5 --json`, the whole process) within 10 s.

It also prints docs/studies/tension-ramps.md's known-truth tables (`depth_table`): ramps of a
droplet of V = 4300 µm³ and T = 1 mN/m down to h̃ from 0.98 to 0.5 (1000 samples,
force noise 0.02 nN, height noise 1 nm, 8 seeds), fitted by both models: T / T_true
(mean, largest error), contact error, R²; and the bias table of an elastic cell
(`bias_table`): the droplet's apparent tension / γ_a of noise-free shell ramps
(R = 6.8 µm, γ_a = 0.5 mN/m, K_S/K_B = 1/3, `synth.shell_ramp`) against K_B/γ_a
and the window's depth.

The 100 recordings are analysed twice: `--model droplet` (target 10 s) and the
shell model alone (`--no-power-law`: the elastic reading; `shell_wall_s`, target 30 s; its errors against the truth,
how many ramps are off by more than 5 % and 1 %, and for how many the elastic
term was not significant, so the droplet was returned)."""

import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from analysis.afm.formats.h5 import write_experiment
from analysis.afm.formats.instruments import to_cell, wedge_height_um
from analysis.afm.tension.ramp import fit_ramp
from solver.geometry import cell_radius

sys.path.insert(1, str(Path(__file__).resolve().parents[1]))   # `studies`, beside bench/ (not installed)
from studies.tension_synth import droplet_recording, shell_ramp  # noqa: E402

N = 100


def _experiment(path):
    rng = np.random.default_rng(0)
    cells, truth = [], []
    for i in range(N):
        volume, tension, h_tilde = rng.uniform(2500, 6000), rng.uniform(0.2, 2.0), rng.uniform(0.5, 0.95)
        depth = 2.0 * float(cell_radius(volume)) * (1.0 - h_tilde)
        rec = droplet_recording(volume, tension, depth, cell_id=f"c{i:03d}", baseline_nN=1.0, seed=i)
        cells.append(to_cell(rec, volume, "synthetic"))
        truth.append(tension)
    write_experiment(path, cells)
    return np.array(truth)


def _depth_table(volume=4300.0, tension=1.0, seeds=8):
    radius = float(cell_radius(volume))
    rows = []
    for h_tilde in (0.98, 0.97, 0.95, 0.9, 0.8, 0.7, 0.6, 0.5):
        depth = 2.0 * radius * (1.0 - h_tilde)
        fits = {"droplet": [], "small-deformation": []}
        for seed in range(seeds):
            rec = droplet_recording(volume, tension, depth, noise_nN=0.02, height_noise_um=0.001, baseline_nN=2.0,
                                    seed=seed)
            x, f = wedge_height_um(rec.segments[0], rec.spring_constant_N_per_m), rec.segments[0].force_nN
            for model, out in fits.items():
                fit = fit_ramp(x, f, radius, model)
                out.append((fit.tension_mN_per_m / tension, fit.contact_um - 2.0 * radius, fit.r2))
        row = {"h_tilde": h_tilde, "depth_um": round(depth, 3), "depth_over_R": round(depth / radius, 3)}
        for model, out in fits.items():
            a = np.array(out)
            row[model] = {"T_ratio_mean": round(float(a[:, 0].mean()), 4),
                          "T_max_rel_error": round(float(np.abs(a[:, 0] - 1).max()), 4),
                          "contact_error_um_mean": round(float(a[:, 1].mean()), 4),
                          "r2_mean": round(float(a[:, 2].mean()), 4)}
        rows.append(row)
    return rows


def _bias_table(radius=6.8, tension=0.5, depths=(0.25, 0.5, 0.75, 1.0)):
    rows = []
    for ratio in (5, 10, 20, 40, 80):
        x, f = shell_ramp(radius, tension, ratio * tension, ratio * tension / 3.0, max(depths), noise_nN=0.0)
        rows.append({"kb_over_gamma": ratio, "droplet_T_over_gamma": {
            str(d): round(fit_ramp(x, f, radius, "droplet", cap_um=d).tension_mN_per_m / tension, 3)
            for d in depths}})
    return rows


def _run(*args):
    t0 = time.perf_counter()
    proc = subprocess.run([str(Path(sys.executable).parent / "cortex"), "afm", "tension", *map(str, args)],
                          capture_output=True, text=True)
    return time.perf_counter() - t0, proc


def _cpu_s():
    """CPU seconds (user + system) of the finished child processes so far."""
    import resource
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def main():
    with tempfile.TemporaryDirectory() as tmp:
        exp = Path(tmp) / "experiment.h5"
        truth = _experiment(exp)
        wall, proc = _run(exp, "--json", "--model", "droplet")
        rows = json.loads(proc.stdout)["rows"]
        ramps = np.array([r["tension_mN_per_m"] for r in rows if r["part"] == "approach"])
        pauses = np.array([r["tension_mN_per_m"] for r in rows if r["part"] == "pause"])
        wall_out, proc_out = _run(exp, "--json", "--model", "droplet", "--out", Path(tmp) / "out")
        cpu0 = _cpu_s()
        shell_wall, shell_proc = _run(exp, "--json", "--no-power-law")
        shell_cpu = _cpu_s() - cpu0
        shell_doc = json.loads(shell_proc.stdout)
        approach = [r for r in shell_doc["rows"] if r["part"] == "approach"]
        shell = np.array([r["tension_mN_per_m"] / truth[int(r["cell_id"][1:])] - 1.0 for r in approach])
        dropped = sum(r["elastic_term"] == "not significant" for r in approach)
    print(json.dumps({"recordings": N, "rows": len(rows), "status": proc.returncode,
                      "wall_s": round(wall, 3), "wall_with_out_s": round(wall_out, 3),
                      "status_with_out": proc_out.returncode,
                      "ramp_max_rel_error": float(np.max(np.abs(ramps / truth - 1))),
                      "pause_max_rel_error": float(np.max(np.abs(pauses / truth - 1))),
                      "target_wall_s": 10.0, "shell_wall_s": round(shell_wall, 3),
                      "shell_cpu_s": round(shell_cpu, 3),
                      "shell_status": shell_proc.returncode, "shell_target_wall_s": 30.0,
                      "shell_ramp_max_rel_error": float(np.max(np.abs(shell))),
                      "shell_ramp_median_rel_error": float(np.median(np.abs(shell))),
                      "shell_ramps_over_5pct": int(np.sum(np.abs(shell) > 0.05)),
                      "shell_ramps_over_1pct": int(np.sum(np.abs(shell) > 0.01)),
                      "shell_elastic_term_not_significant": int(dropped), "shell_ramps": len(approach),
                      "shell_not_analysed": shell_doc["not_analysed"],
                      "bias_table": _bias_table(), "depth_table": _depth_table()}))


if __name__ == "__main__":
    main()
