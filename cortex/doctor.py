"""`cortex doctor`: which MPI and HDF5 stack is active, for users and bug reports."""

import json
import platform
import sys


def register(sub):
    p = sub.add_parser("doctor", help="say which MPI library and HDF5 build are active",
                       description="Report the Python, MPI library and h5py/HDF5 build in use "
                                   "(and whether h5py was built with MPI, which enables the "
                                   "parallel store write path).")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(handler="cortex.doctor:run")


def report():
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
        out["mpi_library"] = MPI.Get_library_version().strip().splitlines()[0]
        out["mpi_standard"] = "%d.%d" % MPI.Get_version()
        out["mpi_size"] = MPI.COMM_WORLD.Get_size()
    except Exception as err:  # MPI missing or broken: that is what doctor is for
        out["mpi_library"] = f"unavailable ({type(err).__name__}: {err})"
    out["stack"] = "parallel-hdf5 (mpio)" if out["h5py_mpi"] else "default (serial h5py, rank-0 writer)"
    return out


def run(args):
    info = report()
    if args.json:
        print(json.dumps(info))
    else:
        width = max(map(len, info))
        for key, value in info.items():
            print(f"{key:<{width}}  {value}")
    return 0
