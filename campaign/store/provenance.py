"""What made a store: the code version (from the installed package's
metadata, so the engine never imports the command-line package), the library
versions, the host, and one record per run."""

from __future__ import annotations

import json
import platform
import socket
import time
from importlib.metadata import PackageNotFoundError, version
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from campaign.store.schema import StoredCampaign

DISTRIBUTION = "cortex-poisson"     # pyproject.toml's [project] name


def code_version() -> str:
    """The installed distribution's version; `0.0.0+unknown` from a checkout that is not installed."""
    try:
        return version(DISTRIBUTION)
    except PackageNotFoundError:
        return "0.0.0+unknown"


def library_versions() -> str:
    """Versions of Python and of the libraries a store's numbers depend on, as JSON text
    (scipy's from its metadata: importing it would cost a no-op campaign 0.2-0.8 s)."""
    import h5py
    import mpi4py
    import numpy
    return json.dumps({"python": platform.python_version(), "numpy": numpy.__version__,
                       "scipy": version("scipy"), "h5py": h5py.version.version,
                       "hdf5": h5py.version.hdf5_version, "mpi4py": mpi4py.__version__})


def _now():
    return time.strftime("%Y-%m-%dT%H:%M:%S")


def store_attrs(campaign: StoredCampaign, ranks: int) -> dict[str, Any]:
    """The attributes a new store is created with."""
    return {"fingerprint": campaign.fingerprint, "trials_fingerprint": campaign.trials_fingerprint,
            "config_text": campaign.text, "name": campaign.name, "method": campaign.method,
            "code_version": code_version(), "versions": library_versions(), "host": socket.gethostname(),
            "ranks": ranks, "created": _now()}


def run_record(ranks: int, write_path: str) -> dict[str, Any]:
    """One entry of a store's `runs` list: when, on how many ranks, where, how written, by which code."""
    return {"started": _now(), "ranks": ranks, "host": socket.gethostname(), "write_path": write_path,
            "code_version": code_version()}
