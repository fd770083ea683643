"""The measurement errors behind every interval of a measured cell (SPEC 5, 9, 11).

The cell's volume, from imaging, has a relative SD σ_V = 7.5 %; the height of
the gap, from the cantilever's wedge and the dish reference, an SD σ_h =
0.5 µm; intervals are at the 95 % level, from `draws` Monte-Carlo draws of
these errors (seeded). The oscillation analysis (`analysis.invert.intervals`,
`analysis.afm.rheology`) and the tension analysis (`analysis.afm.tension.pause`)
take the same `MeasurementErrors`; this module imports no numerical library, so a
command that needs only these numbers (`cortex --help`) loads nothing more.
"""

from dataclasses import dataclass

from common.errors import InputError

VOLUME_SD = 0.075            # relative SD of the volume
HEIGHT_SD_UM = 0.5           # SD of the height, µm
LEVEL = 0.95                 # confidence level of the intervals
DRAWS = 100                  # Monte-Carlo draws per cell of the oscillation analysis


@dataclass(frozen=True)
class MeasurementErrors:
    """The measurement errors an interval includes (defaults: the published ones) and the
    draws that carry them."""

    volume_rel_sd: float = VOLUME_SD
    height_sd_um: float = HEIGHT_SD_UM
    draws: int = DRAWS
    seed: int = 0

    def check(self) -> "MeasurementErrors":
        """Itself, or InputError (one line) for an impossible error or draw count."""
        if not (0 <= self.volume_rel_sd < 0.5):
            raise InputError(f"--volume-sd must be in [0, 0.5) (got {self.volume_rel_sd:g})")
        if not (0 <= self.height_sd_um < 5):
            raise InputError(f"--height-sd must be in [0, 5) um (got {self.height_sd_um:g})")
        if not (10 <= self.draws <= 100_000):
            raise InputError(f"--draws must be in 10..100000 (got {self.draws})")
        return self
