"""Synthetic experiments simulated in time (SPEC 6, 10 and 12): the whole protocol per cell.

Each cell is drawn as in `analysis.afm.synth.cells` (diameter, V, γ_a, K_B,1, the population
draw z, the height step and mean heights, blebbing, spring constant; the published design of
frequencies) with exponents (β_B, β_S) as in `analysis.afm.synth.rheology` (the medians plus
0.03 ε, clipped to [0, 0.6]). Its cortex relaxes as a power law,

    K_B(t) = K_B,1 (t/1 s)^-β_B e^{-t/τ_c},   K_S(t) = K̃_S,1 K_B,1 (t/1 s)^-β_S e^{-t/τ_c},

with K̃_S,1 = exp(μ_1 + σ_1 z) and the memory τ_c (`memory_s`, one for both moduli; inf: the pure
power law), written as Prony series (`solver.time_domain.power_law_cortex`); its moduli at f are the
series' K(iω) = |K*| e^{iδ} (about K(1 s) Γ(1-β) (2πf)^β, δ = β π/2), which the truth holds.
The cell's protocol (`solver.protocol.Protocol.stepped`) starts at the relaxed droplet one step
above the first mean height: every height's ramp (`ramp_speed_um_per_s`, 0.2 µm/s as
published), a hold of T_w (`hold` "height", or "force": the force the ramp reached held while
the plate creeps), then its frequencies one after another (5 periods, 2 at 0.02 Hz); it is
simulated by `solver.protocol_simulation.simulate` (the time-domain shell, the fast solver's
mesh and Newton iteration, one equilibrium per step, at its FINE resolution), oscillations
sampled at 100 Hz, ramps and holds at 1 Hz, and stored with every ramp and hold as one approach
segment (`analysis.afm.synth.time_domain.segments_of`). `history` "carried" (the default) keeps
one cortex history through every height; "relaxed" starts each height from its own relaxed
droplet one cell step above it.
Bending stays elastic with B of K_B(1 s), K_S(1 s) for the chosen variant. A blebbing cell's
jump of γ_a adds Δγ_a 2 H A_c(h) to the force; then the measurement errors of `cells.ERRORS`.

The simulations are independent per cell: `jobs` processes run them (the draws are made first,
in order, so the experiment does not depend on `jobs`). A cell whose simulation fails (no
equilibrium even in halved steps) is left out and named in truth.json's
`time_domain.failed_cells`; if every cell fails, a SolverError says so. truth.json's
`time_domain.memory_s` is τ_c in s, null for inf.
"""

import sys
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from analysis.afm.cell import Cell
from analysis.afm.synth import cells as sy
from analysis.afm.synth.rheology import describe, draw_exponents
from analysis.afm.synth.time_domain import segments_of
from analysis.afm.timeseries import shape_of
from common.errors import SolverError
from common.pool import pool
from solver.elasticity import poisson_of_ratio
from solver.model import Shell
from solver.protocol import Protocol
from solver.protocol_simulation import Recording, Sampling, simulate
from solver.time_domain import Cortex, power_law_cortex

SAMPLING = Sampling(sample_hz=sy.RATE_HZ, approach_hz=sy.APPROACH_RATE_HZ)


@dataclass(frozen=True)
class Job:
    """One cell's simulation: its shell (reference droplet), cortex, protocol and history."""

    shell: Shell
    cortex: Cortex
    protocol: Protocol
    history: str


def _simulate(job: Job) -> tuple[Recording | str, float]:
    """The cell's recording, or why its simulation failed, and the wall time (s)."""
    start = time.perf_counter()
    try:
        rec: Recording | str = simulate(job.shell, job.cortex, job.protocol, sampling=SAMPLING, history=job.history)
    except SolverError as e:
        rec = str(e)
    return rec, time.perf_counter() - start


def _draw(i: int, freqs: tuple[float, ...], rng: np.random.Generator, exp_rng: np.random.Generator,
          medians: tuple[float, float], wait_s: float, bending: str, history: str, hold: str,
          ramp_speed_um_per_s: float, memory_s: float) -> tuple[dict[str, Any], dict[str, Any], Job]:
    """The cell's parameters, truth and simulation."""
    p, truth = sy.parameters(i, rng)
    beta = draw_exponents(exp_rng, medians)
    mu, sigma = sy.POPULATIONS[1.0]
    bulk1, shear1 = p["bulk1"], float(np.exp(mu + sigma * p["z"])) * p["bulk1"]
    cortex = power_law_cortex(bulk1, shear1, float(beta[0]), float(beta[1]), memory_s=memory_s)
    truth.update(bulk_exponent=float(beta[0]), shear_exponent=float(beta[1]), wait_s=wait_s,
                 bulk_1s_mN_per_m=bulk1, shear_1s_mN_per_m=shear1)
    for f in freqs:
        truth["frequencies"][f] = _moduli_at(cortex, f)
    shell = Shell(volume_um3=p["V"], h0_um=float(p["h_means"][0] + p["step"]), bulk_mN_per_m=bulk1,
                  shear_mN_per_m=shear1, tension_mN_per_m=p["tension"], bending=bending)
    protocol = Protocol.stepped(shell.h0_um, tuple(map(float, p["h_means"])), freqs,
                                tuple(sy.periods(f) for f in freqs), wait_s=wait_s, amplitude_um=sy.AMPLITUDE_UM,
                                speed_um_per_s=ramp_speed_um_per_s, hold=hold)
    return p, truth, Job(shell, cortex, protocol, history)


def _moduli_at(cortex: Cortex, f: float) -> dict[str, Any]:
    """The truth at f: the series' K_B*, K_S* (magnitudes, loss angles, parts), K̃_S and ν."""
    Kb, Ks = cortex.bulk.complex_modulus(f), cortex.shear.complex_modulus(f)
    ks = abs(Ks) / abs(Kb)
    return {"nu": float(poisson_of_ratio(ks)), "ks_tilde": float(ks), "bulk_mN_per_m": abs(Kb),
            "shear_mN_per_m": abs(Ks), "bulk_loss_angle_rad": float(np.angle(Kb)),
            "shear_loss_angle_rad": float(np.angle(Ks)), "bulk_complex_mN_per_m": [Kb.real, Kb.imag],
            "shear_complex_mN_per_m": [Ks.real, Ks.imag]}


def _cell(rng: np.random.Generator, p: dict[str, Any], truth: dict[str, Any], rec: Recording,
          errors: bool) -> Cell:
    """The simulated recording with blebbing and the measurement errors."""
    segs = segments_of(rec)
    t, h = rec.time_s, rec.height_um
    gamma_a = sy.active_tension(rng, p, t, truth)
    fpt, _ = shape_of(p["V"], h)
    return sy.measured(rng, p, truth, t, rec.force_nN + (gamma_a - p["tension"]) * fpt, h, segs, errors)


def generate(n_cells: int, seed: int = 0, errors: bool = True, bulk_exponent: float = 0.1,
             shear_exponent: float = 0.3, wait_s: float = 100.0, bending: str = "standard", jobs: int = 1,
             progress: bool = True, history: str = "carried", hold: str = "height",
             ramp_speed_um_per_s: float = sy.SPEED_UM_PER_S,
             memory_s: float = float("inf")) -> tuple[list[Cell], dict[str, Any]]:
    """Return (cells, truth) as `cells.generate` does, the recordings simulated in time; the
    truth's `cost` holds the simulation steps and wall time per cell."""
    from tqdm import tqdm
    rng, exp_rng = np.random.default_rng(seed), np.random.default_rng([seed, 10])
    medians = (float(bulk_exponent), float(shear_exponent))
    drawn = [_draw(i, freqs, rng, exp_rng, medians, float(wait_s), bending, history, hold, float(ramp_speed_um_per_s),
                   float(memory_s))
             for i, freqs in enumerate(f for freqs, n in sy.subset_sizes(n_cells) for f in [freqs] * n)]
    bar = tqdm(total=n_cells, unit="cell", desc="time-domain cells", file=sys.stderr, disable=not progress)
    with pool(jobs) as workers:
        results = []
        for r in workers.map(_simulate, [job for _, _, job in drawn]):
            results.append(r)
            bar.update()
    bar.close()
    cells, truths, cost, failed = [], [], [], {}
    for (p, truth, _), (rec, wall) in zip(drawn, results):
        if isinstance(rec, str):
            failed[truth["cell_id"]] = rec
            continue
        cells.append(_cell(rng, p, truth, rec, errors))
        truths.append(truth)
        recordings = len(rec.oscillations())
        cost.append({"cell_id": truth["cell_id"], "steps": rec.steps, "wall_s": wall, "recordings": recordings})
    if not cells:
        raise SolverError(f"no cell could be simulated: {next(iter(failed.values()))}")
    truth_all = {"seed": seed, "errors": errors, "error_model": sy.ERRORS if errors else None,
                 "time_domain": {"wait_s": float(wait_s), "memory_s": _seconds_or_null(memory_s), "hold": hold,
                                 "ramp_speed_um_per_s": float(ramp_speed_um_per_s),
                                 "bending": bending, "history": history, "jobs": jobs,
                                 "cost": cost, "failed_cells": failed},
                 **sy.summary(truths, n_cells), **describe(medians)}
    return cells, truth_all


def _seconds_or_null(memory_s: float) -> float | None:
    """truth.json's τ_c: the seconds, or null for inf (no turnover; JSON has no infinity)."""
    return None if np.isinf(memory_s) else float(memory_s)
