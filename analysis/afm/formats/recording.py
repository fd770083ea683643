"""One force curve as the instrument recorded it, before it becomes a `Cell`.

Readers of JPK files (text exports, `.jpk-force` archives, one per pixel of
`.jpk-force-map`/`.jpk-qi-data`) and of Bruker NanoScope files (force
curves and their text exports: approach, a pause for a hold, retract)
return `Recording`s: the cantilever's
spring constant k (N/m) and its segments in order, each with its kind
(`approach`, `pause`, `modulation`, `retract`: JPK's styles extend, pause,
modulation, retract), duration (s), sample count, for a modulation its
frequency (Hz) and amplitude (µm), and the samples: time t (s, from the
start of the recording), force F (nN, from the vertical deflection) and the
cantilever's height z (µm, the file's own height channel, falling as the
cantilever approaches the dish).
"""

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from common.errors import InputError

STYLES = {"extend": "approach", "pause": "pause", "modulation": "modulation", "retract": "retract"}
# Height channels in order of preference: the measured (sensor) heights before the piezo's command.
HEIGHT_CHANNELS = ("smoothedMeasuredHeight", "measuredHeight", "strainGaugeHeight", "capacitiveSensorHeight",
                   "height")


def kind_of(style: str | None, where: str) -> str:
    """Our segment kind for a JPK segment style."""
    if style not in STYLES:
        raise InputError(f"{where}: unknown segment style {style!r} (known: {', '.join(STYLES)})")
    return STYLES[style]


@dataclass
class RecordedSegment:
    kind: str
    duration_s: float
    time_s: npt.NDArray[np.floating[Any]]
    force_nN: npt.NDArray[np.floating[Any]]
    height_um: npt.NDArray[np.floating[Any]]
    frequency_hz: float = float("nan")
    amplitude_um: float = float("nan")

    @property
    def n_samples(self) -> int:
        return int(len(self.time_s))

    def summary(self) -> dict[str, Any]:
        osc = self.kind == "modulation"
        return {"kind": self.kind, "duration_s": float(self.duration_s), "n_samples": self.n_samples,
                "frequency_hz": float(self.frequency_hz) if osc else None,
                "amplitude_um": float(self.amplitude_um) if osc else None}


@dataclass
class Recording:
    cell_id: str
    spring_constant_N_per_m: float
    segments: list[RecordedSegment] = field(default_factory=list)
    source: str = ""
    date: str = ""

    def summary(self) -> dict[str, Any]:
        """What `cortex afm import --json` prints for this recording."""
        return {"cell_id": self.cell_id, "spring_constant_N_per_m": float(self.spring_constant_N_per_m),
                "source": self.source, "segments": [s.summary() for s in self.segments]}


def segment_times(start_s: float, duration_s: float, n: int) -> npt.NDArray[np.floating[Any]]:
    """Sample times of a segment of n samples over `duration_s` from `start_s`:
    t_i = start + (i + 1/2) · duration / n (the mid-sample times JPK's own text
    export writes)."""
    return start_s + (np.arange(n) + 0.5) * (duration_s / n if n else 0.0)
