"""Synthetic AFM experiments with known truth (SPEC 6 protocol).

Cells: diameter D ~ U(19, 23) µm (V = π D³/6), active tension γ_a ~ U(0.5, 3)
mN/m, spring constant ~ U(0.3, 0.8) N/m. Subsets as published, scaled to N
cells: 50/85 at 0.1, 1, 10 Hz; 10/85 at all four; 25/85 at 0.02 Hz only.

Frequency dependence (an assumption, stated in the README): power-law
(structural-damping) cortex rheology with exponent β = 0.1:
K_B(f) = K_B(1 Hz) (f / 1 Hz)^β, K_B(1 Hz) = 25 mN/m · lognormal(0, 0.15),
loss angle δ = β π/2 at every frequency. K̃_S(f) = exp(μ_f + σ_f z) with one
z ~ N(0, 1) per cell (a stiff cell is stiff at every frequency), (μ_f, σ_f)
the published populations; K_S = K̃_S K_B(f); true ν = (1 - K̃_S)/(1 + K̃_S).
truth.json also holds the trend slope of ln K̃_S per decade these populations
imply (`true_trend`): the line through the μ_f, and the design-weighted one.

Protocol (`cell_protocol`, a `solver.protocol.Protocol`): from 0.78 D, heights
from h̃ ~ U(0.70, 0.745) down in steps of 0.5 or 1 µm (per cell) to h̃ ≥ 0.49;
each step a ramp at 0.2 µm/s and a hold of U(50, 150) s (one `approach`
segment, stored at 1 Hz; the analysis does not use it), then one `oscillation`
segment per frequency: h(t) = h_m - 0.25 sin(2πft) µm (phase π: pressing
first), 5 periods (2 at 0.02 Hz), 100 Hz sampling. The forces are not
simulated through it: each height is in its relaxed state (below).

Forward model: `forward(V, heights, K_B, K_S, γ_a) -> |K|` at the mean heights
(one solve per cell, frequency and height, not per sample). The default is
the fast solver (`solver_forward`: K of a 0.5 µm compression centred on h_m);
`law_forward(law)` is a stand-in from a calibration law. The recording is
γ_eff(t) = γ_a(t) + |K| (A(h(t + δ/ω)) - A_m)/A_m, F = γ_eff 2 H A_c (h(t)).

Measurement errors (off with errors=False): force noise 0.2 nN (SD, white),
drift ±0.001 nN/s (linear, per cell), recorded height offset N(0, 0.5 µm)
per cell, recorded volume × (1 + N(0, 0.075)). Blebbing cells (8 %, also
without errors): γ_a jumps by a factor U(1.25, 1.6) at a random time.
"""

import typing
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, cast

import numpy as np
import numpy.typing as npt

from analysis.afm.cell import Cell, Segment
from analysis.afm.timeseries import shape_of
from solver.elasticity import poisson_of_ratio
from solver.geometry import cell_radius
from solver.protocol import Hold, Oscillate, Protocol, Ramp, Step

if TYPE_CHECKING:
    from analysis.calibration.law import Law

POPULATIONS = {10.0: (-0.31, 0.92), 1.0: (-0.70, 0.82), 0.1: (-1.03, 0.80), 0.02: (-1.50, 0.80)}
SUBSETS = (((0.1, 1.0, 10.0), 50), ((0.02, 0.1, 1.0, 10.0), 10), ((0.02,), 25))
BETA = 0.1                      # power-law exponent: K_B ∝ f^β, δ = β π/2
BULK_1HZ = 25.0                 # mN/m
RATE_HZ, APPROACH_RATE_HZ = 100.0, 1.0
AMPLITUDE_UM, SPEED_UM_PER_S = 0.25, 0.2
ERRORS = {"force_noise_nN": 0.2, "drift_nN_per_s": 0.001, "height_offset_sd_um": 0.5,
          "volume_rel_sd": 0.075, "bleb_fraction": 0.08}


Forward = Callable[[float, npt.NDArray[np.float64], float, float, float], np.ndarray]
"""forward(V (µm³), mean heights (µm), K_B, K_S, γ_a (mN/m)) -> |K| (mN/m) at each height."""


class ModuliModel(typing.Protocol):
    """A forward model that draws its own moduli (`analysis.afm.synth.rheology.ViscoelasticForward`)."""

    viscoelastic: bool

    def moduli(self, p: dict[str, Any], freqs: tuple[float, ...], truth: dict[str, Any]) -> dict[float, np.ndarray]: ...

    def describe(self) -> dict[str, Any]: ...


def law_forward(law: "Law") -> Forward:
    """Stand-in forward model: K = K_B (1 + α(K̃_S, γ̃_a) exp(h̃/λ)) of a calibration `Law`."""
    def forward(volume: float, heights: npt.NDArray[np.float64], bulk: float, shear: float, tension: float
                ) -> np.ndarray:
        h_tilde = np.asarray(heights) / (2.0 * float(cell_radius(volume)))
        return bulk * (1.0 + law.alpha_of(shear / bulk, tension / bulk) * np.exp(h_tilde / law.lam))
    return forward


def solver_forward(bending: str = "standard", method: str = "fast", dh_um: float = 2 * AMPLITUDE_UM) -> Forward:
    """Forward model from the solver: |K| of a compression h_m + Δh/2 -> h_m - Δh/2."""
    from solver.compression import compress
    from solver.model import Shell

    def forward(volume: float, heights: npt.NDArray[np.float64], bulk: float, shear: float, tension: float
                ) -> np.ndarray:
        return np.array([compress(Shell(volume_um3=float(volume), h0_um=float(h) + dh_um / 2, dh_um=dh_um,
                                        bulk_mN_per_m=float(bulk), shear_mN_per_m=float(shear),
                                        tension_mN_per_m=float(tension), bending=bending), method)
                         .to_dict()["modulus_mN_per_m"] for h in heights])
    return forward


def periods(frequency_hz: float) -> int:
    """Periods of an oscillation segment: 5, 2 below 0.05 Hz (SPEC 6)."""
    return 2 if frequency_hz < 0.05 else 5


def subset_sizes(n_cells: int) -> list[tuple[tuple[float, ...], int]]:
    total = sum(n for _, n in SUBSETS)
    sizes = [round(n_cells * n / total) for _, n in SUBSETS]
    sizes[0] += n_cells - sum(sizes)
    return [(freqs, n) for (freqs, _), n in zip(SUBSETS, sizes)]


def parameters(i: int, rng: np.random.Generator) -> tuple[dict[str, Any], dict[str, Any]]:
    """The cell's drawn truth: diameter D, V = π D³/6, γ_a, K_B at 1 Hz, the
    population draw z, the height step and heights, blebbing, spring constant."""
    D = rng.uniform(19.0, 23.0)
    p = {"D": D, "V": np.pi * D**3 / 6.0, "tension": rng.uniform(0.5, 3.0),
         "bulk1": BULK_1HZ * np.exp(0.15 * rng.standard_normal()), "z": rng.standard_normal()}
    p["step"] = rng.choice([0.5, 1.0])
    p["h_means"] = np.arange(rng.uniform(0.70, 0.745) * D, 0.49 * D, -p["step"])
    p["blebbing"] = rng.random() < ERRORS["bleb_fraction"]
    p["spring"] = rng.uniform(0.3, 0.8)
    truth = {"cell_id": f"cell{i:03d}", "diameter_um": D, "volume_um3": p["V"], "tension_mN_per_m": p["tension"],
             "step_um": p["step"], "blebbing": bool(p["blebbing"]), "frequencies": {}}
    return p, truth


def _moduli(p: dict[str, Any], freqs: tuple[float, ...], forward: Any, truth: dict[str, Any]
            ) -> dict[float, np.ndarray]:
    """K (mN/m) at every mean height per frequency: K_B = K_B(1 Hz) f^β,
    K̃_S from the frequency's population; the truth gets ν, K̃_S and K_B.
    A viscoelastic forward model (`analysis.afm.synth.rheology`) makes its own."""
    if getattr(forward, "viscoelastic", False):
        return forward.moduli(p, freqs, truth)
    K = {}
    for f in freqs:
        bulk = p["bulk1"] * f**BETA
        ks = float(np.exp(POPULATIONS[f][0] + POPULATIONS[f][1] * p["z"]))
        K[f] = forward(p["V"], p["h_means"], bulk, ks * bulk, p["tension"])
        truth["frequencies"][f] = {"nu": float(poisson_of_ratio(ks)), "ks_tilde": ks, "bulk_mN_per_m": bulk}
    return K


def cell_protocol(rng: np.random.Generator, p: dict[str, Any], freqs: tuple[float, ...]) -> Protocol:
    """The cell's protocol (module docstring; the holds drawn from `rng`)."""
    steps: list[Step] = []
    for h_m in p["h_means"]:
        steps += [Ramp(to_um=float(h_m), speed_um_per_s=SPEED_UM_PER_S), Hold(float(rng.uniform(50.0, 150.0)))]
        steps += [Oscillate(f, AMPLITUDE_UM, periods(f), np.pi) for f in freqs]
    return Protocol(float(0.78 * p["D"]), tuple(steps))


def _protocol(protocol: Protocol, p: dict[str, Any], K: dict[float, np.ndarray]
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[Segment]]:
    """The recording's time s, height µm and elastic Δγ (mN/m; NaN on the
    approaches) and its segments: every run of ramps and holds one approach
    (sampled at APPROACH_RATE_HZ from its start), every oscillation at RATE_HZ
    from its start (the area lags by δ = β π/2, or where K is complex by arg K
    per height)."""
    t_chunks, h_chunks, g_chunks, segs, t0, n0 = [], [], [], [], 0.0, 0
    h_prev = h_m = protocol.start_um
    move, held, speed, j = 0.0, 0.0, SPEED_UM_PER_S, -1
    for step in protocol.steps:
        if isinstance(step, Ramp):
            assert step.to_um is not None
            h_prev, h_m, speed, j = h_m, step.to_um, step.speed_um_per_s, j + 1
            move = abs(h_prev - h_m) / speed
            continue
        if isinstance(step, Hold):
            held += step.duration_s
            continue
        if move + held > 0:
            t = t0 + np.arange(0.0, move + held, 1.0 / APPROACH_RATE_HZ)
            h = np.where(t - t0 < move, h_prev + np.sign(h_m - h_prev) * speed * (t - t0), h_m)
            t_chunks.append(t)
            h_chunks.append(h)
            g_chunks.append(np.full(t.size, np.nan))
            segs.append(Segment("approach", n0, n0 + t.size))
            n0, t0, move, held = n0 + t.size, t[-1] + 1.0 / APPROACH_RATE_HZ, 0.0, 0.0
        f, A, phi = step.frequency_hz, step.amplitude_um, step.phase_rad
        s = np.arange(0.0, step.periods / f, 1.0 / RATE_HZ)
        w = 2 * np.pi * f
        delta = float(np.angle(K[f][j])) if np.iscomplexobj(K[f]) else BETA * np.pi / 2
        h = h_m + A * np.sin(w * s + phi)
        fpt, area = shape_of(p["V"], np.r_[h, h_m + A * np.sin(w * s + phi + delta), h_m])
        a_lag, a_mean = area[s.size:2 * s.size], area[-1]
        g_chunks.append(abs(K[f][j]) * (a_lag - a_mean) / a_mean)
        t_chunks.append(t0 + s)
        h_chunks.append(h)
        segs.append(Segment("oscillation", n0, n0 + s.size, f))
        n0, t0 = n0 + s.size, t0 + s[-1] + 1.0 / RATE_HZ
    return np.concatenate(t_chunks), np.concatenate(h_chunks), np.concatenate(g_chunks), segs


def _cell(i: int, freqs: tuple[float, ...], rng: np.random.Generator, forward: Any,
          errors: bool) -> tuple[Cell, dict[str, Any]]:
    p, truth = parameters(i, rng)
    K = _moduli(p, freqs, forward, truth)
    t, h, dg, segs = _protocol(cell_protocol(rng, p, freqs), p, K)
    gamma_a = active_tension(rng, p, t, truth)
    fpt, _ = shape_of(p["V"], h)
    return measured(rng, p, truth, t, (gamma_a + np.nan_to_num(dg)) * fpt, h, segs, errors), truth


def active_tension(rng: np.random.Generator, p: dict[str, Any], t: npt.NDArray[np.float64],
                   truth: dict[str, Any]) -> npt.NDArray[np.float64]:
    """γ_a(t) (mN/m): the cell's, times U(1.25, 1.6) from a time U(0.3, 0.7) t_end on if it blebs."""
    gamma_a = np.full(t.size, p["tension"])
    if p["blebbing"]:
        t_jump = rng.uniform(0.3, 0.7) * t[-1]
        gamma_a[t >= t_jump] *= rng.uniform(1.25, 1.6)
        truth["bleb_time_s"] = float(t_jump)
    return gamma_a


def measured(rng: np.random.Generator, p: dict[str, Any], truth: dict[str, Any], t: npt.NDArray[np.float64],
             force: npt.NDArray[np.float64], h: npt.NDArray[np.float64], segs: list[Segment], errors: bool) -> Cell:
    """The recording as the instrument gives it: with `errors`, force noise and drift, a height
    offset and the volume's error (ERRORS)."""
    V_rec, h_rec = p["V"], h
    if errors:
        force = force + ERRORS["force_noise_nN"] * rng.standard_normal(t.size) \
            + rng.uniform(-1, 1) * ERRORS["drift_nN_per_s"] * t
        h_rec = h + ERRORS["height_offset_sd_um"] * rng.standard_normal()
        V_rec = p["V"] * (1.0 + ERRORS["volume_rel_sd"] * rng.standard_normal())
    return Cell(cell_id=truth["cell_id"], volume_um3=float(V_rec), time_s=t, force_nN=force, height_um=h_rec,
                segments=segs, volume_source="synthetic (confocal-like, "
                                             f"{'with' if errors else 'no'} volume error)",
                spring_constant_N_per_m=float(p["spring"]), date="2026-01-01")


def generate(n_cells: int = 85, seed: int = 0, errors: bool = True, forward: Forward | ModuliModel | None = None
             ) -> tuple[list[Cell], dict[str, Any]]:
    """Return (cells, truth): truth has per frequency the true median ν of the
    non-blebbing cells and every cell's true values."""
    forward = forward or solver_forward()
    rng = np.random.default_rng(seed)
    cells, truths, i = [], [], 0
    for freqs, n in subset_sizes(n_cells):
        for _ in range(n):
            c, t = _cell(i, freqs, rng, forward, errors)
            cells.append(c)
            truths.append(t)
            i += 1
    truth = {"seed": seed, "errors": errors, "error_model": ERRORS if errors else None,
             "beta": BETA, "loss_angle_rad": BETA * np.pi / 2, **summary(truths, n_cells)}
    if getattr(forward, "viscoelastic", False):
        truth.update(cast(ModuliModel, forward).describe())
    return cells, truth


def summary(truths: list[dict[str, Any]], n_cells: int) -> dict[str, Any]:
    """truth.json's populations, per frequency the true median ν of the non-blebbing cells and
    every cell's values, the cells and the true trend."""
    per_f = {}
    for f in POPULATIONS:
        vals = {t["cell_id"]: {**t["frequencies"][f], "blebbing": t["blebbing"]} for t in truths if f in t["frequencies"]}
        ok = [v["nu"] for v in vals.values() if not v["blebbing"]]
        per_f[str(f)] = {"frequency_hz": f, "median_nu_true": float(np.median(ok)) if ok else None,
                         "n_cells": len(vals), "cells": vals}
    return {"populations": {str(k): v for k, v in POPULATIONS.items()}, "frequencies": per_f, "cells": truths,
            **true_trend(n_cells)}


def true_trend(n_cells: int) -> dict[str, float]:
    """The trend slope of ln K̃_S per decade the populations imply: the least-squares line through
    the four (log10 f, μ_f) (the answer's, `analysis.afm.population.mean_trend`; μ_f is not linear
    in log10 f), and the one the design-weighted mixed model of `analysis.afm.population.trend`
    converges to for this design (`pseudo_true_slope`)."""
    from analysis.afm.population.trend import pseudo_true_slope
    x = np.log10(list(POPULATIONS))
    return {"trend_slope_ln_ks_per_decade": float(np.polyfit(x, [m for m, _ in POPULATIONS.values()], 1)[0]),
            "trend_slope_design_weighted_ln_ks_per_decade": pseudo_true_slope(POPULATIONS, subset_sizes(n_cells))}
