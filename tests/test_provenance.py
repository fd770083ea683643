"""How an experiment was made (`analysis.afm.provenance`): what `afm synth` records, the reading
`afm analyze` chooses by default (a frequency-domain experiment exactly as `--wait-s inf`), files
written before provenance was recorded (read as measured, said so, left untouched), and a
malformed provenance refused (one line, status 2). The time-domain experiment read protocol-aware
by default is in tests/test_protocol_replay.py; an imported JPK file measured in tests/test_jpk_import.py."""

import json
import math

import h5py
import numpy as np
import pytest

from analysis.afm import provenance as prov
from analysis.afm.formats.h5 import read_experiment, read_provenance, write_experiment
from analysis.afm.synth.cells import generate, law_forward
from analysis.calibration.file import load_calibration, shipped_path
from common.errors import InputError
from conftest import first_heights
from cortex.cli import main


@pytest.fixture(scope="module")
def cal():
    """The shipped calibration: its law is the forward model, `--method law` the inversion."""
    return shipped_path()


def _cells(n):
    return generate(n, seed=1, errors=False, forward=law_forward(load_calibration(None).calibration["standard"]))[0]


def test_a_frequency_domain_synth_is_read_by_default_as_wait_s_inf(cal, tmp_path):
    """Every table, summary and the population answer of the default reading equal those of
    --wait-s inf, byte for byte; summary.json says which reading and why."""
    exp = tmp_path / "exp"
    assert main(["afm", "synth", "--cells", "4", "--seed", "5", "--solver", "law", "--calibration", str(cal),
                 "--out", str(exp)]) == 0
    assert read_provenance(exp / "experiment.h5") == prov.FREQUENCY_DOMAIN
    for name, extra in (("default", []), ("inf", ["--wait-s", "inf"])):
        assert main(["afm", "analyze", str(exp), "--calibration", str(cal), "--method", "law",
                     "--out", str(tmp_path / name), *extra]) == 0
    files = sorted(p.name for p in (tmp_path / "inf").iterdir() if p.suffix in (".csv", ".json"))
    assert {"cells.csv", "segments.csv", "rheology.csv", "summary.json", "population.json"} <= set(files)
    said = {}
    for name in files:
        a, b = ((tmp_path / run / name).read_bytes() for run in ("default", "inf"))
        if name != "summary.json":
            assert a == b, name
            continue
        said = {run: json.loads(x) for run, x in (("default", a), ("inf", b))}
        assert said["default"].pop("reading") == "relaxed (synthetic, frequency-domain)"
        assert said["inf"].pop("reading") == "relaxed (--wait-s inf; the experiment: synthetic, frequency-domain)"
        assert said["default"] == said["inf"] and "protocol" not in said["default"]
    assert said["default"]["provenance"] == {"kind": "synthetic", "recorded": True, "model": "frequency-domain"}
    assert said["default"]["frequencies"]
    assert "made in the frequency-domain model" in (tmp_path / "default" / "report.md").read_text()


def test_a_time_domain_synth_records_its_cortex(tmp_path, monkeypatch):
    """`afm synth --time-domain` records its model, history, τ_c (inf) and every cell's
    β_B, β_S, K_B(1 s), K_S(1 s) as its truth.json has them; the default reads it protocol-aware."""
    first_heights(monkeypatch, 2)
    exp = tmp_path / "td"
    assert main(["afm", "synth", "--time-domain", "--cells", "1", "--no-errors", "--history", "relaxed",
                 "--out", str(exp)]) == 0
    made = read_provenance(exp / "experiment.h5")
    assert (made.kind, made.model, made.memory_s, made.history) == ("synthetic", "time-domain", math.inf, "relaxed")
    truth = json.loads((exp / "truth.json").read_text())["cells"][0]
    assert made.cortex == {truth["cell_id"]: {k: truth[k] for k in prov.CORTEX_COLUMNS}}
    assert made.to_dict()["memory_s"] is None
    assert prov.reading(made, None, as_made=True) == prov.Reading(None, "protocol-aware", "synthetic, time-domain")
    assert prov.reading(made, math.inf, as_made=False).name == "relaxed"           # an explicit wait decides


def test_a_file_without_provenance_is_read_as_measured_and_left_as_it_is(cal, tmp_path):
    old = write_experiment(tmp_path / "old.h5", _cells(2))          # as files were written before
    before = old.read_bytes()
    assert prov.reading(read_provenance(old), None, as_made=True) == \
        prov.Reading(None, "protocol-aware", "no provenance recorded: read as measured")
    assert main(["afm", "analyze", str(old), "--calibration", str(cal), "--method", "law", "--no-phase",
                 "--out", str(tmp_path / "a")]) == 0
    summary = json.loads((tmp_path / "a" / "summary.json").read_text())
    assert summary["provenance"] == {"kind": "unknown", "recorded": False}
    assert "does not record how it was made" in (tmp_path / "a" / "report.md").read_text()
    assert old.read_bytes() == before


def _bad_cortex(g):
    g.create_dataset("cortex", data=np.zeros(2))


@pytest.mark.parametrize("attrs, edit, says", [
    ({"kind": "guessed"}, None, "provenance kind 'guessed'"),
    ({"kind": "synthetic"}, None, "provenance model 'None'"),
    ({"kind": "synthetic", "model": "spectral"}, None, "provenance model 'spectral'"),
    ({"kind": "measured", "model": "time-domain"}, None, "provenance model 'time-domain'"),
    ({"kind": "synthetic", "model": "time-domain", "memory_s": -1.0, "history": "carried"}, None, "memory_s"),
    ({"kind": "synthetic", "model": "time-domain", "memory_s": "soon", "history": "carried"}, None, "memory_s"),
    ({"kind": "synthetic", "model": "time-domain", "history": "carried"}, None, "memory_s"),
    ({"kind": "synthetic", "model": "time-domain", "memory_s": math.inf, "history": "forgotten"}, None,
     "history 'forgotten'"),
    ({"kind": "synthetic", "model": "time-domain", "memory_s": math.inf, "history": "carried"}, _bad_cortex,
     "cortex is not a table"),
    ({}, None, "'kind' attribute"),
], ids=["kind", "no-model", "model", "measured-model", "memory-negative", "memory-text", "no-memory", "history",
        "cortex", "no-kind"])
def test_a_malformed_provenance_is_refused(cal, tmp_path, capsys, attrs, edit, says):
    path = write_experiment(tmp_path / "bad.h5", _cells(1))
    with h5py.File(path, "r+") as f:
        g = f.create_group("provenance")
        g.attrs.update(attrs)
        if edit:
            edit(g)
    with pytest.raises(InputError, match=says):
        read_experiment(path)
    capsys.readouterr()
    assert main(["afm", "analyze", str(path), "--calibration", str(cal), "--out", str(tmp_path / "a")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(path) in err[0] and "provenance" in err[0], err
    assert not (tmp_path / "a").exists()
