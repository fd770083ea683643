"""A package's public names, imported when first used: `import solver` (or
`campaign`, `analysis`, ...) stays free of numpy, numba and h5py until a name
is asked for, so `cortex --help` stays fast.

Usage in a package's `__init__.py`:

    __all__, __getattr__, __dir__ = lazy_exports(__name__, {"Shell": "solver.model", ...})

where each value is the module that defines the name, or "module:attr" when
the public name differs from the one in its module.
"""

import importlib
import sys
from collections.abc import Callable
from typing import Any


def lazy_exports(package: str, table: dict[str, str]
                 ) -> tuple[list[str], Callable[[str], Any], Callable[[], list[str]]]:
    """(`__all__`, module `__getattr__`, module `__dir__`) for `package`, whose
    public names are the keys of `table` (PEP 562)."""

    def __getattr__(name: str) -> Any:
        if name not in table:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        module, _, attr = table[name].partition(":")
        value = getattr(importlib.import_module(module), attr or name)
        setattr(sys.modules[package], name, value)        # the next look-up is a plain attribute
        return value

    def __dir__() -> list[str]:
        return sorted(set(vars(sys.modules[package])) | set(table))

    return list(table), __getattr__, __dir__
