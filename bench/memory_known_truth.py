"""Known truth for the cortex's memory read from the data (`afm analyze`'s default): time-domain
synthetic experiments made with a known τ_c (or with the history relaxed at every height), each
read by default, against their truth. Prints one JSON list, one object per experiment:

- `memory_true_s` (null: ∞; "relaxed history": every height from its own relaxed droplet);
- `bulk`, `shear`: `bench/time_domain_synth.py`'s exponents (medians against the truth's, the
  share of cells whose 95 % interval holds the true exponent) and the median and largest widening
  of their intervals by the correction's feedback (`rheology.csv`);
- `memory`: per source (fitted, pooled, assumed) the cells; over the cells whose memory was
  identified (fitted), the share whose 95 % interval holds the true τ_c, and the median estimate;
  the pooled memory and its interval;
- `cells_corrected`, `cells_not_settled`, `replays_per_cell` (linearised: rounds and the closing
  ones), `memory_replays_per_cell` (the linearised replays at one memory they made) and
  `full_replays_per_cell` (summary.json's `protocol`).

The reading's CPU is the caller's to measure (`/usr/bin/time`).

    cortex afm synth --time-domain --cells 40 --seed 0 --memory-s 10 --out EXP10     # also 100, inf,
    cortex afm synth --time-domain --cells 40 --seed 0 --history relaxed --out EXPR  # and relaxed
    cortex afm analyze EXP10 --out A10                                              # by default
    python bench/memory_known_truth.py EXP10 A10 [EXP100 A100 ...]
"""

import json
import math
import sys
from pathlib import Path

import pandas as pd

sys.path.insert(0, str(Path(__file__).parent))
from time_domain_synth import exponents  # noqa: E402


def _seconds(value: float) -> float | None:
    return None if math.isinf(value) else float(value)


def memory(truth_s: float, cells: pd.DataFrame) -> dict:
    """The memory read per cell against the truth τ_c `truth_s` (NaN: none, a relaxed history)."""
    per_cell = cells.groupby("cell_id")[["protocol_memory_s", "protocol_memory_lo95_s", "protocol_memory_hi95_s",
                                         "protocol_memory_source"]].first()
    out: dict = {f"cells_{k}": int((per_cell["protocol_memory_source"] == k).sum())
                 for k in ("fitted", "pooled", "assumed")}
    fitted = per_cell[per_cell["protocol_memory_source"] == "fitted"]
    pooled = per_cell[per_cell["protocol_memory_source"] == "pooled"]
    if len(pooled):
        first = pooled.iloc[0]
        out["pooled_s"] = [_seconds(first[k]) for k in ("protocol_memory_lo95_s", "protocol_memory_s",
                                                         "protocol_memory_hi95_s")]
    if len(fitted):
        out["fitted_median_s"] = _seconds(float(fitted["protocol_memory_s"].median()))
        out["fitted_quartiles_s"] = [_seconds(float(fitted["protocol_memory_s"].quantile(q))) for q in (0.25, 0.75)]
        held = (fitted["protocol_memory_lo95_s"] <= truth_s) & (truth_s <= fitted["protocol_memory_hi95_s"])
        out["fitted_interval_coverage"] = None if math.isnan(truth_s) else float(held.mean())
    return out


def one(exp: Path, analysis: Path) -> dict:
    truth = json.loads((exp / "truth.json").read_text())
    td = truth["time_domain"]
    relaxed = td.get("history") == "relaxed"
    out = {"experiment": str(exp), "memory_true_s": "relaxed history" if relaxed else td.get("memory_s"),
           "wait_s": td["wait_s"], **exponents(truth, rheology := pd.read_csv(analysis / "rheology.csv"))}
    for name in ("bulk", "shear"):
        column = f"{name}_exponent_widening"
        if column in rheology:
            widening = rheology.loc[rheology[f"{name}_exponent"].notna(), column]
            out[name]["widening_median"], out[name]["widening_max"] = float(widening.median()), float(widening.max())
    segments = pd.read_csv(analysis / "segments.csv")
    given = td.get("memory_s")
    out["memory"] = memory(math.nan if relaxed else math.inf if given is None else float(given), segments)
    said = json.loads((analysis / "summary.json").read_text()).get("protocol", {})
    out["cells_corrected"], out["replays_per_cell"] = said.get("cells_corrected"), said.get("replays_per_cell")
    out["memory_replays_per_cell"] = said.get("memory_replays_per_cell")
    out["full_replays_per_cell"] = said.get("full_replays_per_cell")
    out["cells_not_settled"] = len(said.get("cells_not_settled", []))
    return out


def main() -> None:
    args = sys.argv[1:]
    if len(args) % 2:
        sys.exit("usage: memory_known_truth.py EXP ANALYSIS [EXP ANALYSIS ...]")
    print(json.dumps([one(Path(e), Path(a)) for e, a in zip(args[::2], args[1::2])]))


if __name__ == "__main__":
    main()
