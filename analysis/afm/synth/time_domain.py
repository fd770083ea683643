"""A simulated recording in time (`solver.time_protocol`) read as an experiment reads it.

The recording becomes a `Cell` (volume V, one approach segment for the ramp and the wait,
one oscillation segment at f) and the segment fit of SPEC 6 step 2
(`analysis.afm.timeseries.segment_moduli`) gives |K*| (`modulus_mN_per_m`), the loss angle
(`loss_angle_rad`, the phase by which γ_eff leads the droplet area) and the rest of its row.
"""

from typing import Any

from analysis.afm.cell import Cell, Segment
from analysis.afm.timeseries import segment_moduli
from solver.time_protocol import Recording


def recording_cell(recording: Recording, volume_um3: float, cell_id: str = "simulated") -> Cell:
    """The recording as a measured cell with its approach and oscillation segments."""
    osc = recording.oscillation
    segments = [Segment("approach", 0, osc.start),
                Segment("oscillation", osc.start, osc.stop, recording.frequency_hz)]
    return Cell(cell_id=cell_id, volume_um3=float(volume_um3), time_s=recording.time_s,
                force_nN=recording.force_nN, height_um=recording.height_um, segments=segments,
                volume_source="simulation").validate()


def segment_fit(recording: Recording, volume_um3: float) -> dict[str, Any]:
    """The oscillation segment's row of `segment_moduli` (|K*|, loss angle, tension, ...)."""
    return segment_moduli(recording_cell(recording, volume_um3))[0]
