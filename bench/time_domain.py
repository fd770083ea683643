"""The protocol in time with a power-law cortex (SPEC 12): Prony fits, cost, and the bias of
the segment fits against the relaxed-state frequency-domain model. Prints one JSON object.

- `prony`: per exponent β (0.1-0.4) and elements per decade, the Maxwell elements kept and the
  largest relative error of the fit to (t/1 s)^-β over 0.01-1000 s (`solver.prony`).
- `recordings`: a cell of V = 4300 µm³, γ_a = 1.5 mN/m, K_B(1 s) = 25 mN/m, K_S(1 s) = 8.33 mN/m
  with K(t) ∝ t^-β (β_B, β_S; Prony series, 2 elements a decade), reference droplet at
  h0 = h_m + 0.25 µm with h_m at h̃ = 0.6; the protocol (`solver.protocol`, simulated by
  `solver.protocol_simulation` at its FINE resolution): ramp 0.25 µm at 0.2 µm/s, hold T_w, 5 cycles of 0.5 µm peak to peak at f, 100 Hz (20 samples a period at
  least). Per f: wall time, equilibrium solves, ms per solve; the segment fit's |K*| and loss
  angle; the relaxed-state model (`solver.relaxed_state`: K_sec C with the series' own
  K*(ω) = K(iω)) and the ratios. Bending `none` unless --bending (the time-domain bending is
  elastic, so it would keep a prestress the relaxed model does not have).

    python bench/time_domain.py [--frequencies 0.1,1] [--wait 100] [--bulk-exponent 0.1]
                                [--shear-exponent 0.3] [--bending none]
"""

import argparse
import json
import time

from analysis.afm.synth.time_domain import segment_fit
from solver.geometry import cell_radius
from solver.model import Shell
from solver.prony import fit_power_law
from solver.relaxed_state import relaxed_state
from solver.protocol import Hold, Oscillate, Protocol, Ramp
from solver.protocol_simulation import Sampling, simulate
from solver.time_domain import Cortex

V, TENSION, BULK, SHEAR, H_TILDE = 4300.0, 1.5, 25.0, 8.33, 0.6


def prony_table():
    return [{"exponent": b, "per_decade": n, "elements": fit.elements,
             "max_relative_error": fit.max_relative_error}
            for b in (0.1, 0.2, 0.3, 0.4) for n in (1, 2)
            for fit in [fit_power_law(b, per_decade=n)]]


def recording(shell, cortex, f, wait_s):
    start = time.perf_counter()
    protocol = Protocol(shell.h0_um, (Ramp(to_um=shell.h0_um - 0.25), Hold(wait_s), Oscillate(f)))
    rec = simulate(shell, cortex, protocol, sampling=Sampling(approach_hz=100.0, min_samples_per_period=20))
    wall = time.perf_counter() - start
    fit = segment_fit(rec, V)
    model = relaxed_state(shell, cortex, f)
    K, delta = model["modulus_mN_per_m"], model["loss_angle_rad"]
    return {"frequency_hz": f, "wait_s": wait_s, "wall_s": wall, "solves": rec.steps,
            "ms_per_solve": 1e3 * wall / rec.steps, "samples": len(rec.time_s),
            "modulus_mN_per_m": float(fit["modulus_mN_per_m"]), "loss_angle_rad": fit["loss_angle_rad"],
            "tension_mN_per_m": fit["tension_mN_per_m"], "h_tilde": fit["h_tilde"],
            "model_modulus_mN_per_m": K, "model_loss_angle_rad": delta,
            "bulk_loss_angle_rad": model["bulk_loss_angle_rad"],
            "shear_loss_angle_rad": model["shear_loss_angle_rad"],
            "modulus_ratio": float(fit["modulus_mN_per_m"]) / K, "loss_angle_ratio": fit["loss_angle_rad"] / delta}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--frequencies", default="0.1,1")
    ap.add_argument("--wait", type=float, default=100.0)
    ap.add_argument("--bulk-exponent", type=float, default=0.1)
    ap.add_argument("--shear-exponent", type=float, default=0.3)
    ap.add_argument("--bending", default="none")
    args = ap.parse_args()
    h_m = H_TILDE * 2.0 * float(cell_radius(V))
    shell = Shell(volume_um3=V, h0_um=h_m + 0.25, bulk_mN_per_m=BULK, shear_mN_per_m=SHEAR,
                  tension_mN_per_m=TENSION, bending=args.bending)
    cortex = Cortex(fit_power_law(args.bulk_exponent, BULK).prony, fit_power_law(args.shear_exponent, SHEAR).prony)
    out = {"prony": prony_table(), "bulk_exponent": args.bulk_exponent, "shear_exponent": args.shear_exponent,
           "bending": args.bending, "h_mean_um": h_m,
           "recordings": [recording(shell, cortex, float(f), args.wait) for f in args.frequencies.split(",")]}
    print(json.dumps(out))


if __name__ == "__main__":
    main()
