"""What the protocol-aware reading says of the cells it did not correct or settle
(`analysis.afm.protocol_reading`): a corrected tension <= 0 refused with its reason, and
summary.json's and report.md's lists of every such cell and why, and of each cell's memory; where the rounds
start."""

import json
import math

import numpy as np
import pandas as pd
import pytest

from analysis.afm.protocol_factors import MEMORY_COLUMNS, refused
from analysis.afm.protocol_reading import MAX_ROUNDS, markdown, started, summary


def test_a_tension_shift_beyond_the_tension_is_refused_with_its_numbers():
    factors = np.array([[1.1, 0.01, 0.4], [1.2, 0.02, 0.9]])
    assert refused(np.array([1.0, 1.5]), factors) is None                 # 0.6 and 0.6 mN/m left
    why = refused(np.array([1.0, 0.8]), factors)                          # 0.8 - 0.9 = -0.1 mN/m
    assert why is not None and "segment 1" in why and "-0.1 mN/m" in why and "≤ 0" in why
    assert refused(np.array([0.9]), np.array([[1.0, 0.0, 0.9]])) is not None   # exactly 0 is refused


def _segments():
    rows = []
    for cell, ok, why, settled in (("a", True, "", True), ("b", False, "corrected tension ≤ 0 refused (x)", True),
                                   ("c", True, "", False), ("d", False, "protocol not recorded: y", True)):
        rows += [{"cell_id": cell, "protocol_corrected": ok, "protocol_reason": why, "protocol_settled": settled}] * 2
    return pd.DataFrame(rows)


def test_summary_and_report_name_every_cell_not_corrected_or_not_settled_and_why():
    said = summary(_segments(), None)
    assert said["cells_corrected"] == 2 and said["cells_not_corrected"] == ["b", "d"]
    assert said["not_corrected_reasons"] == {"b": "corrected tension ≤ 0 refused (x)", "d": "protocol not recorded: y"}
    assert said["cells_not_settled"] == ["c"]
    text = "\n".join(markdown(_segments()))
    assert "2 of 4 cells corrected" in text
    assert "| b | not corrected: corrected tension ≤ 0 refused (x) |" in text
    assert "| d | not corrected: protocol not recorded: y |" in text
    assert f"| c | not settled: its power laws still moved after its last round ({MAX_ROUNDS} linearised" in text
    assert "| a |" not in text


def test_the_rounds_start_from_the_shallowest_heights_tension_and_count_the_replays():
    """θ_0's γ_a is the median mean tension at a cell's shallowest height (within SHALLOWEST_UM of
    its largest mean height: the height that kept least stress), not the median over its heights;
    a cell without segments keeps its fitted γ_a. summary.json says how often a cell was replayed."""
    segments = pd.DataFrame({"cell_id": ["x"] * 5, "mean_height_um": [12.0, 11.95, 12.03, 11.0, 10.0],
                             "tension_mN_per_m": [1.1, 1.2, 1.3, 2.0, 3.0]})
    found = pd.DataFrame({"cell_id": ["x", "y"], "tension": [2.0, 1.5], "bulk_beta": [0.1, 0.1]})
    start = started(found, segments).set_index("cell_id")
    assert start.loc["x", "tension"] == pytest.approx(1.2) and start.loc["y", "tension"] == 1.5
    assert start.loc["x", "bulk_beta"] == 0.1 and found.loc[0, "tension"] == 2.0     # the fit's β kept, found untouched
    rows = _segments().assign(protocol_replays=[1, 1, 3, 3, 2, 2, 0, 0])
    assert summary(rows, None)["replays_per_cell"] == pytest.approx(1.5)
    assert summary(_segments(), None)["replays_per_cell"] is None


def test_summary_and_report_say_each_cells_memory_and_where_it_came_from():
    """Memory columns per cell (fitted, pooled, assumed, the relaxed history): summary.json counts
    them and lists each (null for ∞ or no interval: strict JSON), report.md says the counts."""
    memory = {"a": (40.0, 20.0, 90.0, "fitted", "carried"), "b": (30.0, 10.0, 80.0, "pooled", "carried"),
              "c": (math.inf, 0.0, math.inf, "assumed", "carried"), "d": (math.inf, math.nan, math.nan, "fitted", "relaxed")}
    rows = _segments()
    for k, name in enumerate(MEMORY_COLUMNS):
        rows[name] = rows["cell_id"].map({c: m[k] for c, m in memory.items()})
    said = summary(rows, None)["memory"]
    json.dumps(said, allow_nan=False)
    assert said["memory_s"] == "from the data" and said["grid_s"][-1] is None
    assert (said["cells_fitted"], said["cells_pooled"], said["cells_assumed"], said["cells_relaxed_history"]) == (2, 1, 1, 1)
    assert said["cells"]["c"] == {"memory_s": None, "lo95_s": 0.0, "hi95_s": None, "source": "assumed", "history": "carried"}
    assert said["cells"]["d"]["lo95_s"] is None and said["cells"]["d"]["history"] == "relaxed"
    text = "\n".join(markdown(rows))
    assert "2 cells read their own; 1 cells could not and take the population's (30 s)" in text
    assert "1 cells are undecided by the data" in text and "1 cells read best with the history relaxed" in text
    given = rows.assign(protocol_memory_s=45.0, protocol_memory_source="given")
    assert summary(given, None, 45.0)["memory"]["memory_s"] == 45.0
    assert "given: 45 s for every cell" in "\n".join(markdown(given))
