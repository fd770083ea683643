"""What a running campaign shows: a tqdm bar on a terminal, a log line every
10 s otherwise. The rate is that of this run: the tasks finished since it
started, `(done − done₀) / (t − t₀)`, not counting those a resumed store
already held (`done₀`)."""

import sys
import time
from collections.abc import Callable
from typing import TextIO

LOG_EVERY_S = 10.0


class Progress:
    """`total` tasks, of which `done` were finished before this run."""

    def __init__(self, total: int, done: int, enabled: bool, clock: Callable[[], float] = time.time,
                 stream: TextIO | None = None):
        self.total, self.done, self.done0 = total, done, done
        self.clock, self.stream = clock, stream or sys.stderr
        self.start, self.last = clock(), 0.0
        self.enabled, self.bar = enabled, None
        if enabled and self.stream.isatty():
            from tqdm import tqdm
            self.bar = tqdm(total=total, initial=done, unit="task", desc="campaign", file=self.stream)

    def rate(self) -> float:
        """Tasks per second finished in this run."""
        return (self.done - self.done0) / max(self.clock() - self.start, 1e-9)

    def update(self, count: int = 1) -> None:
        """`count` more tasks finished."""
        self.done += count
        if self.bar is not None:
            self.bar.update(count)
        elif self.enabled and self.clock() - self.last > LOG_EVERY_S:
            self.last = self.clock()
            print(f"campaign: {self.done}/{self.total} tasks finished, {self.rate():.2f} task/s",
                  file=self.stream, flush=True)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
