"""The protocol-aware correction of each segment: the cell's own protocol replayed in time with
its fitted cortex, against the relaxed-state model (SPEC 10, 12; docs/viscoelastic.md).

The relaxed-state reading takes every oscillation about the relaxed droplet at its mean height.
A power-law cortex keeps part of the stress of every earlier height step. Given a cell's power
laws (K_B(t) = K_B,1s t^-β_B, K_S(t) = K_S,1s t^-β_S, `analysis.afm.rheology.cortex_laws`) and
γ_a, its recording's protocol (`analysis.afm.recorded_protocol.protocol_of`) is simulated
(`solver.protocol_simulation.simulate`) and read per segment j as K*_td,j and the mean tension
γ_td,j. By default (`linearised`) at the LINEARISED resolution: every hold one exact Prony step,
every oscillation answered about the replayed state halfway through it (K*_td,j = K*_lin of
`solver.state_response`, γ_td,j = F_0 / (2 H A_c) at h_m); else (`linearised=False`, the full
replay: the reading's last correction, `analysis.afm.protocol_reading`, and the held-out check
of bench/linearised_replay.py) at the REPLAY resolution, read as the recording is read
(`analysis.afm.timeseries.segment_moduli`). The relaxed-state model gives
K*_r,j (`solver.relaxed_state`) and γ_a. Then

    c_j = K*_td,j / K*_r,j,   Δγ_j = γ_td,j - γ_a,

and the segment as the relaxed-state reading should see it is K*_j / c_j with mean tension
<γ_eff>_j - Δγ_j (`correct`; the factors in `CORRECTION_COLUMNS`).

The cortex forgets with the memory τ_c (K(t) ∝ t^-β e^(-t/τ_c); inf: the pure power law; 0: it
keeps nothing, the relaxed-state reading), or keeps only its last step (RELAXED: the history
relaxed at every height); `analysis.afm.memory_fit` decides which from the recording. K*_r is the
pure power law's whatever the memory: c then also maps a turnover's bend of K*(f) back onto the
power law the reading fits. With a wait S (`afm analyze --wait-s S`) every height's wait is S (`protocol_of`); a cell
whose protocol is not recorded is not corrected.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import numpy as np
import pandas as pd

from analysis.afm.cell import Cell
from analysis.afm.memory_fit import RELAXED, Node
from analysis.afm.recorded_protocol import read_protocol
from analysis.afm.synth.time_domain import recording_cell
from analysis.afm.timeseries import segment_moduli
from analysis.afm.wait_relaxation import Waits, modelled, recorded
from common.errors import InputError, SolverError
from solver.model import Shell
from solver.protocol import Oscillate, Protocol
from solver.geometry import droplet
from solver.protocol_simulation import LINEARISED, REPLAY, Recording, simulate
from solver.relaxed_state import relaxed_state
from solver.time_domain import Cortex, power_law_cortex

CORRECTION_COLUMNS = ("protocol_modulus_factor", "protocol_phase_rad", "protocol_tension_shift_mN_per_m")


def replayed_segments(cell: Cell, rep: Recording) -> list[dict[str, Any]]:
    """`segment_moduli` of the replay, read as a recording of the cell's volume."""
    return segment_moduli(recording_cell(rep, cell.volume_um3, cell.cell_id))


def answered_segments(cell: Cell, rep: Recording) -> list[dict[str, Any]]:
    """The linearised replay's answers as `segment_moduli`'s |K*|, loss angle and mean tension
    γ_td = F_0 / (2 H A_c) (the droplet of the cell's volume at h_m)."""
    g = droplet(cell.volume_um3, np.array([a.h_mean_um for a in rep.answers])).force_per_tension_um
    return [{"modulus_mN_per_m": abs(a.modulus_mN_per_m), "loss_angle_rad": float(np.angle(a.modulus_mN_per_m)),
             "tension_mN_per_m": a.force_nN / float(gk)} for a, gk in zip(rep.answers, np.atleast_1d(g))]


def cell_replays(cell: Cell, law: dict[str, float], bending: str, wait_s: float | None = None,
                 linearised: bool = True, memories: Sequence[Node] = (math.inf,)
                 ) -> tuple[dict[Node, np.ndarray | str], Waits | None]:
    """Per memory of `memories` (τ_c in s, or RELAXED: the history relaxed at every height) the
    (segments, 3) |c|, arg c and Δγ (mN/m) per oscillation of `cell` with the power laws `law` (a
    row of `cortex_laws`), by the linearised replay or the full one (module docstring); τ_c = 0:
    nothing kept, c = 1 and Δγ = 0 without a replay. Where the protocol is not recorded or the
    replay finds no equilibrium, why (the segments stay as recorded). K*_r is the pure power law's
    at every memory, so c also undoes the bend a finite τ_c gives K*(f); it is computed once.
    Beside them the cell's recorded waits with each replay's force there
    (`analysis.afm.wait_relaxation`; τ_c = 0: the force constant in a wait; None: no wait reads
    the memory, or the waits are not the recording's, `wait_s` given)."""
    protocol = read_protocol(cell, wait_s)
    if isinstance(protocol, str):
        return {m: f"protocol not recorded: {protocol}" for m in memories}, None
    shell = Shell(volume_um3=cell.volume_um3, h0_um=protocol.start_um, bulk_mN_per_m=law["bulk_1s"],
                  shear_mN_per_m=law["shear_1s"], tension_mN_per_m=law["tension"], bending=bending)
    power_law = power_law_cortex(law["bulk_1s"], law["shear_1s"], law["bulk_beta"], law["shear_beta"])
    reference: list[complex] = []
    out: dict[Node, np.ndarray | str] = {}
    waits: dict[Node, list[tuple[np.ndarray, np.ndarray]]] = {}
    for m in memories:
        if m == 0:
            out[m] = np.tile([1.0, 0.0, 0.0], (len(cell.oscillations()), 1))
            continue
        found = _replayed(cell, law, shell, protocol, m, linearised)
        if isinstance(found, str):
            out[m] = found
            continue
        rows, waits[m] = found
        reference = reference or _references(cell, shell, power_law, protocol)
        K = np.array([r["modulus_mN_per_m"] * np.exp(1j * r["loss_angle_rad"]) for r in rows]) / np.array(reference)
        out[m] = np.column_stack([np.abs(K), np.angle(K), [r["tension_mN_per_m"] - law["tension"] for r in rows]])
    return out, (_waits(cell, waits, 0 in memories) if wait_s is None else None)


def _waits(cell: Cell, steps: dict[Node, list[tuple[np.ndarray, np.ndarray]]], nothing_kept: bool) -> Waits | None:
    """The recorded waits of `cell` and each replay's force in them (`steps`: per memory its
    replay's waits); τ_c = 0 (`nothing_kept`): the relaxed state's force, constant in each wait."""
    if not steps:
        return None
    waits = recorded(cell, next(iter(steps.values())))
    if waits is None:
        return None
    model = {m: modelled(waits, s) for m, s in steps.items()}
    if nothing_kept:
        model[0.0] = np.zeros(waits.time_s.size)
    return replace(waits, model=model)


def cell_correction(cell: Cell, law: dict[str, float], bending: str, wait_s: float | None = None,
                    linearised: bool = True, memory: Node = math.inf) -> np.ndarray | str:
    """`cell_replays`' factors at one memory."""
    return cell_replays(cell, law, bending, wait_s, linearised, (memory,))[0][memory]


def _replayed(cell: Cell, law: dict[str, float], shell: Shell, protocol: Protocol, memory: Node,
              linearised: bool) -> tuple[list[dict[str, Any]], list[tuple[np.ndarray, np.ndarray]]] | str:
    """The replay's segments (|K*|, loss angle, mean tension) and waits at one memory, or why none."""
    tau = math.inf if memory == RELAXED else float(memory)
    cortex = power_law_cortex(law["bulk_1s"], law["shear_1s"], law["bulk_beta"], law["shear_beta"], memory_s=tau)
    try:
        rep = simulate(shell, cortex, protocol, LINEARISED if linearised else REPLAY,
                       history="relaxed" if memory == RELAXED else "carried")
        return (answered_segments(cell, rep) if linearised else replayed_segments(cell, rep)), rep.waits
    except SolverError as e:
        return f"the replay found no equilibrium ({e})"
    except InputError as e:            # a relaxed history needs a first ramp down from the start
        return f"the replay cannot relax its history ({e})"


def _references(cell: Cell, shell: Shell, cortex: Cortex, protocol: Protocol) -> list[complex]:
    """K*_r (mN/m) of the relaxed-state model with `cortex` per oscillation: at its recorded mean
    height and frequency."""
    oscillations = [s for s in protocol.steps if isinstance(s, Oscillate)]
    return [_relaxed(shell, cortex, float(cell.height_um[seg.start:seg.stop].mean()), osc)
            for osc, seg in zip(oscillations, cell.oscillations())]


def _relaxed(shell: Shell, cortex: Cortex, mean_um: float, osc: Oscillate) -> complex:
    """K*_r (mN/m) of the relaxed-state model at the mean height and the oscillation's f."""
    A = osc.amplitude_um
    r = relaxed_state(Shell(volume_um3=shell.volume_um3, h0_um=mean_um + A, dh_um=2 * A, bulk_mN_per_m=1.0,
                            shear_mN_per_m=1.0, tension_mN_per_m=shell.tension_mN_per_m, bending=shell.bending),
                      cortex, osc.frequency_hz, sparse=True)
    return complex(r["modulus_mN_per_m"] * np.exp(1j * r["loss_angle_rad"]))


def apply(segments: pd.DataFrame, factors: np.ndarray) -> pd.DataFrame:
    """`segments` divided by c and less Δγ (`factors`: (rows, 3) in the segments' order; NaN
    rows: not corrected), with the factors in CORRECTION_COLUMNS."""
    factors = np.where(np.isnan(factors), [1.0, 0.0, 0.0], factors)
    out = segments.copy()
    out["modulus_mN_per_m"] = segments["modulus_mN_per_m"].to_numpy(float) / factors[:, 0]
    out["loss_angle_rad"] = segments["loss_angle_rad"].to_numpy(float) - factors[:, 1]
    out["tension_mN_per_m"] = segments["tension_mN_per_m"].to_numpy(float) - factors[:, 2]
    for k, name in enumerate(CORRECTION_COLUMNS):
        out[name] = factors[:, k]
    return out
