"""Benchmark: solve the droplet shape for 10,000 (V, h) pairs in one call.

What the analysis does for every sample of every AFM recording. Volumes
uniform in 500-20,000 µm³, h̃ uniform in 0.3-0.999. Target: < 1 s on one core.
`cold_s` includes the one-time inverse table h̃ -> k (built on first use);
`warm_s` is the best of five repeated calls. Prints one JSON object.
"""

import json
import time

import numpy as np

PAIRS = 10_000
TARGET_S = 1.0


def main():
    rng = np.random.default_rng(2024)
    volume = rng.uniform(500.0, 20000.0, PAIRS)
    h_tilde = rng.uniform(0.3, 0.999, PAIRS)

    t0 = time.perf_counter()
    from solver.geometry import droplet, sphere_height
    height = h_tilde * sphere_height(volume)
    droplet(volume, height)
    cold = time.perf_counter() - t0

    warm = []
    for _ in range(5):
        t0 = time.perf_counter()
        d = droplet(volume, height)
        warm.append(time.perf_counter() - t0)
    assert np.all(np.isfinite(d.surface_area_um2))
    print(json.dumps({"benchmark": "geometry.droplet", "pairs": PAIRS,
                      "cold_s": round(cold, 4), "warm_s": round(min(warm), 4),
                      "per_pair_us": round(1e6 * min(warm) / PAIRS, 2),
                      "target_s": TARGET_S, "ok": min(warm) < TARGET_S}))


if __name__ == "__main__":
    main()
