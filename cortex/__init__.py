"""cortex: the command line and the provenance of the campaign engine."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("cortex-poisson")
except PackageNotFoundError:  # running from a checkout that is not installed
    __version__ = "0.0.0+unknown"
