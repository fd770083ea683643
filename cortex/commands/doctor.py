"""`cortex doctor`: which MPI and HDF5 stack is active, for users and bug reports.

Two stacks are supported (README, "MPI stacks"): the default one (mpi4py on
the PyPI `mpich` wheel, serial h5py: rank 0 writes the store) and the
parallel-HDF5 one (Debian's MPICH, h5py built with MPI: every rank writes its
own rows of a collective `mpio` file). The files behind each library are read
from /proc/self/maps, so the report says which MPI library is really loaded,
and whether mpi4py and HDF5 share it.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
from typing import Any

from cortex.options import Commands


def register(sub: Commands) -> None:
    p = sub.add_parser("doctor", help="say which MPI library and HDF5 build are active",
                       description="Report the Python, MPI library and h5py/HDF5 build in use "
                                   "(and whether h5py was built with MPI, which enables the "
                                   "parallel store write path).")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(handler=run, ranks=True)


def loaded_libraries(*stems: str) -> list[str]:
    """Real paths of the shared libraries mapped in this process whose file
    name starts with one of `stems` (e.g. "libmpi", "libhdf5"); [] off Linux."""
    try:
        with open("/proc/self/maps") as maps:
            paths = {line.split()[-1] for line in maps if "/" in line}
    except OSError:
        return []
    return sorted({os.path.realpath(p) for p in paths
                   if os.path.basename(p).startswith(stems) and ".so" in p})


def _hint(err: Exception) -> str:
    """What to do when mpi4py cannot load its MPI library."""
    wrapper = os.path.join(os.path.dirname(sys.executable), "with-mpi")
    if "libmpi" in str(err) and os.path.exists(wrapper):
        return f"; run through {wrapper}"
    return ""


def report() -> dict[str, Any]:
    """Versions and capabilities of the active stack, as a dict."""
    from cortex import __version__
    import h5py
    import numpy
    out = {"cortex": __version__, "python": platform.python_version(),
           "numpy": numpy.__version__, "h5py": h5py.version.version,
           "hdf5": h5py.version.hdf5_version, "h5py_mpi": bool(h5py.get_config().mpi)}
    try:
        import mpi4py
        from mpi4py import MPI
        out["mpi4py"] = mpi4py.__version__
        out["mpi_library"] = " ".join(MPI.Get_library_version().strip().splitlines()[0].split())
        out["mpi_standard"] = "%d.%d" % MPI.Get_version()
        out["mpi_size"] = MPI.COMM_WORLD.Get_size()
    except Exception as err:  # MPI missing or broken: that is what doctor is for
        out["mpi_library"] = f"unavailable ({type(err).__name__}: {err}{_hint(err)})"
    out["mpi_library_files"] = loaded_libraries("libmpi")
    out["hdf5_library_files"] = loaded_libraries("libhdf5")
    out["stack"] = "parallel-hdf5 (mpio)" if out["h5py_mpi"] else "default (serial h5py, rank-0 writer)"
    return out


def run(args: argparse.Namespace) -> int:
    info = report()
    if args.json:
        print(json.dumps(info))
    else:
        width = max(map(len, info))
        for key, value in info.items():
            print(f"{key:<{width}}  {value}")
    return 0
