"""Every command honours the one exit-status table (`common.errors`): a
signal during any command gives 3 and one line (SIGTERM like Ctrl-C), a
failed write 5, and the one table in the docs (docs/cli.md) is the code's."""

import os
import re
import signal

import pytest

import common.errors as errors
from conftest import ROOT
from cortex.cli import main


def _signalled(args):
    os.kill(os.getpid(), signal.SIGTERM)
    for _ in range(10**7):            # the handler runs at the next bytecode boundary, long before this ends
        pass
    raise AssertionError("SIGTERM was not delivered")


@pytest.mark.parametrize("command", [["afm", "synth", "--cells", "1", "--out", "x"],
                                     ["analysis", "calibrate", "s.h5", "--out", "o"]])
def test_sigterm_during_a_command_gives_status_3(command, monkeypatch, capsys):
    module = "cortex.commands.afm" if command[0] == "afm" else "cortex.commands.analysis"
    monkeypatch.setattr(f"{module}.{command[1]}", _signalled)
    before = signal.getsignal(signal.SIGTERM)
    assert main(command) == errors.EXIT_SIGNAL
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "stopped by a signal" in err[0] and "rerun" in err[0]
    assert signal.getsignal(signal.SIGTERM) is before          # the handler is put back


def test_a_write_failure_anywhere_gives_status_5_naming_the_file(monkeypatch, capsys, tmp_path):
    def full(args):
        raise OSError(28, "No space left on device", str(tmp_path / "x.csv"))
    monkeypatch.setattr("cortex.commands.analysis.calibrate", full)
    assert main(["analysis", "calibrate", "s.h5", "--out", "o"]) == errors.EXIT_WRITE_FAILED
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(tmp_path / "x.csv") in err[0] and "free space" in err[0]


def test_the_docs_table_is_the_code_table():
    text = (ROOT / "docs" / "cli.md").read_text()
    start = text.index("| status | meaning |")
    shown = text[start:].split("\n\n", 1)[0]
    assert shown == errors.exit_status_table()
    for status, meaning in errors.EXIT_STATUSES:                 # and every --help ends with the same table
        assert f"{status} {meaning.replace('`', '')}" in errors.EXIT_STATUS_HELP
    rows = dict(re.findall(r"^\| (\d) \| ([^|]+) \|", shown, flags=re.M))
    constants = {name: value for name, value in vars(errors).items() if name.startswith("EXIT_")
                 and isinstance(value, int)}
    assert sorted(int(k) for k in rows) == sorted(constants.values()) == [0, 1, 2, 3, 4, 5]
    for number, words in ((3, "signal"), (4, "equilibrium"), (5, "write"), (2, "bad input")):
        assert words in rows[str(number)].lower(), (number, rows[str(number)])
        assert words in errors.EXIT_STATUS_HELP


def test_no_other_page_repeats_the_table():
    pages = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
    holders = [p.name for p in pages if "| status | meaning |" in p.read_text()]
    assert holders == ["cli.md"]
