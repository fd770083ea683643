"""Synthetic force curves of a tension-only droplet (known truth for `cortex afm
tension`): an approach ramp onto the free cell down to a chosen depth, a pause
there, a retract.

The cell: volume V (µm³, R = R_cell), tension T (mN/m); the dish at Z = 0, so the
gap is the wedge height x. The ramp runs x from 2R + `above_um` down to
2R - δ_max at constant speed (n samples); the force on the plate is
F = F_b + T · 2 H A_c from the exact droplet (`solver.geometry.droplet`, not
the interpolated table the analysis uses) plus white noise of SD `noise_nN`; the
recorded height channel is z = x - F/k (k the spring constant) plus white noise
of SD `height_noise_um`. The pause holds x at the bottom (constant height) for
`pause_n` samples, the retract mirrors the ramp. Times in s at 1 kHz. A
viscoelastic cell's pause: `pause_relaxation_nN(t)` (t in s since the pause
started, e.g. A φ(t) of `relaxation.shape`) is added to the pause's force,
whose relaxed value is then the droplet's.
"""

from collections.abc import Callable

import numpy as np
import numpy.typing as npt

from analysis.afm.formats.recording import RecordedSegment, Recording, segment_times
from solver.geometry import cell_radius, droplet

RATE_HZ = 1000.0


def droplet_force_nN(volume_um3: float, tension_mN_per_m: float, gap_um: npt.ArrayLike) -> np.ndarray:
    """T · 2 H A_c (nN) at gaps h (µm) of the exact droplet; 0 where h ≥ 2R."""
    gap = np.asarray(gap_um, float)
    top = 2.0 * cell_radius(volume_um3)
    g = np.zeros_like(gap)
    touch = gap < top
    if np.any(touch):
        g[touch] = droplet(np.full(int(touch.sum()), float(volume_um3)), gap[touch]).force_per_tension_um
    return tension_mN_per_m * g


def _segment(kind: str, x: np.ndarray, t0: float, volume: float, tension: float, rng: np.random.Generator, *,
             k: float, baseline_nN: float, noise_nN: float, height_noise_um: float,
             extra: Callable[[np.ndarray], np.ndarray] | None = None) -> RecordedSegment:
    force = baseline_nN + droplet_force_nN(volume, tension, x) + noise_nN * rng.standard_normal(x.size)
    if extra is not None:
        force += extra(np.arange(x.size) / RATE_HZ)
    z = x - 1e-3 * force / k + height_noise_um * rng.standard_normal(x.size)
    duration = x.size / RATE_HZ
    return RecordedSegment(kind, duration, segment_times(t0, duration, x.size), force, z)


def droplet_recording(volume_um3: float, tension_mN_per_m: float, depth_um: float, *, cell_id: str = "synthetic",
                      n: int = 1000, pause_n: int = 500, above_um: float = 2.0, spring_N_per_m: float = 0.1,
                      baseline_nN: float = 0.0, noise_nN: float = 0.02, height_noise_um: float = 0.0,
                      seed: int = 0,
                      pause_relaxation_nN: Callable[[np.ndarray], np.ndarray] | None = None) -> Recording:
    """A `Recording` of approach (n samples), constant-height pause and retract on
    a tension-only droplet, compressed by `depth_um` from its free sphere; the
    pause's force relaxing by `pause_relaxation_nN(t)` where given."""
    rng = np.random.default_rng(seed)
    top = 2.0 * float(cell_radius(volume_um3))
    ramp = np.linspace(top + above_um, top - depth_um, n)
    opts = dict(k=spring_N_per_m, baseline_nN=baseline_nN, noise_nN=noise_nN, height_noise_um=height_noise_um)
    segs, t0 = [], 0.0
    for kind, x in (("approach", ramp), ("pause", np.full(pause_n, ramp[-1])), ("retract", ramp[::-1])):
        extra = pause_relaxation_nN if kind == "pause" else None
        segs.append(_segment(kind, x, t0, volume_um3, tension_mN_per_m, rng, extra=extra, **opts))
        t0 += segs[-1].duration_s
    return Recording(cell_id=cell_id, spring_constant_N_per_m=spring_N_per_m, segments=segs,
                     source=f"synthetic droplet V={volume_um3:g} um^3, T={tension_mN_per_m:g} mN/m")


def shell_ramp(radius_um: float, tension_mN_per_m: float, bulk_mN_per_m: float, shear_mN_per_m: float,
               depth_um: float, *, n: int = 2000, solved: int = 45, noise_nN: float = 0.02,
               baseline_nN: float = 0.0, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(x, F) of an approach ramp onto an elastic cell (SPEC 2: the shell stress-free
    as its free sphere) with x = 2R - δ (the dish at 0), δ evenly from -`depth_um`
    to `depth_um` over n samples, plus white noise of SD `noise_nN`. The force is
    solved (`solver.ramp.ramp_forces_nN`, one continuation) at `solved` depths
    evenly to `depth_um` and read between them by a cubic spline in δ through
    F(0) = 0."""
    from scipy.interpolate import CubicSpline

    from solver.ramp import ramp_forces_nN
    knots = np.linspace(0.0, depth_um, solved + 1)
    solved_nN = ramp_forces_nN(4.0 * np.pi * radius_um ** 3 / 3.0, knots[1:], bulk_mN_per_m, shear_mN_per_m,
                               tension_mN_per_m)
    delta = np.linspace(-depth_um, depth_um, n)
    force = np.where(delta > 0, CubicSpline(knots, np.r_[0.0, solved_nN])(np.clip(delta, 0.0, None)), 0.0)
    rng = np.random.default_rng(seed)
    return 2.0 * radius_um - delta, baseline_nN + force + noise_nN * rng.standard_normal(n)
