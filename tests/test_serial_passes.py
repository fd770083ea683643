"""`--serial {only,skip}` (tests/conftest.py) splits the suite into the two passes
of `make test-serial`: every test in exactly one of them, the SLURM tests (marked
`serial`, docs/testing.md) in the pass that runs alone."""

import subprocess
import sys

from conftest import ROOT

FILES = ("tests/test_slurm.py", "tests/test_architecture_map.py")


def collected(*args):
    """The test ids `pytest --collect-only ARGS` lists for FILES."""
    run = subprocess.run([sys.executable, "-m", "pytest", "--collect-only", "-q", "-p", "no:cacheprovider",
                          *args, *FILES], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stdout + run.stderr
    return {line for line in run.stdout.splitlines() if "::" in line}


def test_the_two_passes_split_the_suite_and_the_slurm_tests_run_alone():
    every, alone, beside = collected(), collected("--serial", "only"), collected("--serial", "skip")
    assert alone and beside and alone | beside == every and not alone & beside
    assert {name.split("::")[0] for name in alone} == {"tests/test_slurm.py"}
