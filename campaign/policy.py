"""What the scheduler runs next: a pure policy, apart from the MPI mechanism.

`Policy` holds the tasks still to hand out and decides, from numbers the
scheduler gives it (no MPI, no store, no clock), which tasks go where:

- **Order.** Compressions first, those some trial task waits for before the
  others (grid order within each group); a Monte-Carlo trial task joins the
  queue once every compression it uses has finished (`finished`), behind the
  compressions still queued, so the short tasks come last and even out the
  ranks' ends. Tasks are numbered: compressions 0..n-1, trial task j is n + j.
- **Batch size** (tasks per message). With `W` workers, `R` ranks
  computing, `M` tasks queued, `T̄` the running mean task time and `c̄` rank
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
  `BATCH_MAX` tasks. Before any task has been timed, b = 1.
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


def master_may_compute(workers):
    """Whether rank 0, serving `workers` workers, ever computes tasks itself."""
    return workers <= MASTER_WORKERS_MAX


class Policy:
    """The queue of tasks to hand out and the rules above.

    `rows`: compressions to do (grid indices, any order); `waits`: per trial
    task to do (its number j), the compressions it uses (grid indices; those
    not in `rows` are done already); `n`: compressions in the grid; `workers`:
    ranks other than 0."""

    def __init__(self, rows, waits, n, workers):
        self.n, self.workers = n, workers
        self.task_s, self.cost_s = None, None
        pending = set(rows)
        self.waiting, self.dependents = {}, {}
        for j, deps in waits.items():
            deps = sorted(set(deps) & pending)
            self.waiting[j] = len(deps)
            for r in deps:
                self.dependents.setdefault(r, []).append(j)
        first = sorted(r for r in pending if r in self.dependents)
        self.todo = deque(first + sorted(pending - set(first)))
        self.todo.extend(self._ready())

    def _ready(self):
        """Trial tasks with nothing left to wait for (task numbers), no longer waiting."""
        ready = [j for j, w in self.waiting.items() if w == 0]
        for j in ready:
            del self.waiting[j]
        return [self.n + j for j in sorted(ready)]

    def finished(self, task):
        """Task `task` has finished (done or failed): the trial tasks it made ready join the queue."""
        if task < self.n:
            ready = []
            for j in self.dependents.pop(task, []):
                self.waiting[j] -= 1
                if self.waiting[j] == 0:          # only these can have become ready
                    ready.append(j)
            for j in sorted(ready):
                del self.waiting[j]
                self.todo.append(self.n + j)

    def timed(self, tasks, seconds):
        """`tasks` tasks took `seconds` of computing."""
        if tasks > 0:
            self.task_s = _mean(self.task_s, seconds / tasks)

    def served(self, messages, seconds):
        """Rank 0 took `seconds` to serve `messages` result messages."""
        if messages > 0:
            self.cost_s = _mean(self.cost_s, seconds / messages)

    def _nominal_batch(self):
        """b without the guided term (module docstring)."""
        T = max(self.task_s, 1e-9)
        by_time = math.floor(BATCH_S / T)
        by_load = math.ceil(self.workers * (self.cost_s or 0.0) / (MASTER_LOAD_MAX * T))
        return max(1, min(max(by_time, by_load), math.floor(BATCH_S_MAX / T), BATCH_MAX))

    def load(self):
        """ρ: the share of rank 0's time serving takes at the nominal batch size."""
        if self.task_s is None or not self.cost_s:
            return 0.0
        return self.workers * self.cost_s / (self._nominal_batch() * max(self.task_s, 1e-9))

    def master_computes(self):
        """Whether rank 0 computes tasks itself now (module docstring)."""
        if self.workers == 0:
            return True
        return master_may_compute(self.workers) and self.load() <= MASTER_LOAD_MAX

    def master_batch(self):
        """Tasks rank 0 computes at once (module docstring); b with no workers to serve."""
        if self.workers == 0 or self.task_s is None:
            return self.batch_size()
        return max(1, min(math.floor(MASTER_BATCH_S / max(self.task_s, 1e-9)), self.batch_size()))

    def computing(self):
        """Ranks computing tasks: the workers, and rank 0 when it does."""
        return self.workers + (1 if self.master_computes() else 0)

    def batch_size(self):
        """b of the module docstring."""
        if self.task_s is None:
            return 1
        guided = len(self.todo) // (GUIDE * max(self.computing(), 1))
        return max(1, min(guided, self._nominal_batch()))

    def ahead(self):
        """Tasks a worker is kept ahead."""
        return max(AHEAD, 2 * self.batch_size())

    def batches_for(self, in_flight):
        """The batches (lists of task numbers) to send a worker that holds `in_flight` tasks."""
        out = []
        while self.todo and in_flight < self.ahead():
            batch = self.take(self.batch_size())
            in_flight += len(batch)
            out.append(batch)
        return out

    def take(self, count):
        """The next `count` tasks (fewer if fewer are queued), no longer queued."""
        return [self.todo.popleft() for _ in range(min(count, len(self.todo)))]

    def left(self):
        """Tasks not yet handed out: queued, or trial tasks still waiting."""
        return len(self.todo) + len(self.waiting)
