"""cortex: the command line, the top floor of the project (`cortex.cli`,
`cortex.doctor`); no other package imports it. `__version__` is the installed
package's version (package metadata, as the campaign stores record it)."""

from importlib.metadata import PackageNotFoundError, version

__all__ = ["__version__"]

try:
    __version__ = version("cortex-poisson")
except PackageNotFoundError:  # running from a checkout that is not installed
    __version__ = "0.0.0+unknown"
