"""SIGTERM and SIGINT (a SLURM time limit, Ctrl-C) during a campaign run: a
flag the scheduler reads to stop handing out work. `cortex campaign run`
installs the handler first thing, before the heavy imports and the store, so
a signal at any moment after that ends the run cleanly (exit status 3 and a
line saying how to resume), not with the default 143/130."""

import signal

stop = {"flag": False}


def _on_signal(signum, frame):
    stop["flag"] = True


def install():
    for signum in (signal.SIGTERM, signal.SIGINT):
        signal.signal(signum, _on_signal)
