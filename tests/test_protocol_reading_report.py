"""What the protocol-aware reading says of the cells it did not correct or settle
(`analysis.afm.protocol_reading`): a corrected tension <= 0 refused with its reason, and
summary.json's and report.md's lists of every such cell and why; where the rounds start."""

import numpy as np
import pandas as pd
import pytest

from analysis.afm.protocol_factors import refused
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
    assert f"| c | not settled: its power laws still moved after {MAX_ROUNDS} rounds" in text
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
