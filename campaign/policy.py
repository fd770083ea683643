"""What the scheduler runs next: a pure policy, apart from the MPI mechanism.

`Policy` holds the tasks still to hand out and decides, from numbers the
scheduler gives it (no MPI, no store, no clock), which tasks go where:

- **Order.** Compressions first, those some trial task waits for before the
  others (grid order within each group); a Monte-Carlo trial task joins the
  queue once every compression it uses has finished (`finished`), behind the
  compressions still queued, so the short tasks come last and even out the
  ranks' ends. A task is its number (`campaign.task_key.TaskNumbers`).
- **Batch size** (tasks per message). With `W` workers, `R` ranks
  computing, `M` tasks queued, `T̄` the running mean task time of the kind
  at the queue's front (compressions and trial tasks are timed apart, and a
  batch holds one kind: a trial may take a thousand times a compression, or
  the reverse) and `c̄` rank
  0's running mean cost of serving one result message (receiving it,
  journalling its entries, the flush, the refill):

      b_time = ⌊BATCH_S / T̄⌋,   b_load = ⌈W c̄ / (MASTER_LOAD_MAX T̄)⌉
      b = clamp(min(⌊M / (GUIDE R)⌋, max(b_time, b_load), ⌊BATCH_S_MAX / T̄⌋), 1, BATCH_MAX)

  `b_time` keeps a batch near `BATCH_S` of work, which bounds the delay of a
  stop on a signal and the work a kill loses; `b_load` is the batch that
  keeps serving at the share `ρ = W c̄ / (b T̄) ≤ MASTER_LOAD_MAX` of rank
  0's time when many workers or short tasks need more (c̄ counted wholly per
  message: an upper bound of the batch needed). The `M / (GUIDE R)` term is
  guided self-scheduling (Polychronopoulos & Kuck 1987): large batches
  while much is left, single tasks at the end, so no rank is left with a
  long tail. A batch is never more than `BATCH_S_MAX` of work nor more than
  `BATCH_MAX` tasks. Before any task of the kind has been timed, b = 1.
- **Look-ahead.** A worker is kept `ahead = max(AHEAD, 2 b)` tasks ahead: one
  batch computing, one queued, so it never waits for rank 0's answer.
- **Does rank 0 compute?** It computes tasks itself between messages while
  serving leaves it time, `ρ = W c̄ / (b T̄) ≤ MASTER_LOAD_MAX` (b without
  the guided term), and it serves at most `MASTER_WORKERS_MAX` workers:
  beyond that, one task of rank 0 delays W workers' answers for the gain of
  one rank in W + 1 (docs/performance.md, "The engine"). It takes
  `⌊MASTER_BATCH_S / T̄⌋` tasks at a time (at least one, at most b): one
  message to its task process (`campaign.isolation`) for many short tasks,
  while its serving waits no longer than about one task or MASTER_BATCH_S.
- **Retries** are the scheduler's input: which tasks are to do (pending, and
  failed ones with --retry-failed) is decided from the store before the run.

Times are in seconds.
"""

import math
from collections import deque
from collections.abc import Iterable, Mapping

from campaign.task_key import TRIAL, TaskKey, TaskNumbers

AHEAD = 4                 # tasks a worker holds at least: outlasts one of rank 0's own tasks
BATCH_S = 0.2             # s: the work in one batch, unless rank 0's load needs more ...
BATCH_S_MAX = 5.0         # s: ... but never more than this (a stop waits for the batches in flight)
BATCH_MAX = 512           # tasks in one message at most
GUIDE = 2                 # guided self-scheduling: a batch is at most 1/(GUIDE R) of what is queued
MASTER_LOAD_MAX = 0.5     # serving should take at most this share of rank 0's time
MASTER_WORKERS_MAX = 15   # ... and it serves at most this many workers
MASTER_BATCH_S = 0.04     # s: the work rank 0 takes at once between messages (workers hold a batch ahead)
SMOOTHING = 0.2           # weight of the newest measurement in the running means


def _mean(old, new):
    """The running mean: the newest measurement weighted SMOOTHING (the first taken as it is)."""
    return new if old is None else (1 - SMOOTHING) * old + SMOOTHING * new


def master_may_compute(workers: int) -> bool:
    """Whether rank 0, serving `workers` workers, ever computes tasks itself."""
    return workers <= MASTER_WORKERS_MAX


class Policy:
    """The queue of tasks to hand out and the rules above.

    `rows`: compressions to do (grid indices, any order); `waits`: per trial
    task to do (its study's place j), the compressions it uses (grid indices;
    those not in `rows` are done already); `n`: compressions in the grid;
    `workers`: ranks other than 0. The queue, `waiting` and `dependents` hold
    task numbers."""

    def __init__(self, rows: Iterable[int], waits: Mapping[int, Iterable[int]], n: int, workers: int):
        numbers, self.workers = TaskNumbers(n), workers
        self.times: dict[bool, float] = {}          # is a trial task -> running mean task time
        self.cost_s: float | None = None
        pending = set(numbers.of_compressions(rows))
        self.waiting: dict[int, int] = {}            # trial task -> compressions it still waits for
        self.dependents: dict[int, list[int]] = {}   # compression -> trial tasks waiting for it
        for j, deps in waits.items():
            trial = numbers.number(TaskKey(TRIAL, j))
            used = sorted(set(numbers.of_compressions(deps)) & pending)
            self.waiting[trial] = len(used)
            for r in used:
                self.dependents.setdefault(r, []).append(trial)
        first = sorted(r for r in pending if r in self.dependents)
        self.todo = deque(first + sorted(pending - set(first)))
        self.compressions_queued = len(self.todo)   # the queue: compressions, then trial tasks
        self.todo.extend(self._ready())

    def _ready(self) -> list[int]:
        """Trial tasks with nothing left to wait for, no longer waiting."""
        ready = sorted(t for t, w in self.waiting.items() if w == 0)
        for t in ready:
            del self.waiting[t]
        return ready

    def finished(self, task: int) -> None:
        """Task `task` has finished (done or failed): the trial tasks it made ready
        join the queue (only compressions have trial tasks waiting for them)."""
        ready = []
        for t in self.dependents.pop(task, []):
            self.waiting[t] -= 1
            if self.waiting[t] == 0:          # only these can have become ready
                ready.append(t)
        for t in sorted(ready):
            del self.waiting[t]
            self.todo.append(t)

    def timed(self, tasks: int, seconds: float, trials: bool = False) -> None:
        """`tasks` tasks (trial tasks if `trials`, else compressions) took `seconds` of computing."""
        if tasks > 0:
            self.times[trials] = _mean(self.times.get(trials), seconds / tasks)

    @property
    def task_s(self) -> float | None:
        """T̄ of the kind at the queue's front (trial tasks when it is empty); None if not timed yet."""
        return self.times.get(not self.compressions_queued)

    def served(self, messages: int, seconds: float) -> None:
        """Rank 0 took `seconds` to serve `messages` result messages."""
        if messages > 0:
            self.cost_s = _mean(self.cost_s, seconds / messages)

    def _nominal_batch(self) -> int:
        """b without the guided term (module docstring)."""
        T = max(self.task_s or 0.0, 1e-9)         # timed before it is asked for
        by_time = math.floor(BATCH_S / T)
        by_load = math.ceil(self.workers * (self.cost_s or 0.0) / (MASTER_LOAD_MAX * T))
        return max(1, min(max(by_time, by_load), math.floor(BATCH_S_MAX / T), BATCH_MAX))

    def load(self) -> float:
        """ρ: the share of rank 0's time serving takes at the nominal batch size."""
        if self.task_s is None or not self.cost_s:
            return 0.0
        return self.workers * self.cost_s / (self._nominal_batch() * max(self.task_s, 1e-9))

    def master_computes(self) -> bool:
        """Whether rank 0 computes tasks itself now (module docstring)."""
        if self.workers == 0:
            return True
        return master_may_compute(self.workers) and self.load() <= MASTER_LOAD_MAX

    def master_batch(self) -> int:
        """Tasks rank 0 computes at once (module docstring); b with no workers to serve."""
        if self.workers == 0 or self.task_s is None:
            return self.batch_size()
        return max(1, min(math.floor(MASTER_BATCH_S / max(self.task_s, 1e-9)), self.batch_size()))

    def computing(self) -> int:
        """Ranks computing tasks: the workers, and rank 0 when it does."""
        return self.workers + (1 if self.master_computes() else 0)

    def batch_size(self) -> int:
        """b of the module docstring."""
        if self.task_s is None:
            return 1
        guided = len(self.todo) // (GUIDE * max(self.computing(), 1))
        return max(1, min(guided, self._nominal_batch()))

    def ahead(self) -> int:
        """Tasks a worker is kept ahead."""
        return max(AHEAD, 2 * self.batch_size())

    def batches_for(self, in_flight: int) -> list[list[int]]:
        """The batches (lists of task numbers) to send a worker that holds `in_flight` tasks."""
        out = []
        while self.todo and in_flight < self.ahead():
            batch = self.take(self.batch_size())
            in_flight += len(batch)
            out.append(batch)
        return out

    def take(self, count: int) -> list[int]:
        """The next `count` tasks (fewer if fewer are queued, or if the
        compressions queued end before), no longer queued."""
        k = min(count, len(self.todo))
        if self.compressions_queued:
            k = min(k, self.compressions_queued)
            self.compressions_queued -= k
        return [self.todo.popleft() for _ in range(k)]

    def left(self) -> int:
        """Tasks not yet handed out: queued, or trial tasks still waiting."""
        return len(self.todo) + len(self.waiting)
