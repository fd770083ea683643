"""One measured cell: metadata + a time series split into segments.

A cell has an id, its volume V (µm³) and how that was obtained, the cantilever
spring constant (N/m), a date and the oscillation frequencies (Hz); the
recording is time (s), force (nN) and cantilever height (µm), sampled at
(nominally) 100 Hz. Segments are half-open sample ranges [start, stop):
`approach` (a height step and its wait), `pause` and `retract` (kept from
instrument files; the analysis does not use them) or `oscillation` (at one
frequency f around a mean height, with its piezo amplitude in µm where the
file says it: JPK's `modulation` segments). `validate` checks everything the
analysis relies on and raises InputError with one line naming the cell and
what is wrong; a cell without any oscillation is valid (it is imported, and
the analysis lists it with that reason). A cell read from a file keeps where
it came from (`source`) and, from an instrument file, what the file said of
the recording (`recorded`: `formats.recording.Recording.summary`); neither is
written to the experiment file. `dish_known` False: the heights are the
instrument's channel, not gaps from the dish (`formats.reader.ImportOptions.
contact_heights`), and are not checked to be positive. `timed` False: the file
holds no sample times (a NanoScope Analysis export alone, read for its ramp by
`afm tension`: `ImportOptions.untimed_ramps`); time_s is NaN and only approach
and retract segments are allowed.
"""

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from common.errors import InputError

KINDS = ("approach", "pause", "retract", "oscillation")


@dataclass
class Segment:
    kind: str                      # approach | pause | retract | oscillation
    start: int                     # first sample
    stop: int                      # one past the last sample
    frequency_hz: float = float("nan")
    amplitude_um: float = float("nan")   # piezo amplitude of an oscillation, NaN where unknown


@dataclass
class Cell:
    cell_id: str
    volume_um3: float
    time_s: npt.NDArray[np.float64]
    force_nN: npt.NDArray[np.float64]
    height_um: npt.NDArray[np.float64]
    segments: list[Segment] = field(default_factory=list)
    volume_source: str = "imaging"
    spring_constant_N_per_m: float = float("nan")
    date: str = ""
    source: str = ""
    recorded: dict[str, Any] | None = None
    dish_known: bool = True
    timed: bool = True

    @property
    def frequencies_hz(self) -> list[float]:
        return sorted({s.frequency_hz for s in self.segments if s.kind == "oscillation"})

    def oscillations(self, frequency_hz: float | None = None) -> list[Segment]:
        return [s for s in self.segments if s.kind == "oscillation"
                and (frequency_hz is None or s.frequency_hz == frequency_hz)]

    def validate(self, where: str = "") -> "Cell":
        """Raise InputError (one line) if the cell cannot be analysed."""
        at = f"{where}cell '{self.cell_id}'"
        v = self.volume_um3
        if v is None or not np.isfinite(v) or v <= 0:
            raise InputError(f"{at}: volume_um3 missing or not a positive number (got {v!r})")
        n = len(self.time_s)
        for name in ("time_s", "force_nN", "height_um")[0 if self.timed else 1:]:
            a = np.asarray(getattr(self, name))
            if a.ndim != 1 or a.size != n:
                raise InputError(f"{at}: column {name} has {a.size} values, time_s has {n}")
            if not np.issubdtype(a.dtype, np.number) or not np.all(np.isfinite(a)):
                bad = np.flatnonzero(~np.isfinite(a.astype(float)))[0] if np.issubdtype(a.dtype, np.number) else 0
                raise InputError(f"{at}: column {name} has a NaN or infinite value at sample {bad}")
        if n < 2:
            raise InputError(f"{at}: recording has {n} sample(s)")
        dt = np.diff(self.time_s) if self.timed else np.ones(n - 1)
        if not self.timed and any(s.kind not in ("approach", "retract") for s in self.segments):
            raise InputError(f"{at}: a recording without sample times holds only approach and retract segments")
        if np.any(dt <= 0):
            raise InputError(f"{at}: time_s is not increasing at sample {int(np.flatnonzero(dt <= 0)[0]) + 1}")
        if self.dish_known and np.any(self.height_um <= 0):
            raise InputError(f"{at}: height_um must be > 0 (min {np.min(self.height_um):g}); "
                             "heights in m instead of um?")
        for i, s in enumerate(self.segments):
            if s.kind not in KINDS:
                raise InputError(f"{at}: segment {i} has kind {s.kind!r} (expected {', '.join(KINDS)})")
            if not (0 <= s.start < s.stop <= n):
                raise InputError(f"{at}: segment {i} spans samples [{s.start}, {s.stop}) outside 0..{n}")
            if s.kind == "oscillation":
                f = s.frequency_hz
                if not (np.isfinite(f) and f > 0):
                    raise InputError(f"{at}: oscillation segment {i} has frequency {f!r} Hz (must be > 0)")
                span = self.time_s[s.stop - 1] - self.time_s[s.start]
                if span * f < 1.0:
                    raise InputError(f"{at}: oscillation segment {i} lasts {span:.3g} s, shorter than "
                                     f"one period at {f:g} Hz")
        return self
