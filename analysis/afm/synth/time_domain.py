"""A simulated recording (`solver.protocol_simulation`) read as an experiment reads it.

The recording becomes a `Cell` of volume V (`recording_cell`): every run of ramps and holds one
`approach` segment (a height step and its wait, as the native format stores it), every
oscillation an `oscillation` segment at its f (`segments_of`); the protocol's start, the first
sample, belongs to no segment. The segment fit of SPEC 6 step 2
(`analysis.afm.timeseries.segment_moduli`) gives |K*| (`modulus_mN_per_m`), the loss angle
(`loss_angle_rad`, the phase by which γ_eff leads the droplet area) and the rest of its row.
"""

from typing import Any

import numpy as np

from analysis.afm.cell import Cell, Segment
from analysis.afm.timeseries import segment_moduli
from solver.protocol_simulation import Recording


def segments_of(recording: Recording) -> list[Segment]:
    """The recording's stretches as a cell's segments (module docstring)."""
    out: list[Segment] = []
    for s in recording.stretches:
        if s.kind == "oscillation":
            out.append(Segment("oscillation", s.start, s.stop, float(s.frequency_hz or np.nan)))
        elif out and out[-1].kind == "approach" and out[-1].stop == s.start:
            out[-1].stop = s.stop
        else:
            out.append(Segment("approach", s.start, s.stop))
    return out


def recording_cell(recording: Recording, volume_um3: float, cell_id: str = "simulated") -> Cell:
    """The recording as a measured cell with its approach and oscillation segments."""
    return Cell(cell_id=cell_id, volume_um3=float(volume_um3), time_s=recording.time_s,
                force_nN=recording.force_nN, height_um=recording.height_um, segments=segments_of(recording),
                volume_source="simulation")


def segment_fit(recording: Recording, volume_um3: float) -> dict[str, Any]:
    """The first oscillation segment's row of `segment_moduli` (|K*|, loss angle, tension, ...)."""
    return segment_moduli(recording_cell(recording, volume_um3))[0]
