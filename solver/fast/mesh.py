"""The fast solver's reference mesh: material points labelled on the droplet at h0.

Material points are labelled by where they sit on the reference droplet at h0
(SPEC section 1; H_d its mean curvature, a0 = R_c(h0), β = 2 H_d a0): the
contact disc (reference radius r0 = a0 η, η ∈ (0, 1]) and the free surface,
labelled by its reference tangent angle ψ0 ∈ [0, π/2] with the closed form

    r0(ψ0) = S (sin ψ0 + sqrt(sin² ψ0 + β²)) / (2 H_d),

and z0(ψ0) a Chebyshev series of the droplet's meridian. S scales the radii so
that the discrete reference mesh encloses exactly V (S - 1 = O(ds²)).

After compression the material with ψ0 < ψ_c lies on the plate too: with
l = log ψ_c as unknown, the nodes of the newly touching strip sit at
ψ0 = ψ_c ζ_j and those of the free part at ψ0 = ψ_c + (π/2 - ψ_c) ξ_j, graded
towards the contact line, where bending acts in a layer of width sqrt(B/γ_a).
`Reference.positions(l)` gives (r0, z0) of every node and their first and
second derivatives in l (needed for the exact Newton matrix):

    ∂ψ0/∂l = ∂²ψ0/∂l² = ψ_c ζ (strip),  ψ_c (1 - ξ) (free part).
"""

from dataclasses import dataclass, replace
from functools import lru_cache

import numpy as np
import numpy.typing as npt
from numpy.polynomial import chebyshev

from solver.frustum import enclosed_volume
from solver.geometry import droplet, meridian
from solver.jit import njit

FIRST = 0.01      # µm, element size at the contact line (resolution 1)
LARGEST = 0.08    # µm, largest element of the free surface
LARGEST_DISC = 0.5   # µm, largest element of the contact disc (evenly stretched)
GROWTH = 1.15     # size ratio of neighbouring elements
NEW = 12          # nodes on the strip of material that rolls onto the plate


@dataclass(frozen=True)
class Reference:
    """The reference droplet at h0 and the mesh labels (cached per shell shape)."""

    a0: float           # R_c(h0), µm
    H: float            # droplet mean curvature H_d, 1/µm
    beta: float         # 2 H_d a0
    eta: np.ndarray     # disc nodes r0 = a0 η, η in (0, 1]
    zeta: np.ndarray    # strip nodes ψ0 = ψ_c ζ, ζ in (0, 1]
    xi: np.ndarray      # free nodes ψ0 = ψ_c + (π/2 - ψ_c) ξ, ξ in (0, 1]
    h0: float
    zcoef: np.ndarray   # Chebyshev series of z0(ψ0) on [0, π/2] (from the mid-plane)
    scale: float = 1.0  # S

    def positions(self, logpsic: float) -> tuple[npt.NDArray[np.float64], ...]:
        """(r0, z0, dr0/dl, dz0/dl, d²r0/dl², d²z0/dl²) of every node, pole first
        (the last call's result is kept: Newton's inner steps keep l)."""
        last = self.__dict__.get("_last")
        if last is not None and last[0] == logpsic:
            return last[1]
        out = label_positions(float(logpsic), *self.arrays())
        object.__setattr__(self, "_last", (logpsic, out))
        return out

    def arrays(self) -> tuple[tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64]], npt.NDArray[np.float64]]:
        """(labels, shape), `label_positions`' description of this mesh:
        labels = (η, ζ, ξ, Chebyshev series of z0), shape = (a0, H_d, β, S, h0)."""
        return (self.eta, self.zeta, self.xi, self.zcoef), np.array([self.a0, self.H, self.beta, self.scale, self.h0])


@njit(cache=True)
def label_positions(logpsic: float, labels: tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64]],
                    shape: npt.NDArray[np.float64]) -> tuple[npt.NDArray[np.float64], ...]:
    """`Reference.positions` compiled: labels = (η, ζ, ξ, Chebyshev series of
    z0), shape = (a0, H_d, β, S, h0). On the free surface, with
    q = sqrt(sin² ψ0 + β²), dr0/dψ0 = r0 cos ψ0 / q and, as dz/dr = -tan ψ0 on
    the droplet, dz0/dψ0 = -(r0/S) sin ψ0 / q; then the chain rule through
    ∂ψ0/∂l = ∂²ψ0/∂l² = dψ (module docstring)."""
    eta, zeta, xi, zcoef = labels
    a0, H, beta, S, h0 = shape[0], shape[1], shape[2], shape[3], shape[4]
    psic = np.exp(logpsic)
    nd, nn = eta.size + 1, zeta.size
    n = nd + nn + xi.size
    out = np.zeros((6, n))
    out[0, 1:nd] = S * a0 * eta
    out[1, :nd] = 0.5 * h0
    for j in range(nn + xi.size):
        if j < nn:
            psi = dpsi = psic * zeta[j]
        else:
            psi = psic + (np.pi / 2 - psic) * xi[j - nn]
            dpsi = psic * (1.0 - xi[j - nn])
        s, c = np.sin(psi), np.cos(psi)
        q = np.sqrt(s * s + beta**2)
        r = S * (s + q) / (2.0 * H)
        r1 = r * c / q
        r2 = r * c * c / q**2 - r * s / q - r * c * c * s / q**3
        z1 = -r * s / (q * S)
        z2 = -(r1 * s + r * c - r * s * s * c / q**2) / (q * S)
        k = nd + j
        out[0, k], out[1, k] = r, 4.0 * psi / np.pi - 1.0     # z0(ψ0)'s argument: z0 below
        out[2, k], out[3, k] = r1 * dpsi, z1 * dpsi
        out[4, k], out[5, k] = r2 * dpsi**2 + r1 * dpsi, z2 * dpsi**2 + z1 * dpsi
    _chebval(out[1, nd:], zcoef)
    return out[0], out[1], out[2], out[3], out[4], out[5]


@njit(cache=True)
def _chebval(x, c):
    """x[k] <- Σ c_i T_i(x[k]) for every k by Clenshaw's recurrence (numpy's
    chebval, compiled), the points advanced together: each step's points are
    independent, so they overlap in the pipeline instead of waiting on one
    point's chain of steps."""
    b1, b2 = np.zeros(x.size), np.zeros(x.size)
    for i in range(c.size - 1, 0, -1):
        for k in range(x.size):
            b1[k], b2[k] = 2.0 * x[k] * b1[k] - b2[k] + c[i], b1[k]
    for k in range(x.size):
        x[k] = x[k] * b1[k] - b2[k] + c[0]


def _ramp(first, largest, total, growth=1.15):
    """Points in (0, total]: steps first·growth^i, capped at `largest`, then
    all scaled by the one factor that makes them end at `total`."""
    n_ramp = max(int(np.ceil(np.log(max(largest / first, 1.0)) / np.log(growth))), 0)
    ramp = first * growth ** np.arange(n_ramp)
    ramp = ramp[np.cumsum(ramp) < total]
    rest = total - ramp.sum()
    steps = np.concatenate([ramp, np.full(int(np.ceil(rest / largest)), rest / np.ceil(rest / largest))])
    pts = np.cumsum(steps)
    return pts * (total / pts[-1])


@lru_cache(maxsize=16)
def _meridian_series(volume, h0):
    """Chebyshev series of the droplet's z0(ψ0) on [0, π/2] (60th degree)."""
    return chebyshev.chebinterpolate(
        lambda x: meridian(volume, h0, np.clip((x + 1.0) * np.pi / 4.0, 0.0, np.pi / 2))[1], 60)


@lru_cache(maxsize=256)
def reference(volume: float, h0: float, resolution: float, layer: float) -> Reference:
    """Reference droplet and graded mesh for `resolution` (1 = default);
    `layer` is the bending layer width sqrt(B/γ_a) (µm).

    Element sizes along the meridian: FIRST µm (or a tenth of the bending
    layer) at the contact line, growing by GROWTH per element up to LARGEST µm
    on the free surface and LARGEST_DISC µm on the contact disc, all divided
    by the resolution. In label space the free surface has
    ds/dψ0 = 1/κ1, from 1/(2 H_d) at the contact line to 1/(2 H_d - 1/R_eq) at
    the equator; the strip has NEW nodes."""
    d = droplet(volume, h0)
    a0, H = float(d.contact_radius_um), float(d.mean_curvature_per_um)
    Req = float(d.equator_radius_um)
    res = float(resolution)
    first = min(layer / 10.0, FIRST) / res
    largest = LARGEST / res
    growth = GROWTH ** (1.0 / res)
    span = np.pi / 2
    xi = _ramp(first * 2.0 * H / span, largest * (2.0 * H - 1.0 / Req) / span, 1.0, growth)
    eta = 1.0 - _ramp(first / a0, LARGEST_DISC / res / a0, 1.0, growth)[::-1]
    eta = np.append(eta[1:], 1.0)
    nn = int(np.ceil(NEW * res))
    zeta = np.linspace(1.0 / nn, 1.0, nn)
    ref = Reference(a0=a0, H=H, beta=2.0 * H * a0, eta=eta, zeta=zeta, xi=xi, h0=h0,
                    zcoef=_meridian_series(volume, h0))
    r, z = ref.positions(np.log(1e-12))[:2]
    return replace(ref, scale=float(np.sqrt(volume / enclosed_volume(r, z))))
