"""Held-out cell protocols, none of them a test's: the cases the protocol-aware reading's
replays are checked on (bench/linearised_replay.py) and the correction's one-age study
(studies/correction_age.py). Each: (name, volume µm³, start µm, heights µm, frequencies Hz,
periods, wait s, bending, K_B(1 s), K_S(1 s) mN/m, β_B, β_S, γ_a mN/m)."""

CASES = (
    ("tall-standard", 5200.0, 21.0, (13.0, 12.5, 11.5), (0.2, 2.0, 8.0), (3, 6, 12), 100.0, "standard",
     30.0, 15.0, 0.08, 0.30, 1.2),
    ("short-double", 3500.0, 18.0, (11.0, 10.5, 9.5), (0.5, 5.0), (4, 10), 50.0, "double",
     20.0, 10.0, 0.15, 0.25, 0.8),
    ("stiff-none", 4300.0, 19.0, (12.5, 12.0, 11.0, 10.0), (1.0, 10.0), (5, 10), 150.0, "none",
     40.0, 30.0, 0.12, 0.35, 2.0),
)
