"""`cortex afm tension`: synthetic droplets through JPK archives and the native
format, the bad-input paths (one line, exit 2, nothing written; in a batch the
rest analysed, exit 1), and the real JPK and Bruker files in ../shared/data/ (`CORTEX_SHARED_DATA`
names another data folder)."""

import json
import os
from pathlib import Path

import numpy as np
import pytest

from analysis.afm.formats.csvcell import write_csv_cell
from analysis.afm.formats.instruments import to_cell
from analysis.afm.tension.shell_shear import shear_range
from studies.tension_synth import droplet_recording
from conftest import ROOT
from cortex.cli import main
from jpk_writer import write_force
from solver.geometry import cell_radius

DATA = Path(os.environ.get("CORTEX_SHARED_DATA", ROOT.parent / "shared" / "data")) / "jpk"
TEXT = DATA / "force-save-2020.10.29-12.06.06.196.txt"
QI = DATA / "qi-data-2021.05.30-14.22.26.978_8777_8777.txt"
need = pytest.mark.skipif(not DATA.is_dir(), reason=f"shared test data not found at {DATA}")
BRUKER = DATA.parent / "bruker" / "MDA-MB231_Dish2_Cell1.000"
BRUKER_TEXT = DATA.parent / "bruker" / "MDA-MB231_Dish2_Cell1.000-NanoScope-Analysis.txt"
need_bruker = pytest.mark.skipif(not BRUKER.is_file(), reason=f"shared test data not found at {BRUKER}")
VOLUME = 3000.0


def _cell(cell_id, tension, h_tilde=0.7, seed=0):
    depth = 2.0 * float(cell_radius(VOLUME)) * (1.0 - h_tilde)
    rec = droplet_recording(VOLUME, tension, depth, cell_id=cell_id, noise_nN=0.02, baseline_nN=1.0, seed=seed)
    return to_cell(rec, VOLUME, "synthetic")


def _json(capsys, *argv):
    status = main(["afm", "tension", *map(str, argv), "--json"])
    return status, json.loads(capsys.readouterr().out)


def test_jpk_archives_give_back_the_tensions(tmp_path, capsys):
    truth = {"a": 0.5, "b": 1.5}
    for cid, t in truth.items():
        write_force(tmp_path / f"{cid}.jpk-force", _cell(cid, t), dish_um=20.0)
    out = tmp_path / "out"
    status, doc = _json(capsys, tmp_path / "a.jpk-force", tmp_path / "b.jpk-force", "--volume", VOLUME, "--out", out,
                        "--model", "droplet")
    assert status == 0 and doc["not_analysed"] == {}
    for row in doc["rows"]:
        assert row["tension_mN_per_m"] == pytest.approx(truth[row["cell_id"]], rel=0.01)
        assert row["tension_lo95_mN_per_m"] < row["tension_mN_per_m"] < row["tension_hi95_mN_per_m"]
    assert sorted((r["cell_id"], r["part"]) for r in doc["rows"]) == [
        ("a", "approach"), ("a", "pause"), ("b", "approach"), ("b", "pause")]
    names = sorted(p.name for p in out.iterdir())
    assert names == [".cortex-outputs", "report.md", "tension.csv", "tension_a.png", "tension_b.png"]
    import pandas as pd
    table = pd.read_csv(out / "tension.csv")
    assert "pressure_Pa" in table and "tension_mN_per_m" in table and len(table) == 4
    # the same recordings with the dish given: the pause heights are the recorded gaps
    status, dish = _json(capsys, tmp_path / "a.jpk-force", "--volume", VOLUME, "--dish-height-um", 20.0,
                         "--model", "droplet")
    pause = next(r for r in dish["rows"] if r["part"] == "pause")
    assert pause["height_reference"] == "dish" and pause["tension_mN_per_m"] == pytest.approx(0.5, rel=0.01)
    # volumes from a table (a wrong one for b: its tension comes out otherwise)
    (tmp_path / "v.csv").write_text(f"cell_id,volume_um3\na,{VOLUME}\nb,{2 * VOLUME}\n")
    status, table = _json(capsys, tmp_path / "a.jpk-force", tmp_path / "b.jpk-force", "--volumes", tmp_path / "v.csv",
                          "--model", "droplet")
    by = {(r["cell_id"], r["part"]): r for r in table["rows"]}
    assert by["a", "approach"]["tension_mN_per_m"] == pytest.approx(0.5, rel=0.01)
    assert by["b", "approach"]["volume_um3"] == 2 * VOLUME
    assert abs(by["b", "approach"]["tension_mN_per_m"] / 1.5 - 1) > 0.05


def test_the_native_format_and_the_small_deformation_model(tmp_path, capsys):
    path = write_csv_cell(tmp_path / "c.csv", _cell("c", 1.0))
    status, doc = _json(capsys, path, "--model", "small-deformation")
    ramp = next(r for r in doc["rows"] if r["part"] == "approach")
    assert status == 0 and ramp["model"] == "small-deformation" and ramp["compare_model"] == "droplet"
    assert ramp["compare_tension_mN_per_m"] == pytest.approx(1.0, rel=0.01)
    assert ramp["tension_mN_per_m"] < 0.8                # the small-deformation formula's bias at h~ = 0.7


def _bad(tmp_path, capsys, *argv):
    """Run, expect exit 2, one line on stderr, the --out folder never made."""
    out = tmp_path / "never"
    status = main(["afm", "tension", *map(str, argv), "--no-power-law", "--out", str(out)])
    err = capsys.readouterr().err.strip()
    assert status == 2 and len(err.splitlines()) == 1 and not out.exists()
    return err


def test_bad_input_is_one_line_and_exit_2_with_nothing_written(tmp_path, capsys):
    flat = write_csv_cell(tmp_path / "flat.csv", _cell("flat", 0.0))          # no tension: no contact
    assert "without contact" in _bad(tmp_path, capsys, flat)
    no_force = _cell("noforce", 1.0)
    pause = next(s for s in no_force.segments if s.kind == "pause")
    no_force.force_nN[pause.start:pause.stop] = 0.0                           # below the baseline (1 nN)
    assert "pause without force" in _bad(tmp_path, capsys, write_csv_cell(tmp_path / "nf.csv", no_force))
    corrupt = tmp_path / "corrupt.jpk-force"
    corrupt.write_bytes(b"PK\x03\x04 not really a zip")
    assert "corrupt.jpk-force" in _bad(tmp_path, capsys, corrupt, "--volume", VOLUME)
    write_force(tmp_path / "ok.jpk-force", _cell("ok", 1.0))
    assert "no volume" in _bad(tmp_path, capsys, tmp_path / "ok.jpk-force")
    assert "--radius-um" in _bad(tmp_path, capsys, tmp_path / "ok.jpk-force", "--radius-um", -3)
    for option in ("--shear-ratio", "--bulk-mN-per-m", "--max-depth-um", "--ramp-speed-um-per-s"):
        assert option in _bad(tmp_path, capsys, tmp_path / "ok.jpk-force", "--volume", VOLUME, option, 0)
    assert "apply to instrument files only" in _bad(tmp_path, capsys, flat, "--volume", VOLUME)
    assert "no such file" in _bad(tmp_path, capsys, tmp_path / "missing.txt", "--volume", VOLUME)


def test_a_batch_lists_what_it_could_not_analyse(tmp_path, capsys):
    write_force(tmp_path / "good.jpk-force", _cell("good", 1.0))
    write_force(tmp_path / "flat.jpk-force", _cell("flat", 0.0))
    (tmp_path / "corrupt.jpk-force").write_bytes(b"garbage")
    out = tmp_path / "out"
    status, doc = _json(capsys, tmp_path / "good.jpk-force", tmp_path / "flat.jpk-force",
                        tmp_path / "corrupt.jpk-force", "--volume", VOLUME, "--out", out, "--no-power-law")
    assert status == 1
    assert {r["cell_id"] for r in doc["rows"]} == {"good"}
    assert set(doc["not_analysed"]) == {"flat", str(tmp_path / "corrupt.jpk-force")}
    assert "without contact" in doc["not_analysed"]["flat"]
    report = (out / "report.md").read_text()
    assert "Not analysed" in report and "flat" in report
    # the shell's K_S/K_B: fitted by default (a droplet: no elastic term, so not identified), or given
    row = doc["rows"][0]
    assert row["elastic_term"] == "not significant" and row["shear_ratio"] is None
    assert (row["shear_ratio_source"], row["shear_ratio_identified"]) == ("fitted", "not identified")
    assert (row["shear_ratio_lo95"], row["shear_ratio_hi95"]) == pytest.approx(shear_range())
    assert "| not identified |" in report
    status, given = _json(capsys, tmp_path / "good.jpk-force", "--volume", VOLUME, "--shear-ratio", 0.5,
                          "--no-power-law")
    row = given["rows"][0]
    assert status == 0 and (row["shear_ratio"], row["shear_ratio_source"], row["shear_ratio_identified"]) == (
        0.5, "given", "given")


def test_figure_names_are_files_and_never_shared():
    from analysis.afm.tension.pipeline import file_names
    assert list(file_names(["a b", "a_b", "c/d"]).values()) == ["tension_a_b.png", "tension_a_b-2.png",
                                                                 "tension_c_d.png"]


@need
def test_the_real_jpk_text_export_gives_a_tension_and_contact_point(capsys):
    """The text export with its constant-force pause (docs/studies/tension-real-files.md has the
    numbers): R = 6.8 µm, the radius the published tool assumes for its test data."""
    status, doc = _json(capsys, TEXT, "--radius-um", 6.8, "--no-power-law")
    assert status == 0
    ramp, pause = doc["rows"]
    assert (ramp["part"], pause["part"]) == ("approach", "pause")
    assert 6.595 < ramp["contact_um"] < 7.095            # within the ramp's wedge heights
    assert ramp["tension_mN_per_m"] > 0 and pause["tension_mN_per_m"] > 0
    assert pause["force_nN"] == pytest.approx(18.6 - 7.9, abs=0.15)    # pause force above the free baseline
    # a constant-force pause: the feedback holds the force, nothing relaxes, F_inf is the mean
    assert pause["relaxation_model"] == "none" and pause["relaxation_flag"] == ""
    assert pause["force_nN"] == pytest.approx(pause["last_half_force_nN"], abs=0.002)
    # with the height channel taken as the gap (Z = 0): a pause at h~ ≈ 0.49
    status, dish = _json(capsys, TEXT, "--radius-um", 6.8, "--dish-height-um", 0, "--no-power-law")
    pause = next(r for r in dish["rows"] if r["part"] == "pause")
    assert pause["height_um"] == pytest.approx(6.656, abs=0.002) and pause["height_reference"] == "dish"
    assert np.isfinite(pause["tension_mN_per_m"]) and pause["pressure_Pa"] > 0


@need
def test_the_real_qi_pixel_is_a_clean_droplet_ramp(capsys):
    status, doc = _json(capsys, QI, "--radius-um", 6.8, "--no-power-law")
    ramp, = doc["rows"]
    assert status == 0 and ramp["r2"] > 0.95 and ramp["compare_r2"] > 0.95
    assert 3.77 < ramp["contact_um"] < 6.3


@need_bruker
def test_the_bruker_binary_file_and_its_text_export_agree(capsys):
    """The same curve, read from the NanoScope file and from NanoScope Analysis's
    export (its spring constant from the file beside it): one tension."""
    status, doc = _json(capsys, BRUKER, BRUKER_TEXT, "--radius-um", 6.8, "--no-power-law")
    assert status == 0 and doc["not_analysed"] == {}
    binary, text = doc["rows"]
    assert binary["part"] == text["part"] == "approach" and binary["r2"] > 0.95 and text["r2"] > 0.95
    assert text["droplet_tension_mN_per_m"] == pytest.approx(binary["droplet_tension_mN_per_m"], rel=0.02)
    for row in (binary, text):         # the shell's γ_a at most the droplet's apparent T (docs/studies/tension-real-files.md)
        assert row["model"] == "shell" and row["tension_mN_per_m"] <= 1.01 * row["droplet_tension_mN_per_m"]
        assert row["tension_lo95_mN_per_m"] < row["tension_mN_per_m"] < row["tension_hi95_mN_per_m"]
    assert text["depth_um"] == pytest.approx(binary["depth_um"], abs=0.05)
    assert text["compare_tension_mN_per_m"] == pytest.approx(binary["compare_tension_mN_per_m"], rel=0.03)
    # the baseline's slope fitted: each reading within the other's interval (they were 2.38 [1.67, 3.09]
    # and 1.28 [0.96, 1.74] with a level baseline), the slopes apart by about the tilt NanoScope
    # Analysis took off (1.359e-3 nm/nm of Z x k = 0.106 nN/um, tests/test_bruker.py; on windows that
    # differ by 4 % of their samples)
    for one, other in ((binary, text), (text, binary)):
        assert other["tension_lo95_mN_per_m"] <= one["tension_mN_per_m"] <= other["tension_hi95_mN_per_m"]
        assert one["bulk_modulus_lo95_mN_per_m"] == 0.0 and not one["bimodal"]
    tilt = binary["baseline_slope_nN_per_um"] - text["baseline_slope_nN_per_um"]
    assert 0.5 < tilt / (1.359e-3 * 0.0777945 * 1e3) < 1.5
    assert binary["ramp_speed_source"] == "recorded"
    assert binary["ramp_speed_um_per_s"] == pytest.approx(16.8717 * 178.0978e-3, rel=0.02)   # Forward vel. x Zsens


@need_bruker
def test_a_text_export_alone_is_read_for_its_ramp(tmp_path, capsys):
    """Without its NanoScope file the export has no sample times: its ramp is fitted all the
    same (as with the file beside it), its speed the option's or unknown; too deep a
    --max-depth-um is a warning. afm import still refuses it (it needs the times)."""
    alone = tmp_path / BRUKER_TEXT.name
    alone.write_bytes(BRUKER_TEXT.read_bytes())
    _, beside = _json(capsys, BRUKER_TEXT, "--radius-um", 6.8, "--no-power-law")
    status, doc = _json(capsys, alone, "--radius-um", 6.8, "--spring-constant", 0.0777945, "--no-power-law")
    row, = doc["rows"]
    assert status == 0 and row["tension_mN_per_m"] == pytest.approx(beside["rows"][0]["tension_mN_per_m"], rel=1e-9)
    assert (row["ramp_speed_um_per_s"], row["ramp_speed_source"], row["warning"]) == (None, "unknown", "")
    status, doc = _json(capsys, alone, "--radius-um", 6.8, "--spring-constant", 0.0777945,
                        "--ramp-speed-um-per-s", 3.0, "--max-depth-um", 2.0, "--no-power-law")
    row, = doc["rows"]
    assert (row["ramp_speed_um_per_s"], row["ramp_speed_source"]) == (3.0, "--ramp-speed-um-per-s")
    assert row["warning"].startswith("--max-depth-um 2 exceeds") and "reaches 0.4" in row["warning"]
    assert main(["afm", "import", str(alone), "--volume", "4000", "--spring-constant", "0.08", "--dish-height-um",
                 "-5", "--out", str(tmp_path / "imp")]) == 2 and not (tmp_path / "imp").exists()
    assert "sample times unknown" in capsys.readouterr().err


@need_bruker
def test_a_text_export_alone_is_read_by_the_power_law_shell_at_the_given_speed(tmp_path, capsys):
    """The export alone, timed by --ramp-speed-um-per-s at the binary's recorded speed (its samples
    taken evenly in time), reads the power-law γ_a and β of the binary within the binary's
    intervals (a ramp without a pause: γ_a only bounded above), and says how it was timed;
    without the speed the row says it has no sample times."""
    alone = tmp_path / BRUKER_TEXT.name
    alone.write_bytes(BRUKER_TEXT.read_bytes())
    _, doc = _json(capsys, BRUKER, "--radius-um", 6.8)
    binary, = doc["rows"]
    status, doc = _json(capsys, alone, "--radius-um", 6.8, "--spring-constant", 0.0777945,
                        "--ramp-speed-um-per-s", binary["ramp_speed_um_per_s"])
    text, = doc["rows"]
    assert status == 0 and text["power_law_note"].startswith("times from --ramp-speed-um-per-s")
    assert binary["power_law_tension_lo95_mN_per_m"] <= text["power_law_tension_mN_per_m"] \
        <= binary["power_law_tension_hi95_mN_per_m"]
    assert abs(text["power_law_exponent"] - binary["power_law_exponent"]) <= 1.96 * binary["power_law_exponent_sd"]
    assert text["headline_tension_mN_per_m"] == text["power_law_tension_mN_per_m"]
    _, doc = _json(capsys, alone, "--radius-um", 6.8, "--spring-constant", 0.0777945, "--shear-ratio", 0.5)
    assert doc["rows"][0]["power_law_note"] == "no sample times"


def _elastic_ramp_and_hold(path, tension=0.8, bulk=10.0, seed=1):
    """A single-cell CSV of an elastic cell (β = 0; `shell_ramp`, K_S/K_B 1/3) pressed at 1 µm/s to
    0.14 R, held there 5 s at constant height (its force does not relax), and retracted."""
    from analysis.afm.cell import Cell, Segment
    from studies.tension_synth import shell_ramp
    radius = float(cell_radius(VOLUME))
    x, f = shell_ramp(radius, tension, bulk, bulk / 3.0, 0.14 * radius, n=400, noise_nN=0.0)
    n, m = x.size, 500
    t = np.r_[x[0] - x, x[0] - x[-1] + np.arange(1, m + 1) / 100.0]
    t = np.r_[t, t[-1] + (t[1] - t[0]) * np.arange(1, n + 1)]
    force = np.r_[f, np.full(m, f[-1]), f[::-1]] + 0.02 * np.random.default_rng(seed).standard_normal(2 * n + m)
    segments = [Segment("approach", 0, n), Segment("pause", n, n + m), Segment("retract", n + m, 2 * n + m)]
    cell = Cell("e", VOLUME, t, force, np.r_[x, np.full(m, x[-1]), x[::-1]], segments, volume_source="synthetic",
                spring_constant_N_per_m=0.1)
    return write_csv_cell(path, cell)


def test_by_default_the_power_law_shell_reads_the_ramp_and_its_hold_and_heads_the_row(tmp_path, capsys):
    """The default: the approach row's power_law_* columns filled and its headline; an elastic cell
    reads β ≈ 0 and its γ_a and K_B(1 s) within their intervals, the elastic shell's γ_a (the β = 0
    reading) beside it; tension.csv and report.md carry both."""
    path, out = _elastic_ramp_and_hold(tmp_path / "e.csv"), tmp_path / "out"
    status, doc = _json(capsys, path, "--shear-ratio", 1 / 3, "--out", out)
    ramp, pause = doc["rows"]
    assert status == 0 and ramp["power_law_note"] == "" and ramp["power_law_hold"] == "height"
    assert ramp["power_law_shear_ratio_source"] == "given"
    assert ramp["power_law_tension_lo95_mN_per_m"] <= 0.8 <= ramp["power_law_tension_hi95_mN_per_m"]
    assert ramp["power_law_tension_mN_per_m"] == pytest.approx(0.8, rel=0.05)
    assert ramp["power_law_exponent"] < 0.02 and ramp["power_law_bulk_1s_mN_per_m"] == pytest.approx(10.0, rel=0.1)
    assert (ramp["headline_tension_mN_per_m"], ramp["headline_tension_lo95_mN_per_m"],
            ramp["headline_tension_hi95_mN_per_m"]) == (ramp["power_law_tension_mN_per_m"],
                                                        ramp["power_law_tension_lo95_mN_per_m"],
                                                        ramp["power_law_tension_hi95_mN_per_m"])
    assert ramp["headline_reading"] == "power-law shell" and ramp["model"] == "shell"
    assert ramp["tension_mN_per_m"] == pytest.approx(0.8, rel=0.05)         # the β = 0 reading
    assert pause["headline_reading"] == "pause relaxed force" and "power_law_hold" not in pause
    from cortex.commands.afm import _tension_line
    assert _tension_line(ramp).startswith(f"e: approach 0: power-law gamma_a {ramp['power_law_tension_mN_per_m']:.4g} "
                                          "mN/m [") and "; beta = 0 reading: gamma_a " in _tension_line(ramp)
    import pandas as pd
    table = pd.read_csv(out / "tension.csv")
    assert table.loc[0, "power_law_exponent"] == pytest.approx(ramp["power_law_exponent"])
    assert table.loc[0, "headline_reading"] == "power-law shell"
    report = (out / "report.md").read_text()
    assert "## Approach ramps: the power-law shell" in report and "the β = 0 reading" in report
    assert f"| {ramp['headline_tension_mN_per_m']:.4g} | " in report


def test_no_power_law_is_the_elastic_shell_alone_and_a_droplet_row_says_why(tmp_path, capsys):
    """`--no-power-law`: no power_law_* columns, the headline the elastic shell's (β = 0) reading;
    `--model droplet` by default: the columns say why there is no power-law reading (`--power-law`
    asks for it); `--power-law` and `--no-power-law` together are refused."""
    path, out = _elastic_ramp_and_hold(tmp_path / "e.csv"), tmp_path / "out"
    status, doc = _json(capsys, path, "--shear-ratio", 1 / 3, "--no-power-law", "--out", out)
    ramp = doc["rows"][0]
    assert status == 0 and not [k for k in ramp if k.startswith("power_law")]
    assert ramp["headline_reading"] == "elastic shell (β = 0)"
    from cortex.commands.afm import _tension_line
    assert _tension_line(ramp).startswith(f"e: approach 0: beta = 0 reading: gamma_a {ramp['tension_mN_per_m']:.4g} mN/m [")
    assert ramp["headline_tension_mN_per_m"] == ramp["tension_mN_per_m"] == pytest.approx(0.8, rel=0.05)
    import pandas as pd
    assert not [c for c in pd.read_csv(out / "tension.csv") if c.startswith("power_law")]
    assert "power-law shell" not in (out / "report.md").read_text()
    status, doc = _json(capsys, path, "--model", "droplet")
    ramp = doc["rows"][0]
    assert ramp["power_law_note"] == "not read with --model droplet (--power-law reads it)"
    assert ramp["power_law_tension_mN_per_m"] is None and ramp["headline_reading"] == "droplet"
    assert _tension_line(ramp).startswith("e: approach 0: power law: not read with --model droplet (--power-law ")
    assert main(["afm", "tension", str(path), "--power-law", "--no-power-law"]) == 2
    assert "not allowed with" in capsys.readouterr().err


def test_a_power_law_fit_that_breaks_down_leaves_the_elastic_reading_and_says_why(tmp_path, capsys, monkeypatch):
    """A numerical failure inside the power-law fit (here made to happen) does not stop the command:
    the row's note names it and the headline is the elastic shell's (β = 0) reading."""
    import analysis.afm.tension.pipeline as pipeline

    def broken(*args, **kwargs):
        raise np.linalg.LinAlgError("Singular matrix")
    monkeypatch.setattr(pipeline, "power_law_columns", broken)
    status, doc = _json(capsys, _elastic_ramp_and_hold(tmp_path / "e.csv"), "--shear-ratio", 1 / 3)
    ramp = doc["rows"][0]
    assert status == 0 and ramp["power_law_note"] == "not read: LinAlgError: Singular matrix"
    assert ramp["power_law_tension_mN_per_m"] is None and ramp["headline_reading"] == "elastic shell (β = 0)"
    assert ramp["headline_tension_mN_per_m"] == ramp["tension_mN_per_m"] == pytest.approx(0.8, rel=0.05)
