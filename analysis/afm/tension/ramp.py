"""Cortical tension from an approach ramp onto a free (spherical) cell (SPEC 11).

Data: the ramp's forces F_i (nN) and wedge heights x_i (µm): the height channel
plus the deflection, x = z + F/k - Z (`formats.instruments.wedge_height_um`: the
cantilever's bending subtracted from the piezo travel), falling as the cantilever
descends. With x0 the contact point (where the wedge meets the top of the free
cell of radius R) the deformation is δ_i = max(x0 - x_i, 0), and

    droplet:            F_i = F_b + T g(δ_i),  g = 2 H A_c of the droplet of the cell's
                        volume at gap h = 2R - δ (`solver.droplet_table`): exact for a
                        tension-only cell (held at its value at δ = 1.6 R, h̃ = 0.2, for
                        deeper trial contacts: the window never reaches there);
    small-deformation:  F_i = F_b + T π δ_i (1 + 5 δ_i / (4R))
                        (Cartagena-Rivera et al., Biophys. J. 110:2528, 2016),

with F_b the baseline force (the deflection's offset). For a fixed x0 both are
linear in (F_b, T): least squares in closed form (variable projection), T ≥ 0.
The baseline is level: these are the published readings, and with a free tilt a
tension-only model loses its contact (a contact above the data and a tilt mimic
the small-deformation form's linear term); the shell fits the tilt (`shell_fit`).
x0 minimises the residual sum of squares: a grid of GRID candidates across the
window, then a bounded Brent search between the best candidate's neighbours
(in later rounds and refits, Brent alone within a quarter of the window of the
contact found before).

The fit window (`fit_ramp`): the samples with x in [x0 - d, x0 + d], with
d = min(x0 - min x, cap) the deepest deformation the ramp reaches (at most
`cap`, default R: h̃ ≥ 0.5), so the window holds as much baseline above the
contact as compression below it: the baseline pins F_b and the contact, and
equal spans keep the far baseline's drift out. Start: x0 at the last sample
before the deepest one whose force is within 3σ of the baseline (median of the
first BASELINE_FRACTION of the ramp; σ from its successive differences, robust
to drift); then fit, take the window around the fitted x0, and refit until the
window holds the same samples (at most ROUNDS rounds). A ramp whose force never
rises CONTACT_SIGMAS noise SDs above the baseline has no contact (InputError);
so has a fit with fewer than MIN_BASELINE window samples above the contact
(the ramp starts in contact: no free cell to start from).
"""

from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
from scipy.optimize import minimize_scalar

from solver.droplet_table import DEPTH_MAX, unit_force_per_tension
from common.errors import InputError
from common.names import TENSION_ONLY_RAMP_MODELS

MODELS = TENSION_ONLY_RAMP_MODELS
GRID = 41
ROUNDS = 8
BASELINE_FRACTION = 0.3
CONTACT_SIGMAS = 10.0
MIN_BASELINE = 5
MIN_SAMPLES = 20


def force_per_tension_um(model: str, depth_um: npt.ArrayLike, radius_um: float) -> np.ndarray:
    """F/T (µm; × mN/m gives nN) of `model` at deformations δ (µm, ≤ 0: no contact)
    of a free cell of radius R (µm)."""
    d = np.clip(np.asarray(depth_um, float), 0.0, None)
    if model == "droplet":
        return radius_um * unit_force_per_tension(np.minimum(d / radius_um, DEPTH_MAX))
    if model == "small-deformation":
        return np.pi * d * (1.0 + 5.0 * d / (4.0 * radius_um))
    raise InputError(f"unknown ramp model {model!r} (known: {', '.join(MODELS)})")


@dataclass(frozen=True)
class RampFit:
    """One model fitted on one window: T (mN/m), contact x0 (µm, in the ramp's
    x), baseline F_b (nN), R² on the window, the window [x_lo, x_hi] (µm) and its
    sample mask, and the deepest deformation in it (µm)."""

    model: str
    tension_mN_per_m: float
    contact_um: float
    baseline_nN: float
    r2: float
    window_lo_um: float
    window_hi_um: float
    window: npt.NDArray[np.bool_]
    depth_um: float

    def baseline_at(self, x_um: npt.ArrayLike) -> np.ndarray:
        """The fitted baseline at wedge heights x (µm): level, F_b."""
        return np.full(np.shape(x_um), self.baseline_nN)

    def force_nN(self, x_um: npt.ArrayLike, radius_um: float) -> np.ndarray:
        """The fitted force at wedge heights x (µm)."""
        return self.baseline_nN + self.tension_mN_per_m * force_per_tension_um(
            self.model, self.contact_um - np.asarray(x_um, float), radius_um)


def _sse(x: np.ndarray, f: np.ndarray, x0s: np.ndarray, model: str,
         radius: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(residual sum of squares, T, F_b) of the linear fit at every contact candidate x0s."""
    g = force_per_tension_um(model, x0s[:, None] - x[None, :], radius)
    n = x.size
    fc = f - f.mean()
    gm = g.mean(axis=1)
    var = np.einsum("ij,ij->i", g, g) - n * gm * gm
    cov = g @ fc
    t = np.where((var > 0) & (cov > 0), cov / np.where(var > 0, var, 1.0), 0.0)
    sst = fc @ fc
    return sst - t * cov, t, f.mean() - t * gm


def _fit_window(x: np.ndarray, f: np.ndarray, lo: float, hi: float, model: str, radius: float,
                near: float | None = None) -> tuple[float, float, float, float]:
    """The best contact in [lo, hi] for the samples x, f: (x0, T, F_b, sse); a grid
    of GRID candidates then Brent between the best one's neighbours, or, given
    `near` (a contact found before), Brent alone within a quarter of the window of it."""
    if near is None:
        grid = np.linspace(lo, hi, GRID)
        sse, _, _ = _sse(x, f, grid, model, radius)
        j = int(np.argmin(sse))
        a, b, best = grid[max(j - 1, 0)], grid[min(j + 1, GRID - 1)], (float(grid[j]), float(sse[j]))
    else:
        span = 0.25 * (hi - lo)
        a, b = max(lo, near - span), min(hi, near + span)
        best = (float(near), float(_sse(x, f, np.array([near]), model, radius)[0][0]))
    res = minimize_scalar(lambda c: _sse(x, f, np.array([c]), model, radius)[0][0], bounds=(a, b),
                          method="bounded", options={"xatol": 1e-5 * max(hi - lo, 1e-9)})
    x0 = float(res.x) if res.fun <= best[1] else best[0]
    s, t, fb = _sse(x, f, np.array([x0]), model, radius)
    return x0, float(t[0]), float(fb[0]), float(s[0])


def baseline_noise(force_nN: npt.NDArray[np.float64]) -> tuple[float, float]:
    """(baseline median, noise SD) of the first BASELINE_FRACTION of a ramp."""
    head = np.asarray(force_nN, float)[: max(int(BASELINE_FRACTION * len(force_nN)), 3)]
    sd = 1.4826 * np.median(np.abs(np.diff(head) - np.median(np.diff(head)))) / np.sqrt(2.0)
    return float(np.median(head)), float(max(sd, 1e-12 * max(1.0, abs(np.median(head)))))


def contact_guess(x_um: npt.NDArray[np.float64], force_nN: npt.ArrayLike) -> tuple[float, int]:
    """Where the force leaves the baseline (µm), the index of the deepest sample;
    InputError if the ramp shows no contact."""
    f = np.asarray(force_nN, float)
    if f.size < MIN_SAMPLES:
        raise InputError(f"approach ramp has {f.size} samples (need {MIN_SAMPLES})")
    base, sd = baseline_noise(f)
    smooth = np.median(np.lib.stride_tricks.sliding_window_view(np.pad(f, 2, mode="edge"), 5), axis=1)
    peak = float(np.max(smooth))                # a running median of 5: one spike is no contact
    if peak - base < CONTACT_SIGMAS * sd:
        raise InputError(f"approach ramp without contact: the force rises {peak - base:.3g} nN above its "
                         f"baseline, less than {CONTACT_SIGMAS:g} noise SDs ({CONTACT_SIGMAS * sd:.3g} nN)")
    deepest = int(np.argmin(x_um))
    below = np.flatnonzero(f[: deepest + 1] < base + 3.0 * sd)
    return float(x_um[below[-1]] if below.size else x_um[0]), deepest


def fit_ramp(x_um: npt.ArrayLike, force_nN: npt.ArrayLike, radius_um: float, model: str = "droplet",
             cap_um: float | None = None, start: float | None = None) -> RampFit:
    """T and the contact point of one approach ramp by `model`, on the window of the
    module's rule (deformations up to `cap_um`, default R); `start` a first contact
    point (default `contact_guess`). InputError for a ramp without contact."""
    x, f = np.asarray(x_um, float), np.asarray(force_nN, float)
    guess, _ = contact_guess(x, f)
    x0 = guess if start is None else float(start)
    cap = radius_um if cap_um is None else cap_um
    mask, lo_hi = None, None
    for round_ in range(ROUNDS):
        depth = min(max(x0 - x.min(), 0.0), cap)
        new = (x >= x0 - depth) & (x <= x0 + depth)
        if mask is not None and np.array_equal(new, mask):
            break
        mask = new
        if mask.sum() < MIN_SAMPLES:
            raise InputError(f"approach ramp: {int(mask.sum())} samples within the fit window "
                             f"[{x0 - depth:.4g}, {x0 + depth:.4g}] um (need {MIN_SAMPLES})")
        lo_hi = (x0 - depth, x0 + depth)
        x0, t, fb, sse = _fit_window(x[mask], f[mask], *lo_hi, model, radius_um, near=x0 if round_ else None)
    if t <= 0 or np.sum(x[mask] > x0) < MIN_BASELINE:
        why = "no rise above the baseline" if t <= 0 else "it starts in contact (no baseline before the contact)"
        raise InputError(f"approach ramp without a free-cell contact: {why}")
    return _result(model, f[mask], mask, lo_hi, x0 - x[mask].min(), (x0, t, fb, sse))


def refit(fit: RampFit, x_um: npt.ArrayLike, force_nN: npt.ArrayLike, radius_um: float) -> RampFit:
    """`fit`'s model refitted on its own window for another cell radius (one round:
    the window kept, the contact and T fitted again)."""
    x, f = np.asarray(x_um, float)[fit.window], np.asarray(force_nN, float)[fit.window]
    lo_hi = (fit.window_lo_um, fit.window_hi_um)
    solved = _fit_window(x, f, *lo_hi, fit.model, radius_um, near=fit.contact_um)
    return _result(fit.model, f, fit.window, lo_hi, solved[0] - x.min(), solved)


def _result(model: str, f: np.ndarray, mask: Any, lo_hi: Any, depth: float,
            solved: tuple[float, float, float, float]) -> RampFit:
    """The `RampFit` of a solved window (x0, T, F_b, sse) with forces f in it."""
    x0, t, fb, sse = solved
    sst = float(np.sum((f - f.mean()) ** 2))
    return RampFit(model=model, tension_mN_per_m=t, contact_um=x0, baseline_nN=fb,
                   r2=1.0 - sse / sst if sst > 0 else float("nan"), window_lo_um=lo_hi[0],
                   window_hi_um=lo_hi[1], window=mask, depth_um=float(max(depth, 0.0)))
