"""numba's `njit`, started without importing scipy.linalg, its on-disk cache
kept per version of the compiled sources.

When numba first compiles or loads a function from its cache, it imports
`numba.np.arraymath`, which imports `scipy.linalg` only to learn whether
a BLAS is there for its `np.dot`-style inner products (`_HAVE_BLAS`).
Importing scipy.linalg costs every process about 0.3 s (measured: first
droplet of a process 0.51-0.58 s with it, 0.24-0.30 s without), and no
compiled function of this project uses BLAS: the banded solves are our
own (`solver.fast.banded`). So arraymath is imported here once, with
scipy.linalg hidden; numba then uses its own loop for those inner
products, and numba's linear algebra, if ever compiled, still imports
scipy itself then. A process that has imported scipy.linalg already is
left as it is.

numba's cache checks only the time stamp of the file that holds a function,
yet a compiled function carries the code of those it calls from other
files (`fast/newton.py`'s Newton iteration holds the kernel of `fast/kernel.py`
and the LU of `fast/banded.py`): after a change to `fast/kernel.py` alone, the old
kernel would go on running inside the cached iteration. So the cache is a
folder per version of all the compiled sources (`cache_dir`: a hash of
every module of `solver`, its subpackages included, that takes `njit` from
here), below numba's own cache
folder if one is set (NUMBA_CACHE_DIR), else below `solver/__pycache__`.
A change to any of them compiles afresh (about a minute, once).
"""

import hashlib
import importlib
import os
import pathlib
import sys


def _import_without_scipy_linalg(module):
    """Import `module` with scipy.linalg unimportable, unless already imported."""
    if "scipy.linalg" in sys.modules or module in sys.modules:
        return importlib.import_module(module)
    sys.modules["scipy.linalg"] = None  # type: ignore[assignment]  # `import scipy.linalg` raises ImportError
    try:
        return importlib.import_module(module)
    finally:
        del sys.modules["scipy.linalg"]


def cache_dir(base: str, package: str | os.PathLike[str] = pathlib.Path(__file__).parent) -> str:
    """`base`/numba-<hash of the sources of the modules of `package` and its
    subpackages that compile>."""
    digest = hashlib.sha256()
    for path in sorted(pathlib.Path(package).rglob("*.py")):
        text = path.read_bytes()
        if b"from solver.jit import njit" in text:
            digest.update(path.relative_to(package).as_posix().encode() + b"\0" + text)
    return os.path.join(base, "numba-" + digest.hexdigest()[:16])


_import_without_scipy_linalg("numba.np.arraymath")
import numba  # noqa: E402
from numba import njit  # noqa: E402

# (numba.config makes its settings at import, unseen by the type checker)
numba.config.CACHE_DIR = cache_dir(numba.config.CACHE_DIR or str(pathlib.Path(__file__).parent / "__pycache__"))  # type: ignore[attr-defined]

__all__ = ["njit"]
