"""SIGTERM and SIGINT (a SLURM time limit, Ctrl-C) during a campaign run: a
flag the scheduler reads to stop handing out work. `cortex campaign run`
installs the handler first thing, before the heavy imports and the store, so
a signal at any moment after that ends the run cleanly (exit status 3 and a
line saying how to resume), not with the default 143/130. It is installed
there only, once: the scheduler leaves the handlers as it finds them."""

import signal

stop = {"flag": False}


def _on_signal(signum, frame):
    stop["flag"] = True


def install() -> None:
    """The flag's handler for SIGTERM and SIGINT in this process."""
    for signum in (signal.SIGTERM, signal.SIGINT):
        signal.signal(signum, _on_signal)
