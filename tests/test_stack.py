"""The installed command and `cortex doctor` describe the stack actually running.

Run in either venv: the default stack (mpi4py on the PyPI `mpich` wheel, serial
h5py) or the parallel-HDF5 one (Debian's MPICH under `with-mpi`, h5py with
MPI). Which one is active is found here independently of doctor: from h5py's
build config and from the files the `mpich` wheel installed.
"""

import importlib.metadata
import json
import os
import re
import sys
from pathlib import Path

import h5py
import pytest

import cortex
from conftest import cortex as cortex_command    # the package `cortex` is tested here too



def run_cortex(*args):
    done = cortex_command(*args, timeout=120)
    assert done.returncode == 0, done.stderr
    return done.stdout


@pytest.fixture(scope="module")
def doctor():
    return json.loads(run_cortex("doctor", "--json"))


def mpich_wheel_libs():
    """Real paths of the MPI libraries the PyPI `mpich` wheel installed, or set()."""
    try:
        dist = importlib.metadata.distribution("mpich")
    except importlib.metadata.PackageNotFoundError:
        return set()
    return {os.path.realpath(dist.locate_file(f)) for f in dist.files
            if Path(f).name.startswith("libmpi.so")}


def test_version_matches_package_metadata():
    out = run_cortex("--version").strip()
    assert out == f"cortex {cortex.__version__}"
    assert cortex.__version__ == importlib.metadata.version("cortex-poisson")


def test_doctor_reports_this_h5py(doctor):
    assert doctor["h5py"] == h5py.version.version
    assert doctor["hdf5"] == h5py.version.hdf5_version
    assert doctor["h5py_mpi"] is bool(h5py.get_config().mpi)
    assert doctor["mpi_size"] == 1                 # run serially here
    assert doctor["python"] == ".".join(map(str, sys.version_info[:3]))


def test_doctor_names_one_loaded_mpi_library(doctor):
    libs = doctor["mpi_library_files"]
    assert len(libs) == 1, libs                     # never two MPIs in one process
    assert doctor["mpi_library"].startswith("MPICH Version:"), doctor["mpi_library"]
    assert doctor["hdf5_library_files"], "HDF5 not found in the process maps"


def test_doctor_stack_matches_the_installed_mpi(doctor):
    lib = doctor["mpi_library_files"][0]
    if h5py.get_config().mpi:
        # Debian's MPICH, shared by mpi4py and parallel HDF5; no PyPI mpich beside it
        assert doctor["stack"].startswith("parallel-hdf5")
        assert Path(lib).name.startswith("libmpich.so.12"), lib
        assert any("hdf5_mpich" in f for f in doctor["hdf5_library_files"])
        assert not mpich_wheel_libs(), "the PyPI mpich wheel is installed in the MPI-HDF5 venv"
    else:
        assert doctor["stack"].startswith("default")
        assert lib in mpich_wheel_libs(), (lib, mpich_wheel_libs())
        wheel = re.match(r"\d+(\.\d+)*", importlib.metadata.version("mpich")).group()
        assert doctor["mpi_library"] == f"MPICH Version: {wheel}"
