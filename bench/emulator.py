"""The emulator against the solver (SPEC 9). Prints one JSON object.

`offgrid`: K from the fast solver at random points off the grid (seeded; h̃
0.45-0.82, K̃_S 0.05-5 and γ̃_a 0.01-0.25 uniform in their logarithms, V
3000-6500 µm³, K_B 15-35 mN/m, every bending variant) against the shipped
emulator: the largest and RMS relative error of K.
`dependence`: how much K/K_B moves at fixed (h̃, K̃_S, γ̃_a) when V is 3000 or
6000 instead of 4300 µm³, Δh 0.25 instead of 0.5 µm, K_B 15 or 35 instead of
25 mN/m (relative change of K, at four points across the domain).

    python bench/emulator.py [N_PER_VARIANT]      (default 15)
"""

import json
import sys
import time

import numpy as np


from analysis.calibration.file import load_calibration
from solver.compression import compress
from solver.geometry import cell_radius
from solver.model import Shell

POINTS = [(0.5, 0.3, 0.05), (0.7, 0.3, 0.05), (0.7, 3.0, 0.2), (0.6, 0.07, 0.015)]


def solve(h_tilde, ks, gt, volume=4300.0, dh=0.5, bulk=25.0, bending="standard"):
    """K (mN/m) of the compression whose mean height is h̃."""
    h0 = h_tilde * 2.0 * float(cell_radius(volume)) + dh / 2
    return compress(Shell(volume_um3=volume, h0_um=h0, dh_um=dh, bulk_mN_per_m=bulk, shear_mN_per_m=bulk * ks,
                          tension_mN_per_m=bulk * gt, bending=bending)).to_dict()["modulus_mN_per_m"]


def offgrid(emu, n, rng):
    rows = []
    for bending in ("standard", "double", "none"):
        for _ in range(n):
            h = rng.uniform(0.45, 0.82)
            ks = float(np.exp(rng.uniform(np.log(0.05), np.log(5.0))))
            gt = float(np.exp(rng.uniform(np.log(0.01), np.log(0.25))))
            V, bulk = rng.uniform(3000.0, 6500.0), rng.uniform(15.0, 35.0)
            K = solve(h, ks, gt, V, bulk=bulk, bending=bending)
            K_emu = float(emu.modulus(h, bulk, ks, gt * bulk, V, bending))
            rows.append({"bending": bending, "h_tilde": h, "ks_tilde": ks, "gamma_tilde": gt, "volume_um3": V,
                         "bulk_mN_per_m": bulk, "modulus_mN_per_m": K, "rel_err": K_emu / K - 1})
    err = np.array([r["rel_err"] for r in rows])
    return {"n": len(rows), "max_abs_rel_err": float(np.max(np.abs(err))),
            "rms_rel_err": float(np.sqrt(np.mean(err**2))), "points": rows}


def dependence():
    out = []
    for h, ks, gt in POINTS:
        base = solve(h, ks, gt)
        out.append({"h_tilde": h, "ks_tilde": ks, "gamma_tilde": gt, "k_over_kb": base / 25.0,
                    "V3000_rel": solve(h, ks, gt, volume=3000.0) / base - 1,
                    "V6000_rel": solve(h, ks, gt, volume=6000.0) / base - 1,
                    "dh0.25_rel": solve(h, ks, gt, dh=0.25) / base - 1,
                    "KB15_rel": solve(h, ks, gt, bulk=15.0) / (base / 25.0 * 15.0) - 1,
                    "KB35_rel": solve(h, ks, gt, bulk=35.0) / (base / 25.0 * 35.0) - 1})
    return out


def main():
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 15
    file = load_calibration()
    emu, prov = file.emulator, file.provenance
    start = time.perf_counter()
    out = {"benchmark": "emulator", "offgrid": offgrid(emu, n, np.random.default_rng(13)),
           "dependence": dependence(), "emulator_built": prov.get("built", {})}
    out["wall_s"] = round(time.perf_counter() - start, 1)
    out["target_max_abs_rel_err"] = 0.002
    print(json.dumps(out))


if __name__ == "__main__":
    main()
