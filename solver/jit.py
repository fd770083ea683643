"""numba's `njit`, with numba started without importing scipy.linalg.

When numba first compiles or loads a function from its cache, it imports
`numba.np.arraymath`, which imports `scipy.linalg` only to learn whether
a BLAS is there for its `np.dot`-style inner products (`_HAVE_BLAS`).
Importing scipy.linalg costs every process about 0.3 s (measured: first
droplet of a process 0.51-0.58 s with it, 0.24-0.30 s without), and no
compiled function of this project uses BLAS: the banded solves are our
own (`solver.banded`). So arraymath is imported here once, with
scipy.linalg hidden; numba then uses its own loop for those inner
products, and numba's linear algebra, if ever compiled, still imports
scipy itself then. A process that has imported scipy.linalg already is
left as it is.
"""

import importlib
import sys


def _import_without_scipy_linalg(module):
    """Import `module` with scipy.linalg unimportable, unless already imported."""
    if "scipy.linalg" in sys.modules or module in sys.modules:
        return importlib.import_module(module)
    sys.modules["scipy.linalg"] = None          # `import scipy.linalg` raises ImportError
    try:
        return importlib.import_module(module)
    finally:
        del sys.modules["scipy.linalg"]


_import_without_scipy_linalg("numba.np.arraymath")
from numba import njit  # noqa: E402

__all__ = ["njit"]
