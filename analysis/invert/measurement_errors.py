"""The measurement errors behind every interval of a measured cell (SPEC 5, 9).

The cell's volume, from imaging, has a relative SD σ_V = 7.5 %; the height of
the gap, from the cantilever's wedge and the dish reference, an SD σ_h =
0.5 µm; intervals are at the 95 % level. The oscillation analysis
(`analysis.invert.intervals`) and the tension analysis (`analysis.afm.tension.pause`) draw
from the same model; this module imports nothing, so a command that needs
only these numbers loads nothing more.
"""

VOLUME_SD = 0.075            # relative SD of the volume
HEIGHT_SD_UM = 0.5           # SD of the height, µm
LEVEL = 0.95                 # confidence level of the intervals
