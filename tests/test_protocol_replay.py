"""The protocol-aware reading (SPEC 10, 12): a recording's protocol read off it
(`analysis.afm.recorded_protocol.protocol_of`) and simulated at the REPLAY resolution against
the synthetic experiments' FINE one (`solver.protocol_simulation.simulate`), the power laws it
is replayed with (`analysis.afm.rheology.cortex_laws`), `afm analyze` (by default with each
recording's own waits, as a time-domain experiment's provenance asks) on a cell simulated in time against its truth and against `--wait-s inf`,
the relaxed-state reading, under mpiexec, and killed part way and run again (it resumes from its
kept replays); bad values exit 2."""

import json
import signal
import subprocess

import numpy as np
import pandas as pd
import pytest
from scipy.special import gamma

from analysis.afm.recorded_protocol import protocol_of
from analysis.afm.cell import Cell, Segment
from analysis.afm.replayed import cell_correction, replayed_segments
from analysis.afm.rheology import cortex_laws
from analysis.afm.synth.time_domain import recording_cell
from analysis.afm.timeseries import segment_moduli
from conftest import BIN, ROOT, cortex, first_heights, poll_until
from cortex.cli import main
from solver.model import Shell
from solver.protocol import Oscillate, Protocol, Ramp
from solver.protocol_simulation import REPLAY, simulate
from solver.time_domain import power_law_cortex


def _recorded(shell, cortex, protocol):
    return recording_cell(simulate(shell, cortex, protocol), shell.volume_um3, "c")


def test_the_replay_resolution_reads_as_the_fine_one():
    """Two heights, 1 and 10 Hz, a 20 s wait, β_B = 0.1, β_S = 0.3: the recording's own protocol
    read off it and simulated at the REPLAY resolution (16 steps a period, 2 periods) read by the
    segment fit against the FINE simulation's (64 steps a period, 5 periods): |K*| within 1.5 %,
    loss angle within 0.012 rad, mean tension within 2.5 % (found up to 0.63 %, 0.0070 rad, 1.55 %)."""
    shell = Shell(volume_um3=4300.0, h0_um=14.0, bulk_mN_per_m=25.0, shear_mN_per_m=20.0,
                  tension_mN_per_m=1.0, bending="none")
    cortex = power_law_cortex(25.0, 20.0, 0.1, 0.3)
    cell = _recorded(shell, cortex, Protocol.stepped(14.0, (13.5, 13.0), (1.0, 10.0), (5, 5), wait_s=20.0))
    protocol = protocol_of(cell)
    assert protocol.start_um == 14.0
    assert [s.to_um for s in protocol.steps if isinstance(s, Ramp)] == pytest.approx([13.5, 13.0])
    assert [(s.frequency_hz, s.periods) for s in protocol.steps if isinstance(s, Oscillate)] == [(1.0, 5), (10.0, 5)] * 2
    replay = simulate(shell, cortex, protocol, REPLAY)
    assert [s.stop - s.start for s in replay.oscillations()] == [32] * 4
    replayed = replayed_segments(cell, replay)
    for full, coarse in zip(segment_moduli(cell), replayed):
        assert coarse["modulus_mN_per_m"] == pytest.approx(full["modulus_mN_per_m"], rel=0.015)
        assert coarse["loss_angle_rad"] == pytest.approx(full["loss_angle_rad"], abs=0.012)
        assert coarse["tension_mN_per_m"] == pytest.approx(full["tension_mN_per_m"], rel=0.025)


def test_power_laws_from_the_fits_at_each_frequency():
    """|K*(f)| = K(1 s) Γ(1-β) (2π f)^β at three frequencies gives back β and K(1 s); one
    frequency gives β = 2δ/π; γ_a is the median tension."""
    rows = []
    for f in (0.1, 1.0, 10.0):
        for cell, beta_b, beta_s, n in (("a", 0.1, 0.3, 3), ("b", 0.2, 0.4, 1)):
            if cell == "b" and f != 1.0:
                continue
            kb, ks = (k * gamma(1 - b) * (2 * np.pi * f) ** b for k, b in ((25.0, beta_b), (10.0, beta_s)))
            rows.append({"cell_id": cell, "frequency_hz": f, "bulk_abs": kb, "bulk_delta": beta_b * np.pi / 2,
                         "shear_abs": ks, "shear_delta": beta_s * np.pi / 2, "tension": 1.0 + f})
    laws = cortex_laws(pd.DataFrame(rows)).set_index("cell_id")
    assert laws.loc["a", ["bulk_beta", "shear_beta", "bulk_1s", "shear_1s", "tension"]].to_list() == \
        pytest.approx([0.1, 0.3, 25.0, 10.0, 2.0])
    assert laws.loc["b", ["bulk_beta", "shear_beta", "bulk_1s", "shear_1s"]].to_list() == \
        pytest.approx([0.2, 0.4, 25.0, 10.0])


@pytest.fixture
def five_heights(monkeypatch):
    """One cell (0.1, 1 and 10 Hz), its first five mean heights."""
    first_heights(monkeypatch, 5)


@pytest.fixture(scope="module")
def in_time(tmp_path_factory):
    """A noiseless cell simulated in time with its history carried (100 s waits, its first five
    heights, τ_c = ∞; exp/) and its default reading (aware/): the folder holding both. The reading
    is stopped once: `cortex afm analyze` killed (SIGKILL) as soon as two of its replays are kept
    in aware/replays, then the same command run again (in this process) goes on from them."""
    root = tmp_path_factory.mktemp("in-time")
    with pytest.MonkeyPatch.context() as patch:
        first_heights(patch, 5)
        assert main(["afm", "synth", "--time-domain", "--cells", "1", "--no-errors", "--out", str(root / "exp")]) == 0
    args = ["afm", "analyze", str(root / "exp"), "--out", str(root / "aware")]
    proc = subprocess.Popen([str(BIN / "cortex"), *args], cwd=ROOT, stdin=subprocess.DEVNULL,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        poll_until(lambda: len(list((root / "aware" / "replays").glob("*.npz"))) >= 2, 600, "two replays kept", proc)
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    assert not (root / "aware" / "rheology.csv").exists()
    assert main(args) in (0, 1)
    return root


def test_wait_s_reads_a_cell_simulated_in_time(in_time, tmp_path):
    """The cell of `in_time`: the relaxed-state reading excludes it by the tension filter (the kept
    stress: found 20 %) and,
    the filter lifted, reads β_S 0.158 low and β_B 0.025 high, outside their intervals; `--memory-s 0`
    is that same reading. The default reads the memory from the drift (found 11970 s, the carried
    history), keeps the cell and reads both exponents within 0.025 of the truth (found -0.002 and
    -0.005), each inside its 95 % interval."""
    exp = in_time / "exp"
    truth = json.loads((exp / "truth.json").read_text())["cells"][0]
    runs = {"relaxed": ["--wait-s", "inf"], "lifted": ["--wait-s", "inf", "--tension-tolerance", "inf"],
            "forgets": ["--memory-s", "0", "--tension-tolerance", "inf"]}
    for name, extra in runs.items():
        assert main(["afm", "analyze", str(exp), "--out", str(tmp_path / name), *extra]) in (0, 1)
    dirs = {**{name: tmp_path / name for name in runs}, "aware": in_time / "aware"}
    read = {name: pd.read_csv(folder / "rheology.csv") for name, folder in dirs.items()}
    assert read["relaxed"].empty
    assert read["lifted"]["shear_exponent"][0] - truth["shear_exponent"] < -0.1
    pd.testing.assert_frame_equal(read["forgets"], read["lifted"])
    aware = read["aware"].iloc[0]
    for name in ("bulk", "shear"):
        assert aware[f"{name}_exponent"] == pytest.approx(truth[f"{name}_exponent"], abs=0.025)
        assert aware[f"{name}_exponent_lo95"] <= truth[f"{name}_exponent"] <= aware[f"{name}_exponent_hi95"]
    segments = pd.read_csv(dirs["aware"] / "segments.csv")
    assert segments["protocol_corrected"].all() and (segments["protocol_tension_shift_mN_per_m"] > 0).all()
    cells = pd.read_csv(dirs["aware"] / "cells.csv")
    assert cells["protocol_memory_s"][0] >= 1000.0 and cells["protocol_history"][0] == "carried"
    said = json.loads((dirs["aware"] / "summary.json").read_text())
    assert said["protocol"]["wait_s"] == "recorded"
    assert said["protocol"]["memory"]["memory_s"] == "from the data" and said["protocol"]["memory"]["cells_fitted"] == 1
    assert said["protocol"]["cells_not_corrected"] == said["protocol"]["cells_not_settled"] == []
    assert "1 of 1 cells corrected" in (dirs["aware"] / "report.md").read_text()
    assert said["reading"] == "protocol-aware (synthetic, time-domain)"      # read as it was made


def test_under_mpiexec_or_after_a_kill_the_reading_is_the_same(in_time):
    """`mpiexec -n 2 cortex afm analyze` (rank 0 reads and writes, rank 1 replays the cell:
    `common.pool.ranks`), never stopped, writes the same files byte for byte as the reading in one
    process that was killed part way and run again (`in_time`: it read its kept replays back,
    summary.json says how many, the only difference); --jobs beside mpiexec is one line and exit
    status 2."""
    run = cortex("afm", "analyze", in_time / "exp", "--out", in_time / "ranks", mpi=2)
    assert run.returncode in (0, 1), run.stderr
    for name in ("cells.csv", "segments.csv", "rheology.csv", "report.md"):
        assert (in_time / "ranks" / name).read_bytes() == (in_time / "aware" / name).read_bytes(), name
    whole, resumed = (json.loads((in_time / d / "summary.json").read_text()) for d in ("ranks", "aware"))
    assert whole["protocol"].pop("replays_read_back") == 0 and resumed["protocol"].pop("replays_read_back") >= 2
    assert whole == resumed
    bad = cortex("afm", "analyze", in_time / "exp", "--out", in_time / "jobs", "--jobs", "2", mpi=2)
    assert bad.returncode == 2 and bad.stderr.count("--jobs goes without mpiexec") == 1, bad.stderr
    assert not (in_time / "jobs").exists()


def test_a_cell_relaxed_at_every_height_is_read_so(five_heights, tmp_path):
    """A noiseless cell simulated with its history relaxed at every height (each from its own relaxed
    droplet one step above): the default reads the relaxed history as its memory, not a τ_c of the
    carried one (which read β_S 0.045 off), and both exponents within 0.025 (found -0.003, +0.018)."""
    exp = tmp_path / "exp"
    assert main(["afm", "synth", "--time-domain", "--cells", "1", "--no-errors", "--history", "relaxed",
                 "--out", str(exp)]) == 0
    truth = json.loads((exp / "truth.json").read_text())["cells"][0]
    assert main(["afm", "analyze", str(exp), "--out", str(tmp_path / "a")]) in (0, 1)
    cells = pd.read_csv(tmp_path / "a" / "cells.csv")
    assert cells["protocol_history"][0] == "relaxed" and cells["protocol_memory_source"][0] == "fitted"
    rheology = pd.read_csv(tmp_path / "a" / "rheology.csv").iloc[0]
    for name in ("bulk", "shear"):
        assert rheology[f"{name}_exponent"] == pytest.approx(truth[f"{name}_exponent"], abs=0.025)


@pytest.mark.parametrize("args, message", [
    (["--wait-s", "soon"], "--wait-s: 'soon' is not a number"),
    (["--wait-s", "-5"], "--wait-s: the wait must be >= 0 s"),
    (["--wait-s", "100", "--no-phase"], "cannot go with --no-phase"),
    (["--jobs", "0"], "jobs must be >= 1"),
    (["--memory-s", "long"], "--memory-s: 'long' is not a number"),
    (["--memory-s", "-1"], "--memory-s: the memory must be >= 0 s"),
    (["--memory-s", "30", "--wait-s", "inf"], "cannot go with --wait-s inf"),
    (["--memory-s", "30"], "a memory is the protocol-aware reading's"),
])
def test_wait_s_bad_values_exit_2(tmp_path, capsys, args, message):
    assert main(["afm", "synth", "--cells", "2", "--out", str(tmp_path / "exp")]) == 0
    capsys.readouterr()
    assert main(["afm", "analyze", str(tmp_path / "exp"), "--out", str(tmp_path / "a"), *args]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0]


def test_a_jpk_pause_of_half_a_second_is_corrected():
    """A JPK-like recording (approach 20 -> 15 µm over 10 s, a 0.5 s pause, 5 periods at 1 Hz):
    the pause times the hold, so the cell is corrected; 0.5 s after the step it keeps much of the
    step's stress (found |c| 1.05, Δγ 1.9 mN/m with γ_a 1 mN/m). Uncorrected, |c| is 1; the
    contact search's resolution moves |c| by ~0.2 %, hence the bound 1.03."""
    t = np.arange(0.0, 15.5, 0.01)
    h = np.interp(t, [0.0, 10.0, 15.5], [20.0, 15.0, 15.0])
    h[t >= 10.5] -= 0.25 * np.sin(2 * np.pi * (t[t >= 10.5] - 10.5))
    i10, i105 = np.searchsorted(t, 10.0), np.searchsorted(t, 10.5)
    segs = [Segment("approach", 0, i10), Segment("pause", i10, i105), Segment("oscillation", i105, t.size, 1.0)]
    law = {"bulk_1s": 25.0, "shear_1s": 10.0, "bulk_beta": 0.1, "shear_beta": 0.3, "tension": 1.0}
    found = cell_correction(Cell("jpk", 4300.0, t, np.zeros_like(t), h, segs), law, "standard")
    assert isinstance(found, np.ndarray) and found.shape == (1, 3)
    assert found[0, 0] > 1.03 and found[0, 2] > 1.0
