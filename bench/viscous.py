"""Wall times of the viscous-interior solver and its mesh convergence; prints one JSON object.

For the cell of the published check (V = 4300 µm³, h0 = 12 µm, Δh = 0.5 µm,
K_B = 25, K_S = 8.33, γ_a = 1.5 mN/m, standard bending), best of --repeat:

- `prepare_s`: the equilibrium at h_m, its Hessian, the fluid mesh and the
  condensation of the Stokes interior onto the shell (once per cell);
- `solve_s`: one frequency-domain solve K*(ω) (per viscosity and frequency);
- `time_domain_s`: the time-domain check (8 periods, 400 BDF2 steps each);
- `convergence`: K*(η = 1 Pa·s, f = 10 Hz) against the fluid mesh's largest
  element h_max (µm) and the shell resolution, with |K*|/K - 1 and the
  loss angle, and each value's relative distance to the finest.
"""

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from solver import viscous
from solver.model import Shell

sys.path.insert(1, str(Path(__file__).resolve().parents[1]))   # `studies`, beside bench/ (not installed)
from studies import viscous_time  # noqa: E402

SHELL = Shell(volume_um3=4300.0, h0_um=12.0, dh_um=0.5, bulk_mN_per_m=25.0, shear_mN_per_m=8.33,
              tension_mN_per_m=1.5)


def best(fn, repeat):
    walls = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        walls.append(time.perf_counter() - start)
    return min(walls)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    out = {"prepare_s": best(lambda: viscous.prepare(SHELL), args.repeat)}
    lin = viscous.prepare(SHELL)[0]
    out["solve_s"] = best(lambda: viscous.respond(lin, 1.0, 10.0), 10 * args.repeat)
    t = np.arange(8 * 400 + 1) / 4000.0
    dh = 0.05 * np.sin(2 * np.pi * 10.0 * t)
    out["time_domain_s"] = best(lambda: viscous_time.integrate(lin, 1.0, t, dh), args.repeat)
    rows = []
    for resolution, h_max in ((1.0, 1.0), (1.0, 0.5), (1.0, 0.25), (1.5, 0.5), (2.0, 0.5)):
        shell = Shell(**{**SHELL.to_dict(), "resolution": resolution})
        lin, fluid = viscous.prepare(shell, h_max)
        K = viscous.respond(lin, 1.0, 10.0).complex_modulus
        K0 = viscous.respond(lin, 0.0, 10.0).complex_modulus.real
        rows.append({"shell_resolution": resolution, "fluid_h_max_um": h_max,
                     "fluid_unknowns": int(fluid.ub.N + fluid.pb.N), "shell_nodes": int(lin.lag.N + 1),
                     "modulus_mN_per_m": abs(K), "elastic_modulus_mN_per_m": K0,
                     "change": abs(K) / K0 - 1, "loss_angle_rad": float(np.angle(K))})
    for row in rows:
        row["change_vs_finest_fluid"] = row["change"] / rows[2]["change"] - 1
    out["convergence"] = rows
    print(json.dumps(out))


if __name__ == "__main__":
    main()
