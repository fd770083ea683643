"""Round trip with the real solver: a calibration built here from the paper
grid's 180 fast-solver compressions (standard bending, `cortex campaign run`,
read back with `campaign.store.reader.read_results`, calibrated with
`analysis.calibration`), and a synthetic experiment whose forward model is
the same fast solver at each cell's own V, K_B(f), K_S and γ_a. Measurement
errors off: the recovered median ν per frequency must be within 0.05 of the
truth, and the blebbing cells must be excluded with their reason."""

import os
import subprocess

import numpy as np
import pytest

from analysis.afm.analyze import analyze_cells
from analysis.invert.method import choose
from analysis.afm.population.summary import summary
from analysis.afm.synth.cells import generate, solver_forward
from analysis.calibration.law import calibrate
from campaign.store.reader import read_results
from conftest import BIN, ROOT

GRID = """
[campaign]
name = "paper-standard"
[grid]
volume_um3 = 4300.0
h0_um = [15.0, 14.0, 13.0, 12.0, 11.0, 10.0]
dh_um = 0.5
bulk_mN_per_m = 25.0
shear_mN_per_m = [8.33, 10.0, 15.0, 20.0, 25.0]
tension_mN_per_m = [0.5, 1.0, 1.5, 2.0, 2.5, 3.0]
thickness_um = 0.2
bending = "standard"
[solver]
method = "fast"
timeout_s = 300.0
"""


@pytest.fixture(scope="module")
def calibration(tmp_path_factory):
    d = tmp_path_factory.mktemp("paper")
    (d / "grid.toml").write_text(GRID)
    out = subprocess.run([str(BIN / "cortex"), "campaign", "run", str(d / "grid.toml"), "--store",
                          str(d / "s.h5"), "--quiet"], capture_output=True, text=True, cwd=ROOT,
                         env=dict(os.environ), timeout=600)
    assert out.returncode == 0, out.stderr
    results = read_results(d / "s.h5")
    assert (results["state"] == "done").sum() == 180
    cal, fits, _ = calibrate(results)
    assert len(fits) == 30                      # 5 shear moduli x 6 tensions, 6 heights each
    return cal


@pytest.mark.slow
def test_solver_round_trip_without_errors(calibration):
    cells, truth = generate(40, seed=5, errors=False, forward=solver_forward("standard"))
    table, _ = analyze_cells(cells, choose("law", calibration, None), "standard", None)
    s = summary(table)
    assert [r["frequency_hz"] for r in s["frequencies"]] == [0.02, 0.1, 1.0, 10.0]
    for r in s["frequencies"]:
        true = truth["frequencies"][str(r["frequency_hz"])]["median_nu_true"]
        assert abs(r["median_nu"] - true) < 0.05, (r, true)
    # published ordering: ν falls with frequency
    med = [r["median_nu"] for r in s["frequencies"]]
    assert med == sorted(med, reverse=True)
    # the blebbing cells, and only they, are excluded, each for its tension jump
    bleb = {c["cell_id"] for c in truth["cells"] if c["blebbing"]}
    assert bleb
    excluded = table[table["excluded_reason"].notna()]
    assert set(excluded["cell_id"]) == bleb
    assert excluded["excluded_reason"].str.startswith("average tension not constant").all()
    # cells inside the calibrated grid (K̃_S in [1/3, 1], γ̃_a in [0.02, 0.12]) come back one by one
    ok = table[table["excluded_reason"].isna()]
    err, inside = [], []
    for row in ok.itertuples():
        t = truth["frequencies"][str(row.frequency_hz)]["cells"][row.cell_id]
        g = row.tension_mN_per_m / t["bulk_mN_per_m"]
        err.append(row.nu - t["nu"])
        inside.append(1 / 3 <= t["ks_tilde"] <= 1 and 0.02 <= g <= 0.12)
    err, inside = np.array(err), np.array(inside)
    assert inside.sum() >= 10
    assert np.median(np.abs(err[inside])) < 0.03
    # the population reaches beyond the published grid; those results are flagged
    flag = ok["outside_calibration"].astype(bool).to_numpy()
    assert 0 < flag.sum() < len(flag)
    assert np.mean(flag[inside]) < 0.2          # (recovered values near the edge may cross it)
