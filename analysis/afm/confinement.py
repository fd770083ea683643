"""Whether a recording looks like plate confinement (SPEC 6): one warning line per cell that does not.

The model reads a rounded cell pressed between two plates. A recording whose cantilever and
oscillations are those of tip microrheology, or whose free cell is far from the sphere of its
volume, is read with the wrong geometry. The signs, any one of which warns:

- a spring constant k < SOFT_N_PER_M (a tip cantilever; wedged plates use ~0.1-1 N/m);
- an oscillation amplitude A < SMALL_UM (the recorded piezo amplitude, else half the height's
  range over the segment) or a frequency f > FAST_HZ;
- where the heights are gaps from the dish, a free-cell height h_c far from 2R, R = (3V/4π)^(1/3):
  |h_c / 2R - 1| > FAR. h_c is the height where the force of the first approach first rises
  CONTACT of its range above its first sample, if the approach starts out of contact (its force
  flat, within CONTACT of that range, over its first BASELINE share of samples). FAR = 0.3: a rounded cell sits at most slightly
  flattened (h_c/2R ~0.85-1) and a 15 % volume error moves 2R by 5 %, while a spread adherent
  cell under a tip is at h_c/2R ~0.2-0.5 (or the volume or the dish is not the cell's).
"""

from __future__ import annotations

import math

import numpy as np

from analysis.afm.cell import Cell
from solver.geometry import cell_radius

SOFT_N_PER_M = 0.05   # N/m
SMALL_UM = 0.05       # µm
FAST_HZ = 100.0       # Hz
FAR = 0.3             # relative distance of h_c from 2R
CONTACT = 0.05        # share of the first approach's force range that marks contact
BASELINE = 0.2        # share of the first approach's samples that must be out of contact


def contact_height_um(cell: Cell) -> float:
    """h_c (module docstring); NaN without an approach whose force rises from a flat baseline."""
    first = next((s for s in cell.segments if s.kind == "approach"), None)
    if first is None or first.stop - first.start < 2:
        return math.nan
    f = cell.force_nN[first.start:first.stop]
    rise = f - f[0]
    top = float(np.nanmax(rise))
    if not top > 0 or np.nanmax(np.abs(rise[:max(2, int(BASELINE * rise.size))])) > CONTACT * top:
        return math.nan
    at = int(np.flatnonzero(rise >= CONTACT * top)[0])
    return float(cell.height_um[first.start + at])


def _amplitude_um(cell: Cell) -> float:
    amps = [s.amplitude_um if math.isfinite(s.amplitude_um) else float(np.ptp(cell.height_um[s.start:s.stop])) / 2
            for s in cell.oscillations() if s.stop > s.start]
    return min(amps) if amps else math.nan


def warning(cell: Cell) -> str | None:
    """One line saying why `cell` does not look like plate confinement; None if it does."""
    signs = []
    if cell.spring_constant_N_per_m < SOFT_N_PER_M:
        signs.append(f"spring constant {cell.spring_constant_N_per_m:.3g} N/m < {SOFT_N_PER_M:g}")
    amp, fastest = _amplitude_um(cell), max(cell.frequencies_hz, default=math.nan)
    if amp < SMALL_UM:
        signs.append(f"oscillation amplitude {amp * 1e3:.3g} nm < {SMALL_UM * 1e3:g}")
    if fastest > FAST_HZ:
        signs.append(f"frequency {fastest:g} Hz > {FAST_HZ:g}")
    h_c, d = contact_height_um(cell), 2 * float(cell_radius(cell.volume_um3))
    if cell.dish_known and abs(h_c / d - 1) > FAR:
        signs.append(f"free-cell height {h_c:.3g} µm vs the volume's sphere 2R = {d:.3g} µm (beyond ±{FAR:.0%})")
    if not signs:
        return None
    return f"warning: cell {cell.cell_id} does not look like plate confinement: " + "; ".join(signs)


def warnings(cells: list[Cell]) -> list[str]:
    """The warning lines of `cells`, in their order."""
    return [w for w in map(warning, cells) if w is not None]
