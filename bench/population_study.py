"""The population answer (docs/population.md) against known truth: coverage of its
intervals, the measurement share, and the power of paired against unpaired tests.
Prints one JSON object.

    python bench/population_study.py full SEED ... [--no-errors] --cache FILE.jsonl
    python bench/population_study.py simulate --cache FILE.jsonl [--experiments 200] [--reps 400] [--rho 1 0.7]
    python bench/population_study.py rescore --cache FILE.jsonl

`full`: per seed, the whole pipeline: `cortex afm synth`'s experiment (85 cells,
the published design, the fast solver as the forward model, errors on unless
--no-errors), `cortex afm analyze`'s inversion (emulator, standard bending;
with --no-errors the intervals also assume no volume or height error) and its
population.json (`analysis.afm.population.answer.answer`). Each experiment is
appended to the cache (one JSON line: truth, the answer, every cell's estimate,
its standard error `ln_ks_se`, its 95 % interval and its true ln K̃_S) and the summary
covers every cached experiment of that kind: how often the 95 % intervals of the
population mean μ_f and SD σ_f hold the synth's (μ_f, σ_f), how often the interval of
the answer's slope (`slope_*`) and of the design-weighted one (`slope_design_weighted_*`)
hold the least-squares line through the μ_f (`true_slope`) and the design-weighted
pseudo-true slope (`true_slope_design_weighted`), the measurement shares, the seconds
per experiment.

`rescore`: the `full` summary of every cached experiment (errors on and off) with
the population statistics recomputed by the current code from the cached per-cell
estimates (the inversion is not rerun). Every cell's s is its standard error `ln_ks_se`.

`simulate`: the same statistics over many more experiments, without the solver:
each simulated cell takes a fresh true ln K̃_S(f) = μ_f + σ_f z and the
measurement of a cell drawn (with replacement) from the cached full-pipeline
experiments with the same frequencies: its errors (estimate minus truth, NaN
where excluded) and its SDs, so the errors keep their size, their correlation
across a cell's frequencies, their relation to the reported SD and the filters'
exclusions; and again with those errors centred per frequency (`coverage_errors_centred`) and
with, besides, each s scaled so that its RMS is the actual errors' SD
(`coverage_errors_centred_sd_matched`): the measurement the model assumes, which
says how much of a shortfall is the model's and how much the per-cell errors'.
Then the power table: n cells measured at 0.1, 1 and 10 Hz (n = 10,
20, 50; included where their measurement was), the two-sided paired Wilcoxon
test per pair against the unpaired Mann-Whitney test on the same cells, and
Friedman against Kruskal-Wallis, all at p < 0.05 on ν; at the synth's within-cell
correlation of the true ln K̃_S across frequencies (1: one z per cell) and at a
weaker one (--rho).
"""

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
from scipy import stats

from analysis.afm.population import mean_trend, random_effects, trend
from analysis.afm.population.answer import answer
from solver.elasticity import poisson_of_ratio

FREQS = (0.02, 0.1, 1.0, 10.0)
PAIRED = (0.1, 1.0, 10.0)
SIZES = (10, 20, 50)
ALPHA = 0.05


def run_full(seed, errors):
    from analysis.afm.synth import cells as synth
    from analysis.afm.analyze import analyze_cells
    from analysis.invert.method import choose
    from analysis.invert.measurement_errors import MeasurementErrors
    from analysis.calibration.file import load_calibration
    file = load_calibration()
    cal, emu = file.calibration, file.emulator
    t0 = time.perf_counter()
    cells, truth = synth.generate(85, seed=seed, errors=errors)
    t1 = time.perf_counter()
    err = MeasurementErrors() if errors else MeasurementErrors(volume_rel_sd=0.0, height_sd_um=0.0)
    table, _ = analyze_cells(cells, choose("emulator", cal, emu), "standard", err)
    doc = answer(table)
    t2 = time.perf_counter()
    true = {(c["cell_id"], float(f)): float(np.log(v["ks_tilde"])) for c in truth["cells"]
            for f, v in c["frequencies"].items()}
    ok = table["excluded_reason"].isna()
    rows = [{"cell_id": r.cell_id, "frequency_hz": float(r.frequency_hz),
             "ln_ks": float(np.log(r.ks_tilde)) if ok[i] else None,
             "ln_ks_se": float(r.ln_ks_se) if ok[i] else None,
             "ks_lo95": float(r.ks_lo95) if ok[i] else None, "ks_hi95": float(r.ks_hi95) if ok[i] else None,
             "true_ln_ks": true[(r.cell_id, float(r.frequency_hz))]} for i, r in zip(table.index, table.itertuples())]
    return {"seed": seed, "errors": errors, "synth_s": t1 - t0, "analyze_s": t2 - t1,
            "populations": truth["populations"], "true_slope": truth["trend_slope_ln_ks_per_decade"],
            "true_slope_design_weighted": truth["trend_slope_design_weighted_ln_ks_per_decade"], "answer": doc,
            "cells": rows}


def _holds(lo, x, hi):
    return bool(lo is not None and hi is not None and lo <= x <= hi)


def summarise(records):
    """Coverage per frequency, of the slope, measurement shares, over `records` (full or simulated)."""
    out = {"experiments": len(records), "frequencies": {}}
    for f in FREQS:
        cov_mu, cov_sd, share, n = [], [], [], []
        for rec in records:
            mu, sd = rec["populations"][str(f)]
            r = next(r for r in rec["answer"]["frequencies"] if r["frequency_hz"] == f)
            cov_mu.append(_holds(r["mean_ln_ks_lo95"], mu, r["mean_ln_ks_hi95"]))
            cov_sd.append(_holds(r["between_cell_sd_ln_ks_lo95"], sd, r["between_cell_sd_ln_ks_hi95"]))
            share.append(r["measurement_share"])
            n.append(r["n_cells"])
        share = np.array(share, float)
        out["frequencies"][f"{f:g}"] = {
            "mean_coverage": float(np.mean(cov_mu)), "sd_coverage": float(np.mean(cov_sd)),
            "measurement_share_median": float(np.median(share)),
            "measurement_share_range": [float(share.min()), float(share.max())],
            "n_cells_median": float(np.median(n))}
    for key, name in (("trend", "slope"), ("trend_design_weighted", "slope_design_weighted")):
        t = [rec["answer"][key] for rec in records]
        for truth in ("true_slope", "true_slope_design_weighted"):
            out[f"{name}_holds_{truth}"] = float(np.mean([_holds(x["slope_lo95"], rec[truth], x["slope_hi95"])
                                                           for x, rec in zip(t, records)]))
        slopes = np.array([x["slope_ln_ks_per_decade"] for x in t])
        out[f"{name}_mean"] = float(slopes.mean())
        out[f"{name}_sd"] = float(slopes.std(ddof=1)) if len(t) > 1 else None
        out[f"{name}_half_width_median"] = float(np.median([(x["slope_hi95"] - x["slope_lo95"]) / 2 for x in t]))
    out["true_slope"] = records[0]["true_slope"]
    out["true_slope_design_weighted"] = records[0]["true_slope_design_weighted"]
    return out


def actual_errors(records):
    """Per frequency, median over experiments: the SD of the actual errors (estimate minus
    truth) of the included cells, their mean, the SD the intervals claim (s_m), and the share of
    the observed variance the actual errors explain, var(error) / var(estimate)."""
    out = {}
    for f in FREQS:
        sd, mean, claimed, share = [], [], [], []
        for rec in records:
            g = pd.DataFrame(rec["cells"]).dropna(subset=["ln_ks"])
            g = g[g["frequency_hz"] == f]
            e = g["ln_ks"] - g["true_ln_ks"]
            sd.append(e.std(ddof=1)), mean.append(e.mean()), claimed.append(np.sqrt(np.mean(g["s"] ** 2)))
            share.append(e.var(ddof=1) / g["ln_ks"].var(ddof=1))
        out[f"{f:g}"] = {"error_sd": float(np.median(sd)), "error_mean": float(np.median(mean)),
                         "error_mean_range": [float(np.min(mean)), float(np.max(mean))],
                         "claimed_sd": float(np.median(claimed)), "actual_share": float(np.median(share))}
    return out


def _load(cache, errors=None):
    """The cached experiments (of `errors` if given), each cell's s its standard error `ln_ks_se`."""
    recs = [json.loads(line) for line in Path(cache).read_text().splitlines() if line.strip()]
    recs = [r for r in recs if errors is None or r["errors"] == errors]
    for c in (c for r in recs for c in r["cells"] if c["ln_ks"] is not None):
        c["s"] = c["ln_ks_se"]
    return recs


def full(args):
    for seed in args.seeds:
        rec = run_full(seed, not args.no_errors)
        with open(args.cache, "a") as fh:
            fh.write(json.dumps(rec) + "\n")
        print(f"seed {seed}: {rec['synth_s']:.0f} s synth, {rec['analyze_s']:.0f} s analyze", file=sys.stderr)
    recs = _load(args.cache, not args.no_errors)
    out = {"kind": "full pipeline", "errors": not args.no_errors, "seeds": [r["seed"] for r in recs],
           "synth_s_median": float(np.median([r["synth_s"] for r in recs])),
           "analyze_s_median": float(np.median([r["analyze_s"] for r in recs])), **summarise(recs),
           "actual_errors": actual_errors(recs)}
    print(json.dumps(out))


def _pool(records):
    """{frequencies: [(errors per f, s per f), ...]} of the cached cells, by the frequencies measured."""
    pool = {}
    for rec in records:
        df = pd.DataFrame(rec["cells"])
        for cid, g in df.groupby("cell_id"):
            key = tuple(sorted(g["frequency_hz"]))
            e = {r.frequency_hz: (np.nan if r.ln_ks is None or pd.isna(r.ln_ks) else r.ln_ks - r.true_ln_ks)
                 for r in g.itertuples()}
            s = {r.frequency_hz: (np.nan if r.s is None or pd.isna(r.s) else r.s) for r in g.itertuples()}
            pool.setdefault(key, []).append((e, s))
    return pool


def _corrected(pool, centre, rescale):
    """The pool with each frequency's mean error removed (`centre`) and each s scaled so that its
    RMS is the SD of the actual errors (`rescale`): the measurement the model assumes."""
    errs = {}
    for cells in pool.values():
        for e, s in cells:
            for f in e:
                if np.isfinite(e[f]):
                    errs.setdefault(f, []).append((e[f], s[f]))
    shift = {f: float(np.mean([x for x, _ in v])) if centre else 0.0 for f, v in errs.items()}
    scale = {f: float(np.std([x for x, _ in v]) / np.sqrt(np.mean([y**2 for _, y in v]))) if rescale else 1.0
             for f, v in errs.items()}
    return {k: [({f: e[f] - shift[f] for f in e}, {f: s[f] * scale[f] for f in s}) for e, s in cells]
            for k, cells in pool.items()}


def _draw_cells(rng, pool, key, n, populations):
    """n cells of frequencies `key`: rows (cell, f, y, s) with y NaN where excluded."""
    rows = []
    picks = rng.integers(0, len(pool[key]), n)
    for i, k in enumerate(picks):
        e, s = pool[key][k]
        z = rng.standard_normal()
        for f in key:
            mu, sd = populations[str(f)]
            rows.append((i, f, mu + sd * z + e[f], s[f]))
    return rows


def _simulated_answer(rows):
    df = pd.DataFrame(rows, columns=["cell", "f", "y", "s"]).dropna()
    doc = {"frequencies": [{"frequency_hz": f, **random_effects.fit(g["y"], g["s"]).to_dict()}
                           for f, g in df.groupby("f")]}
    doc["trend"] = mean_trend.fit(df["cell"], df["f"], df["y"]).to_dict()
    doc["trend_design_weighted"] = trend.fit(trend.Observations.of(df["cell"], df["f"], df["y"], df["s"])).to_dict()
    return doc


def coverage_sim(rng, pool, template, n_exp):
    from analysis.afm.synth.cells import subset_sizes
    recs = []
    for _ in range(n_exp):
        rows, base = [], 0
        for freqs, n in subset_sizes(85):
            rows += [(c + base, f, y, s) for c, f, y, s in _draw_cells(rng, pool, tuple(freqs), n,
                                                                         template["populations"])]
            base += n
        recs.append({**{k: template[k] for k in ("populations", "true_slope", "true_slope_design_weighted")},
                     "answer": _simulated_answer(rows)})
    return summarise(recs)


def power(rng, pool, populations, reps, rho=1.0):
    """Power table at the within-cell correlation `rho` of the true ln K̃_S across frequencies
    (z_f = ρ z + sqrt(1 - ρ²) z'_f; the synth's cells have ρ = 1: one z per cell)."""
    keys = [k for k in pool if set(PAIRED) <= set(k)]
    flat = [(e, s) for k in keys for e, s in pool[k]]
    table = []
    for n in SIZES:
        hits = {}
        for _ in range(reps):
            nu = {f: np.full(n, np.nan) for f in PAIRED}
            for i, k in enumerate(rng.integers(0, len(flat), n)):
                e, _ = flat[k]
                z = rng.standard_normal()
                for f in PAIRED:
                    mu, sd = populations[str(f)]
                    zf = rho * z + np.sqrt(1.0 - rho**2) * rng.standard_normal()
                    nu[f][i] = poisson_of_ratio(np.exp(mu + sd * zf + e[f]))
            for a, b in ((0.1, 1.0), (1.0, 10.0), (0.1, 10.0)):
                both = np.isfinite(nu[a]) & np.isfinite(nu[b])
                key = f"{a:g}-{b:g} Hz"
                p_w = stats.wilcoxon(nu[b][both] - nu[a][both]).pvalue if both.sum() >= 6 else 1.0
                p_u = stats.mannwhitneyu(nu[a][np.isfinite(nu[a])], nu[b][np.isfinite(nu[b])]).pvalue
                hits.setdefault(f"wilcoxon {key}", []).append(p_w < ALPHA)
                hits.setdefault(f"mann_whitney {key}", []).append(p_u < ALPHA)
            allf = np.isfinite(np.column_stack([nu[f] for f in PAIRED])).all(axis=1)
            p_f = stats.friedmanchisquare(*[nu[f][allf] for f in PAIRED]).pvalue if allf.sum() >= 3 else 1.0
            p_k = stats.kruskal(*[nu[f][np.isfinite(nu[f])] for f in PAIRED]).pvalue
            hits.setdefault("friedman 0.1/1/10 Hz", []).append(p_f < ALPHA)
            hits.setdefault("kruskal_wallis 0.1/1/10 Hz", []).append(p_k < ALPHA)
        table.append({"n_cells": n, "rho": rho, **{k: float(np.mean(v)) for k, v in hits.items()}})
    return table


def rescore(args):
    """The summary of every cached full-pipeline experiment with its population statistics
    recomputed by the current code from the cached per-cell estimates (the inversion is not rerun)."""
    out = {}
    for errors in (True, False):
        recs = _load(args.cache, errors)
        if not recs:
            continue
        t0 = time.perf_counter()
        for rec in recs:
            df = pd.DataFrame(rec["cells"]).dropna(subset=["ln_ks"])
            cells = np.unique(df["cell_id"], return_inverse=True)[1]
            rec["answer"] = _simulated_answer(list(zip(cells, df["frequency_hz"], df["ln_ks"], df["s"])))
        out["errors_on" if errors else "errors_off"] = {
            "seeds": [r["seed"] for r in recs], "refit_s": time.perf_counter() - t0,
            "synth_s_median": float(np.median([r["synth_s"] for r in recs])),
            "analyze_s_median": float(np.median([r["analyze_s"] for r in recs])),
            **summarise(recs), "actual_errors": actual_errors(recs)}
    print(json.dumps(out))


def simulate(args):
    recs = _load(args.cache, True)
    rng = np.random.default_rng(args.seed)
    pool = _pool(recs)
    t0 = time.perf_counter()
    out = {"kind": "simulated from the full-pipeline errors", "pool_experiments": len(recs),
           "pool_cells": {"/".join(f"{f:g}" for f in k): len(v) for k, v in pool.items()},
           "coverage": coverage_sim(rng, pool, recs[0], args.experiments),
           "coverage_errors_centred": coverage_sim(rng, _corrected(pool, True, False), recs[0], args.experiments),
           "coverage_errors_centred_sd_matched": coverage_sim(rng, _corrected(pool, True, True), recs[0],
                                                              args.experiments),
           "power_reps": args.reps, "power": [row for rho in args.rho
                                              for row in power(rng, pool, recs[0]["populations"], args.reps, rho)]}
    out["wall_s"] = time.perf_counter() - t0
    print(json.dumps(out))


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    f = sub.add_parser("full")
    f.add_argument("seeds", nargs="+", type=int)
    f.add_argument("--no-errors", action="store_true")
    f.add_argument("--cache", required=True)
    s = sub.add_parser("simulate")
    s.add_argument("--cache", required=True)
    s.add_argument("--experiments", type=int, default=200)
    s.add_argument("--reps", type=int, default=400)
    s.add_argument("--seed", type=int, default=0)
    s.add_argument("--rho", type=float, nargs="+", default=[1.0, 0.7],
                   help="within-cell correlations of the power table (1: the synth's cells)")
    r = sub.add_parser("rescore")
    r.add_argument("--cache", required=True)
    args = p.parse_args()
    {"full": full, "simulate": simulate, "rescore": rescore}[args.cmd](args)


if __name__ == "__main__":
    main()
