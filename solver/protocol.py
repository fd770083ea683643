"""The AFM protocol: what the plate does, step by step (SPEC 6, 11 and 12).

A protocol starts at `start_um`, the gap at t = `start_s` where the cell is its stress-free
droplet, and runs its steps one after another:

- `Ramp`: the plate moves at `speed_um_per_s` to a gap `to_um`, or until the plate force
  reaches `to_nN`;
- `Hold`: for `duration_s`, at constant height (`kind` "height": the gap stays) or at constant
  force (`kind` "force": the force the hold starts with stays, the plate creeps);
- `Oscillate`: h(t) = h_m + A sin(2π f (t - t_0) + φ) for `periods` periods about the gap h_m
  where it starts (A = `amplitude_um`, φ = `phase_rad`; φ = π presses first).

One type for every protocol the project simulates or reads: the synthetic experiments
(`stepped`: a cell's mean heights, a wait at each and its frequencies), the bias map's single
height, and a recording's own protocol (`analysis.afm.protocol_of`). How a simulated recording
is sampled (`solver.protocol_simulation.Sampling`) and how finely it is simulated
(`solver.protocol_simulation.Resolution`) are not the protocol's.

`ages_s`: for every oscillation the time since the end of the last ramp before it (the age of
the step's stress: the wait, plus the oscillations in between at the same height).
"""

import math
from dataclasses import dataclass

from common.errors import InputError
from common.names import HOLD_KINDS


def _positive(name: str, value: float) -> None:
    if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
        raise InputError(f"{name} must be a finite number > 0 (got {value!r})")


@dataclass(frozen=True)
class Ramp:
    """Move the plate at `speed_um_per_s` to the gap `to_um` (µm) or to the force `to_nN` (nN)."""

    to_um: float | None = None
    to_nN: float | None = None
    speed_um_per_s: float = 0.2

    def __post_init__(self) -> None:
        if (self.to_um is None) == (self.to_nN is None):
            raise InputError("a ramp goes to a height (to_um) or to a force (to_nN), one of them")
        _positive("a ramp's speed_um_per_s", self.speed_um_per_s)
        if self.to_um is not None:
            _positive("a ramp's to_um", self.to_um)
        elif not (isinstance(self.to_nN, (int, float)) and math.isfinite(self.to_nN)):
            raise InputError(f"a ramp's to_nN must be a finite number (got {self.to_nN!r})")


@dataclass(frozen=True)
class Hold:
    """Hold for `duration_s` at constant height (`kind` "height") or constant force ("force")."""

    duration_s: float
    kind: str = "height"

    def __post_init__(self) -> None:
        if self.kind not in HOLD_KINDS:
            raise InputError(f"a hold is at constant {' or '.join(HOLD_KINDS)} (got {self.kind!r})")
        if not (isinstance(self.duration_s, (int, float)) and math.isfinite(self.duration_s)
                and self.duration_s >= 0):
            raise InputError(f"a hold's duration_s must be a finite number >= 0 (got {self.duration_s!r})")


@dataclass(frozen=True)
class Oscillate:
    """`periods` periods of h_m + A sin(2π f (t - t_0) + φ) about the gap h_m where it starts."""

    frequency_hz: float
    amplitude_um: float = 0.25
    periods: int = 5
    phase_rad: float = 0.0

    def __post_init__(self) -> None:
        _positive("an oscillation's frequency_hz", self.frequency_hz)
        _positive("an oscillation's amplitude_um", self.amplitude_um)
        if not (isinstance(self.periods, int) and self.periods >= 1):
            raise InputError(f"an oscillation lasts at least one whole period (got periods={self.periods!r})")
        if not math.isfinite(self.phase_rad):
            raise InputError(f"an oscillation's phase_rad must be finite (got {self.phase_rad!r})")

    @property
    def duration_s(self) -> float:
        return self.periods / self.frequency_hz


Step = Ramp | Hold | Oscillate


@dataclass(frozen=True)
class Protocol:
    """From the stress-free droplet at gap `start_um` (µm) at time `start_s` (s), the `steps`."""

    start_um: float
    steps: tuple[Step, ...]
    start_s: float = 0.0

    def __post_init__(self) -> None:
        _positive("a protocol's start_um", self.start_um)
        if not math.isfinite(self.start_s):
            raise InputError(f"a protocol's start_s must be finite (got {self.start_s!r})")
        if not self.steps or not all(isinstance(s, (Ramp, Hold, Oscillate)) for s in self.steps):
            raise InputError("a protocol is a non-empty list of ramps, holds and oscillations")
        h: float | None = self.start_um
        for s in self.steps:
            if isinstance(s, Ramp):
                h = s.to_um
            elif isinstance(s, Hold) and s.kind == "force":
                h = None
            elif isinstance(s, Oscillate) and h is not None and s.amplitude_um >= h:
                raise InputError(f"the protocol would close the gap: an oscillation of {s.amplitude_um:g} µm "
                                 f"about {h:g} µm")

    def ages_s(self) -> list[float]:
        """Per oscillation the time (s) since the end of the last ramp before it (NaN: none)."""
        out, since = [], math.nan
        for s in self.steps:
            if isinstance(s, Oscillate):
                out.append(since)
            since = 0.0 if isinstance(s, Ramp) else since + self.duration_of(s)
        return out

    @staticmethod
    def duration_of(step: Step) -> float:
        """The step's duration (s) where the protocol fixes it (a ramp's depends on the cell: NaN)."""
        return step.duration_s if isinstance(step, (Hold, Oscillate)) else math.nan

    @classmethod
    def stepped(cls, start_um: float, heights_um: tuple[float, ...], frequencies_hz: tuple[float, ...],
                periods: tuple[int, ...], wait_s: float = 100.0, amplitude_um: float = 0.25,
                speed_um_per_s: float = 0.2, hold: str = "height", phase_rad: float = 0.0) -> "Protocol":
        """A cell's protocol (SPEC 6): per mean height a ramp to it, a hold of `wait_s` (of kind
        `hold`) and one oscillation per frequency with its periods."""
        if not heights_um or not frequencies_hz or len(periods) != len(frequencies_hz):
            raise InputError("a stepped protocol needs mean heights, frequencies and one number of periods each")
        steps: list[Step] = []
        for h in heights_um:
            steps += [Ramp(to_um=float(h), speed_um_per_s=speed_um_per_s), Hold(float(wait_s), hold)]
            steps += [Oscillate(float(f), amplitude_um, int(n), phase_rad) for f, n in zip(frequencies_hz, periods)]
        return cls(float(start_um), tuple(steps))
