"""A whole cell's AFM protocol in time: several mean heights, one cortex history (SPEC 6 and 12).

From the relaxed droplet at h0 (the stress-free reference, t = 0; one step above the first
mean height) the plate visits the mean heights h_1 > h_2 > ... in turn; at each h_i it

1. ramps from the last gap to h_i at 0.2 µm/s and waits T_w (`solver.time_protocol.approach`);
2. oscillates h(t) = h_i + A sin(2π f (t - t_f)) at each of the cell's frequencies f, one after
   another from the last one's end, n_f periods each (`solver.time_protocol.oscillate`).

With `history` "carried" (the default) one `TimeShell` carries the cortex's history through the
whole recording: every stress is σ(t) = ∫ K(t - t') dε(t') over everything since t = 0, so each
height starts from what the earlier heights left. With "relaxed" every mean height h_i starts
from its own relaxed droplet at h_i + Δh (Δh = h0 - h_1, the cell's first step): a fresh
`TimeShell` of reference h_i + Δh, no stress from the earlier heights (the assumption of the
published relaxed-state reading, SPEC 10); the recording's times run on, and the approach's
samples are read between the relaxed droplet at h_i + Δh (its force) and h_i.

A power-law cortex K_B(t) = K_B,1s (t/1 s)^-β_B, K_S(t) = K_S,1s (t/1 s)^-β_S is written as
Prony series (`power_law_cortex`, `solver.prony.fit_power_law`).

The instrument's samples: every oscillation at `sample_hz` (100 Hz: 10 a period at 10 Hz; the
plate's height exactly, the force splined through the steps); the ramps and waits at `approach_hz`
(linear between steps), as `cortex afm synth` stores them. `stretches` say which samples are
an approach and which an oscillation (and at which f).
"""

from dataclasses import dataclass, field, replace

import numpy as np
import numpy.typing as npt

from common.errors import InputError
from common.names import CORTEX_HISTORIES
from solver.model import Shell
from solver.prony import fit_power_law
from solver.time_domain import Cortex, TimeShell
from solver.time_protocol import Steps, approach, oscillate

Array = npt.NDArray[np.float64]


def power_law_cortex(bulk_1s_mN_per_m: float, shear_1s_mN_per_m: float, bulk_exponent: float,
                     shear_exponent: float, memory_s: float = float("inf"),
                     shear_memory_s: float | None = None) -> Cortex:
    """K_B(t) = K_B,1s (t/1 s)^-β_B e^(-t/τ_c) and K_S(t) = K_S,1s (t/1 s)^-β_S e^(-t/τ_c) as
    Prony series (`solver.prony.fit_power_law`), τ_c = `memory_s` (s; inf: no turnover, the pure
    power law). One τ_c for both moduli by default: the actin network's turnover renews the
    whole material, its bulk and shear response alike; `shear_memory_s` gives K_S its own."""
    shear_memory = memory_s if shear_memory_s is None else shear_memory_s
    return Cortex(fit_power_law(bulk_exponent, bulk_1s_mN_per_m, memory_s=memory_s).prony,
                  fit_power_law(shear_exponent, shear_1s_mN_per_m, memory_s=shear_memory).prony)


@dataclass(frozen=True)
class CellProtocol:
    """The mean heights (µm, decreasing), the frequencies at each (Hz) and the periods of each;
    `history`: "carried" (one cortex history through every height) or "relaxed" (each height
    from its own relaxed droplet one cell step above it; module docstring)."""

    heights_um: tuple[float, ...]
    frequencies_hz: tuple[float, ...]
    cycles: tuple[int, ...]
    wait_s: float = 100.0
    amplitude_um: float = 0.25
    ramp_um_per_s: float = 0.2
    sample_hz: float = 100.0
    approach_hz: float = 1.0
    history: str = "carried"

    def __post_init__(self) -> None:
        if self.history not in CORTEX_HISTORIES:
            raise InputError(f"the cortex history must be one of {', '.join(CORTEX_HISTORIES)} "
                             f"(got {self.history!r})")
        h = np.asarray(self.heights_um, float)
        if h.size < 1 or np.any(~np.isfinite(h)) or np.any(np.diff(h) >= 0) or h[-1] <= self.amplitude_um:
            raise InputError("mean heights must be finite, decreasing and above the oscillation's amplitude")
        if len(self.frequencies_hz) < 1 or len(self.cycles) != len(self.frequencies_hz):
            raise InputError("one number of periods for each of at least one frequency")
        if not all(np.isfinite(f) and f > 0 for f in self.frequencies_hz) or min(self.cycles) < 1:
            raise InputError("frequencies must be > 0 Hz and each oscillation at least one period")
        if not (np.isfinite(self.wait_s) and self.wait_s >= 0):
            raise InputError(f"the wait must be a finite number >= 0 s (got {self.wait_s:g})")
        for name in ("amplitude_um", "ramp_um_per_s", "sample_hz", "approach_hz"):
            if not (np.isfinite(getattr(self, name)) and getattr(self, name) > 0):
                raise InputError(f"{name} must be a finite number > 0 (got {getattr(self, name):g})")


@dataclass(frozen=True)
class Stretch:
    """Samples [start, stop) of a recording: an "approach" (ramp and wait) or an "oscillation" at f."""

    kind: str
    start: int
    stop: int
    frequency_hz: float | None = None


@dataclass
class CellRecording:
    """The instrument's samples of a whole cell and the simulation steps (equilibrium solves)."""

    time_s: Array
    force_nN: Array
    height_um: Array
    stretches: list[Stretch] = field(default_factory=list)
    steps: int = 0


def _sampled(steps: Steps, t_from_s: float, h_from_um: float, f_from_nN: float, rate_hz: float) -> Steps:
    """The approach's samples every 1/rate after t_from, its last at its end (linear between steps)."""
    end = float(steps.time_s[-1])
    t = np.r_[t_from_s + np.arange(1.0, np.ceil((end - t_from_s) * rate_hz - 1e-9)) / rate_hz, end]
    t_sim = np.r_[t_from_s, steps.time_s]
    h: Array = np.asarray(np.interp(t, t_sim, np.r_[h_from_um, steps.height_um]), float)
    f: Array = np.asarray(np.interp(t, t_sim, np.r_[f_from_nN, steps.force_nN]), float)
    return Steps(t, h, f)


def run_cell(shell: Shell, cortex: Cortex, protocol: CellProtocol) -> CellRecording:
    """Simulate `protocol` on the shell (reference droplet at shell.h0_um, above the first mean
    height) with `cortex`: the recording at t = 0 (the reference) and every sample after; with
    `protocol.history` "relaxed" each later height from its own relaxed droplet (module docstring)."""
    p = protocol
    if shell.h0_um <= p.heights_um[0]:
        raise InputError("the reference droplet must stand above the first mean height")
    state = TimeShell(shell, cortex)
    pieces = [Steps(np.zeros(1), np.full(1, shell.h0_um), np.full(1, state.force_nN()))]
    rec = CellRecording(np.empty(0), np.empty(0), np.empty(0))
    n, steps = 1, 0
    for i, h_m in enumerate(p.heights_um):
        t_from = float(pieces[-1].time_s[-1])
        if i and p.history == "relaxed":      # a fresh cortex, relaxed one cell step above h_m
            state = TimeShell(replace(shell, h0_um=h_m + shell.h0_um - p.heights_um[0]), cortex)
            h_from, f_from = state.h_um, state.force_nN()
        else:
            h_from, f_from = float(pieces[-1].height_um[-1]), float(pieces[-1].force_nN[-1])
        app = approach(state, t_from, h_m, p.ramp_um_per_s, p.wait_s, 1.0 / p.sample_hz)
        pieces.append(_sampled(app, t_from, h_from, f_from, p.approach_hz))
        rec.stretches.append(Stretch("approach", n, n + len(pieces[-1].time_s)))
        n, steps = n + len(pieces[-1].time_s), steps + len(app.time_s)
        for f, cycles in zip(p.frequencies_hz, p.cycles):
            osc, k = oscillate(state, float(pieces[-1].time_s[-1]), h_m, f, p.amplitude_um, cycles,
                               1.0 / p.sample_hz)
            pieces.append(osc)
            rec.stretches.append(Stretch("oscillation", n, n + len(osc.time_s), float(f)))
            n, steps = n + len(osc.time_s), steps + k
    rec.time_s, rec.height_um, rec.force_nN = (np.concatenate([getattr(q, a) for q in pieces])
                                               for a in ("time_s", "height_um", "force_nN"))
    rec.steps = steps
    return rec
