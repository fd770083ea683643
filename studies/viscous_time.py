"""The viscous cell's linear response in the time domain: the check of K*(ω).

The same linearised equations as `solver.viscous`, but integrated in time for
a prescribed gap history h(t) = h_m + δh(t) instead of solved at one
frequency. With C = 2·1e-3 η D (the fluid condensed onto the shell, nN·s/µm;
the factor 2 for both halves) and q = (δu, δz_p), δz_p = δh/2:

    C_uu δu' + H_uu δu = -(H_u,zp δz_p + C_u,zp δz_p'),
    δF = -(1/2) (H_zp,u δu + H_zp,zp δz_p + C_zp,u δu' + C_zp,zp δz_p'),

a differential-algebraic system (the pressure and the contact label carry no
damping), integrated by the second-order backward difference formula
(BDF2, its first step backward Euler) with one LU of (3/(2Δt)) C_uu + H_uu.
`periodic_response` gives the frequency-domain answer for the same history
(Fourier superposition of K*(ω)), which the time integration must reproduce.
"""

import numpy as np
import numpy.typing as npt
from scipy.linalg import lu_factor, lu_solve

from common.errors import InputError
from solver.model import check_viscous_inputs
from solver.viscous import NN_PER_PA_UM2, Linearised, shell_response


def _damping(lin: Linearised, viscosity_Pa_s: float) -> npt.NDArray[np.float64]:
    """C = 2·1e-3 η D with its near-null directions (eigenvalues below 1e-9 of the
    largest) made exactly null: a relabelling of the nodes that moves no
    material (nodes sliding along the shell as l changes) has ~1e-9 relative
    damping from round-off and slightly negative stiffness; left in, it would be
    a spurious unstable mode of the time integration; nulled, it is algebraic,
    as it is in the frequency domain."""
    C = 2.0 * NN_PER_PA_UM2 * viscosity_Pa_s * lin.D
    ev, V = np.linalg.eigh(C)
    ev[ev < 1e-9 * ev[-1]] = 0.0
    return (V * ev) @ V.T


def integrate(lin: Linearised, viscosity_Pa_s: float, t: npt.NDArray[np.float64], dh: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """δF(t) (nN) for the gap change δh(t) (µm) sampled at the equally spaced
    times t (s), starting from rest at h_m (δh(t[0]) should be 0)."""
    check_viscous_inputs(viscosity_Pa_s, 1.0)
    t, dh = np.asarray(t, float), np.asarray(dh, float)
    if t.ndim != 1 or len(t) < 3 or t.shape != dh.shape or not np.allclose(np.diff(t), t[1] - t[0]):
        raise InputError("times must be at least 3 equally spaced samples, one δh each")
    n, dt = lin.lag.size, t[1] - t[0]
    H, C = lin.H, _damping(lin, viscosity_Pa_s)
    zp = 0.5 * dh
    q = np.zeros((len(t), n))
    rate = np.zeros((len(t), n))
    zrate = np.gradient(zp, dt, edge_order=2)
    lu1 = lu_factor(C[:n, :n] / dt + H[:n, :n])
    lu2 = lu_factor(1.5 * C[:n, :n] / dt + H[:n, :n])
    for k in range(1, len(t)):
        force = -(H[:n, n] * zp[k] + C[:n, n] * zrate[k])
        if k == 1:                                   # backward Euler
            q[k] = lu_solve(lu1, force + C[:n, :n] @ q[k - 1] / dt)
            rate[k] = (q[k] - q[k - 1]) / dt
        else:                                        # BDF2
            q[k] = lu_solve(lu2, force + C[:n, :n] @ (2.0 * q[k - 1] - 0.5 * q[k - 2]) / dt)
            rate[k] = (1.5 * q[k] - 2.0 * q[k - 1] + 0.5 * q[k - 2]) / dt
    return -0.5 * (q @ H[n, :n] + H[n, n] * zp + rate @ C[n, :n] + C[n, n] * zrate)


def half_cosine(t: npt.NDArray[np.float64], depth_um: float, frequency_hz: float) -> npt.NDArray[np.float64]:
    """SPEC 2's plate motion as a change of gap: δh(t) = -(Δ/2)(1 - cos(2π f t))
    until full compression (f t = 1/2), then held at -Δ (SPEC 2's cos(f t),
    with f read as the oscillation frequency in Hz)."""
    phase = np.minimum(2.0 * np.pi * frequency_hz * np.asarray(t, float), np.pi)
    return -0.5 * depth_um * (1.0 - np.cos(phase))


def periodic_response(lin: Linearised, viscosity_Pa_s: float, t: npt.NDArray[np.float64], dh: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """The frequency-domain answer for a periodic gap history: δF(t) (nN) =
    Σ_k T(ω_k) ĥ_k e^{iω_k t}, with ĥ the discrete Fourier transform of δh over
    the window t (equally spaced, one period) and T(ω) = δF/δh from
    `solver.viscous.shell_response` at every harmonic (T(0) the elastic one)."""
    check_viscous_inputs(viscosity_Pa_s, 1.0)
    t, dh = np.asarray(t, float), np.asarray(dh, float)
    dt = t[1] - t[0]
    spectrum = np.fft.rfft(dh)
    f = np.fft.rfftfreq(len(t), dt)
    transfer = np.array([-shell_response(lin, viscosity_Pa_s, fk)[1] for fk in f])
    return np.fft.irfft(transfer * spectrum, n=len(t))
