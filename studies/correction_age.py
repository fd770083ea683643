"""Whether a segment's protocol correction is a function of one age: the question a table of the
correction (SPEC 10, 12; docs/studies/correction-age.md) rests on.

The protocol-aware reading replays each cell's whole protocol (`analysis.afm.replayed`). A table
would replace the replay by the correction of a canonical history: the plate ramped from the
stress-free droplet at the start straight to the segment's gap h_j at the recorded speed, held,
and oscillated at f_j for the segment's periods, its answer (`solver.protocol_simulation`'s
LINEARISED, halfway through the oscillation) an age a after the ramp ended. Per segment j of a
recorded protocol, with the same cortex and memory τ_c:

    the replay's K*_j and mean force F_j (the linearised replay of the whole protocol),
    the canonical K*(a), F(a) at ages a = a_j × AGE_FACTORS (a_j: the segment's own age since
        its height's ramp ended),
    a*_j: the age at which the canonical F(a) equals F_j (linear in ln a between the ages),
    and at a*_j: |K*(a*)| / |K*_j| - 1 and arg K*(a*) - arg K*_j.

If both stay within the reading's bounds (1 %, 0.005 rad) on every segment, one age per segment
carries what a table needs of the history; a table then also needs a*_j without a replay, here
the Boltzmann estimate: the carried depth D_j = Σ_i Δd_i φ(t_j - t_i) (Δd_i each ramp's depth
step, t_i its middle; φ(t) = t^-β e^-t/τ_c with β the mean of β_B and β_S) equated to the
canonical ramp's, d_j φ(a_B + T_r/2) (T_r its duration), solved for a_B.

    python -m studies.correction_age [--memory-s S ...]    # prints one JSON object
"""

from __future__ import annotations

import argparse
import json
import math

import numpy as np
from scipy.optimize import brentq

from solver.model import Shell
from solver.protocol import Hold, Oscillate, Protocol, Ramp
from solver.protocol_simulation import LINEARISED, simulate
from solver.time_domain import Cortex, power_law_cortex
from studies.held_out import CASES

AGE_FACTORS = (0.1, 0.2, 0.35, 0.6, 1.0, 1.6, 2.5, 4.0, 8.0)
BOUNDS = {"modulus_rel": 0.01, "phase_rad": 0.005}


def _timeline(protocol: Protocol) -> tuple[list[tuple[float, float, float]], list[tuple[float, float, Oscillate]]]:
    """The ramps as (start s, end s, depth step µm) and the oscillations as (the age of their
    middle since their height's ramp ended s, their middle s, the step)."""
    t, h, ramps, oscillations, ended = protocol.start_s, protocol.start_um, [], [], protocol.start_s
    for s in protocol.steps:
        if isinstance(s, Ramp):
            if s.to_um is None:
                raise ValueError("a ramp to a force has no depth step: the study takes ramps to a gap")
            d, end = h - s.to_um, t + abs(h - s.to_um) / s.speed_um_per_s
            ramps.append((t, end, d))
            t, h, ended = end, s.to_um, end
        elif isinstance(s, Hold):
            t += s.duration_s
        else:
            oscillations.append((t + 0.5 * s.duration_s - ended, t + 0.5 * s.duration_s, s))
            t += s.duration_s
    return ramps, oscillations


def _phi(t: float, beta: float, memory_s: float) -> float:
    return t ** -beta * (math.exp(-t / memory_s) if math.isfinite(memory_s) else 1.0)


def boltzmann_age(ramps: list[tuple[float, float, float]], t_mid: float, depth_um: float, speed: float,
                  beta: float, memory_s: float) -> float:
    """a_B (s): the canonical ramp's age carrying the depth the recorded ramps carry at t_mid (module doc)."""
    carried = sum(d * _phi(t_mid - 0.5 * (a + b), beta, memory_s) for a, b, d in ramps if b <= t_mid)
    half = 0.5 * depth_um / speed
    f = lambda a: depth_um * _phi(a + half, beta, memory_s) - carried   # noqa: E731
    return brentq(f, 1e-6, 1e7) if f(1e-6) > 0 > f(1e7) else math.nan


def _answer(shell: Shell, cortex: Cortex, protocol: Protocol) -> list[tuple[complex, float]]:
    rep = simulate(shell, cortex, protocol, LINEARISED)
    return [(a.modulus_mN_per_m, a.force_nN) for a in rep.answers]


def _matched(ages: np.ndarray, canon: list[tuple[complex, float]], force: float) -> float | None:
    """The age at which the canonical force equals `force` (linear in ln a), or None."""
    F = np.array([c[1] for c in canon])
    for k in range(len(ages) - 1):
        if (F[k] - force) * (F[k + 1] - force) <= 0 and F[k] != F[k + 1]:
            w = (force - F[k]) / (F[k + 1] - F[k])
            return float(math.exp(math.log(ages[k]) + w * (math.log(ages[k + 1]) - math.log(ages[k]))))
    return None


def _canonical(start_um: float, gap_um: float, speed: float, osc: Oscillate, age_s: float) -> Protocol:
    """The canonical history: a ramp from the start to the gap, a hold, the oscillation, its middle
    `age_s` after the ramp ended."""
    hold = [Hold(age_s - 0.5 * osc.duration_s)] if age_s > 0.5 * osc.duration_s else []
    return Protocol(start_um, (Ramp(to_um=gap_um, speed_um_per_s=speed), *hold, osc))


def case(spec: tuple, memory_s: float) -> list[dict[str, float | str]]:
    name, volume, start, heights, freqs, periods, wait, bending, kb, ks, bb, bs, tension = spec
    shell = Shell(volume_um3=volume, h0_um=start, bulk_mN_per_m=kb, shear_mN_per_m=ks, tension_mN_per_m=tension,
                  bending=bending)
    cortex = power_law_cortex(kb, ks, bb, bs, memory_s=memory_s)
    protocol = Protocol.stepped(start, heights, freqs, periods, wait_s=wait)
    ramps, oscillations = _timeline(protocol)
    real = _answer(shell, cortex, protocol)
    heights_of = [h for h in heights for _ in freqs]
    speed = next(s.speed_um_per_s for s in protocol.steps if isinstance(s, Ramp))
    rows = []
    for j, ((age, t_mid, osc), (K, F), h) in enumerate(zip(oscillations, real, heights_of)):
        ages = age * np.array(AGE_FACTORS)
        ages = ages[ages > 0.5 * osc.duration_s]
        canon = [_answer(shell, cortex, _canonical(start, h, speed, osc, a))[0] for a in ages]
        found = _matched(ages, canon, F)
        row: dict[str, float | str] = {"case": name, "segment": j, "gap_um": h, "frequency_hz": osc.frequency_hz,
                                       "age_s": age, "force_nN": F}
        a_b = boltzmann_age(ramps, t_mid, start - h, speed, 0.5 * (bb + bs), memory_s)
        row["boltzmann_age_s"] = a_b
        if found is None:
            row["matched"] = "no canonical age gives the replay's force"
        else:
            K_star = _matched_at(ages, canon, found)[0]
            row.update(matched_age_s=found, modulus_rel=abs(K_star) / abs(K) - 1,
                       phase_rad=float(np.angle(K_star) - np.angle(K)))
            if math.isfinite(a_b) and ages[0] <= a_b <= ages[-1]:
                at_b = _matched_at(ages, canon, a_b)
                row.update(boltzmann_modulus_rel=abs(at_b[0]) / abs(K) - 1,
                           boltzmann_phase_rad=float(np.angle(at_b[0]) - np.angle(K)),
                           boltzmann_force_rel=at_b[1] / F - 1)
        rows.append(row)
    return rows


def _matched_at(ages: np.ndarray, canon: list[tuple[complex, float]], age: float) -> tuple[complex, float]:
    """The canonical K* and F at `age` (linear in ln a; `age` within the ages)."""
    x = math.log(age)
    la = np.log(ages)
    K = complex(np.interp(x, la, [c[0].real for c in canon]), np.interp(x, la, [c[0].imag for c in canon]))
    return K, float(np.interp(x, la, [c[1] for c in canon]))


def summary(rows: list[dict[str, float | str]]) -> dict[str, object]:
    def worst(key: str) -> float:
        v = [abs(float(r[key])) for r in rows if key in r]
        return max(v) if v else math.nan
    matched = [r for r in rows if "modulus_rel" in r]
    return {"segments": len(rows), "matched": len(matched),
            "matched_age_modulus_rel_max": worst("modulus_rel"), "matched_age_phase_rad_max": worst("phase_rad"),
            "boltzmann_modulus_rel_max": worst("boltzmann_modulus_rel"),
            "boltzmann_phase_rad_max": worst("boltzmann_phase_rad"),
            "boltzmann_force_rel_max": worst("boltzmann_force_rel"),
            "within_bounds_at_matched_age": bool(matched) and worst("modulus_rel") <= BOUNDS["modulus_rel"]
            and worst("phase_rad") <= BOUNDS["phase_rad"]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--memory-s", type=float, nargs="+", default=[math.inf, 30.0], help="τ_c (s) of the cortex")
    args = ap.parse_args()
    out: dict[str, object] = {"bounds": BOUNDS, "age_factors": AGE_FACTORS}
    for m in args.memory_s:
        rows = [r for spec in CASES for r in case(spec, m)]
        out[f"memory_{m:g}_s"] = {"summary": summary(rows), "segments": rows}
    print(json.dumps(out, indent=1, default=float))


if __name__ == "__main__":
    main()
