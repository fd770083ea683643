"""What the magnitude-only reading misses (SPEC 10): the bias of the published ν when
δ_B ≠ δ_S. Prints one JSON object.

A cell (V = 4300 µm³, K_B = 25 mN/m, γ_a = 1.5 mN/m, six heights h̃ 0.5-0.75) of true
magnitudes K̃_S = |K_S*|/|K_B*| (ν = (1 - K̃_S)/(1 + K̃_S)) and loss angles (δ_B, δ_S):
its |K*(h̃)| from the complex forward model (emulator × `analysis.calibration.viscoelastic_table`),
inverted by the magnitude-only emulator fit (`analysis.invert.emulator_fit`) as today's
analysis does: ν_mag - ν per (ν, δ_B, δ_S), and Re ν* of the complex Poisson ratio.

    python bench/viscoelastic_bias.py
"""

import json

import numpy as np


from analysis.invert.emulator_fit import invert_curves_emulator
from analysis.calibration.file import load_calibration
from solver.elasticity import shear_ratio

NUS = (0.2, 0.5, 0.7)
ANGLES = ((0.16, 0.16), (0.16, 0.31), (0.16, 0.47), (0.31, 0.16), (0.08, 0.47), (0.31, 0.63))


def main():
    model = load_calibration().viscoelastic
    emu, table = model.emulator, model.table
    h = np.linspace(0.5, 0.75, 6)
    rows = []
    for nu in NUS:
        ks = float(shear_ratio(nu))
        for db, ds in ANGLES:
            K = emu.modulus(h, 25.0, ks, 1.5, 4300.0) * np.exp(table.log_factor(h, ks, 1.5 / 25.0, db, ds, 4300.0))
            fit = invert_curves_emulator(h[None], np.abs(K)[None], 1.5, 4300.0, emu).iloc[0]
            star = (np.exp(1j * db) - ks * np.exp(1j * ds)) / (np.exp(1j * db) + ks * np.exp(1j * ds))
            rows.append({"nu": nu, "bulk_loss_angle_rad": db, "shear_loss_angle_rad": ds,
                         "nu_magnitude_only": float(fit["nu"]), "bias": float(fit["nu"] - nu),
                         "nu_complex_real": float(star.real), "nu_complex_imag": float(star.imag)})
    print(json.dumps({"rows": rows}))


if __name__ == "__main__":
    main()
