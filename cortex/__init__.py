"""cortex: the command line, the top floor of the project (`cortex.cli` and the
command groups of `cortex.commands`); no other package imports it. `__version__` is the installed
package's version (package metadata, as the campaign stores record it), read
on first use: importing `importlib.metadata` costs a command's start-up
about half a second on a busy machine."""

__all__ = ["__version__"]


def __getattr__(name: str) -> str:
    if name != "__version__":
        raise AttributeError(f"module 'cortex' has no attribute {name!r}")
    from importlib.metadata import PackageNotFoundError, version
    try:
        value = version("cortex-poisson")
    except PackageNotFoundError:  # running from a checkout that is not installed
        value = "0.0.0+unknown"
    globals()["__version__"] = value
    return value
