"""The scheduler's policy (campaign.policy), without MPI: the order of the
tasks, trial tasks after the compressions they wait for, batch sizes,
look-ahead, when rank 0 computes, and what a retry or a resume hands out."""

import math

import numpy as np
import pytest

from campaign import policy
from campaign.policy import AHEAD, BATCH_MAX, BATCH_S, GUIDE, Policy


def drain(p, worker_in_flight=0):
    """Every task of `p` in the order a worker with nothing in flight gets them,
    each handed-out task finishing at once (so trials become ready)."""
    order = []
    while p.todo:
        for batch in p.batches_for(worker_in_flight):
            for task in batch:
                order.append(task)
                p.finished(task)
    return order


def test_compressions_in_grid_order_then_trials():
    p = Policy(rows=[3, 0, 2, 1], waits={}, n=4, workers=1)
    assert drain(p) == [0, 1, 2, 3]
    assert p.left() == 0


def test_what_trials_wait_for_goes_first_and_trials_come_after_their_compressions():
    # 6 compressions; trial task 0 uses rows 4 and 5, trial task 1 uses row 1
    p = Policy(rows=range(6), waits={0: [4, 5], 1: [1]}, n=6, workers=1)
    assert list(p.todo) == [1, 4, 5, 0, 2, 3]           # the waited-for rows first, grid order in each
    assert p.left() == 6 + 2
    order = drain(p)
    assert sorted(order) == list(range(8)) and len(order) == 8       # every task once
    assert order.index(6 + 1) > order.index(1)                       # trial 1 after row 1
    assert order.index(6 + 0) > max(order.index(4), order.index(5))  # trial 0 after rows 4 and 5
    assert order.index(6 + 1) > order.index(3)          # ready trials queue behind the compressions left


def test_a_trial_waits_until_its_last_compression_finished_failed_or_not():
    p = Policy(rows=[0, 1], waits={0: [0, 1]}, n=2, workers=1)
    assert p.take(2) == [0, 1]
    p.finished(0)
    assert not p.todo and p.left() == 1                 # still waiting for row 1
    p.finished(1)                                       # the policy does not look at the state
    assert list(p.todo) == [2] and p.left() == 1


def test_resume_hands_out_only_what_is_left():
    # rows 0-2 done before (not in `rows`); trial 0 uses only done rows: ready at once
    p = Policy(rows=[3, 4], waits={0: [0, 1, 2], 1: [2, 3]}, n=5, workers=2)
    assert list(p.todo) == [3, 4, 5]                    # row 3 (waited for) first, trial 0 is ready
    assert drain(p) == [3, 4, 5, 6]


def test_retry_of_failed_rows_is_just_more_rows():
    """Which tasks are to do is the scheduler's input: failed rows retried are rows like any."""
    states = np.array([2, 3, 0, 2])                     # done, failed, pending, done
    retry = np.flatnonzero((states == 0) | (states == 3)).tolist()
    assert drain(Policy(retry, {}, 4, 1)) == [1, 2]
    assert drain(Policy(np.flatnonzero(states == 0).tolist(), {}, 4, 1)) == [2]


def test_batch_is_one_task_until_a_task_has_been_timed():
    p = Policy(range(1000), {}, 1000, workers=3)
    assert p.batch_size() == 1 and p.ahead() == AHEAD
    assert [len(b) for b in p.batches_for(0)] == [1] * AHEAD


def test_batch_size_bounded_by_time_by_the_queue_and_by_the_cap():
    p = Policy(range(100_000), {}, 100_000, workers=3)
    p.timed(100, 100 * 0.02)                            # 20 ms tasks: 10 per BATCH_S = 0.2 s
    assert p.task_s == pytest.approx(0.02)
    assert p.batch_size() == int(BATCH_S / 0.02)
    p.timed(1000, 1000 * 1e-6)                          # smoothed towards 1 µs tasks
    for _ in range(200):
        p.timed(1000, 1000 * 1e-6)
    assert p.task_s == pytest.approx(1e-6, rel=1e-6)
    assert p.batch_size() == BATCH_MAX                  # no-ops: the cap
    p.take(len(p.todo) - 40)                            # 40 left, 3 workers (rank 0 computes: 4 ranks)
    assert p.master_computes()
    assert p.batch_size() == 40 // (GUIDE * 4)          # guided: small batches at the end
    p.take(len(p.todo) - 3)
    assert p.batch_size() == 1


def test_look_ahead_is_two_batches_and_counts_what_the_worker_holds():
    p = Policy(range(10_000), {}, 10_000, workers=1)
    p.timed(10, 10 * 0.01)                              # 10 ms: batches of 20
    b = p.batch_size()
    assert b == 20 and p.ahead() == 2 * b
    assert [len(x) for x in p.batches_for(0)] == [b, b]
    assert [len(x) for x in p.batches_for(b + 1)] == [b]
    assert p.batches_for(2 * b) == []


def test_rank_0_computes_only_while_serving_leaves_it_time():
    p = Policy(range(100), {}, 100, workers=4)
    assert p.master_computes()                          # nothing measured yet
    p.timed(10, 10 * 0.03)                              # 30 ms tasks: batches of 6 by time
    p.served(1, 2e-3)                                   # 2 ms a message: rho = 4 * 2e-3 / (6 * 0.03) = 0.044
    assert p.batch_size() == 6 and p.load() == pytest.approx(4 * 2e-3 / (6 * 0.03))
    assert p.master_computes() and p.computing() == 5
    noop = Policy(range(100_000), {}, 100_000, workers=4)
    noop.timed(10, 10 * 20e-6)                          # 20 µs tasks, 20 ms to serve a message
    noop.served(1, 20e-3)
    assert noop.batch_size() == BATCH_MAX               # as large as allowed, and still
    assert noop.load() == pytest.approx(4 * 20e-3 / (BATCH_MAX * 20e-6))    # rho = 7.8
    assert not noop.master_computes() and noop.computing() == 4
    many = Policy(range(100), {}, 100, workers=policy.MASTER_WORKERS_MAX + 1)
    many.timed(10, 10 * 1.0)                            # long tasks, but too many workers to serve
    many.served(1, 1e-6)
    assert not many.master_computes()
    alone = Policy(range(3), {}, 3, workers=0)
    alone.timed(1, 1e-6)
    alone.served(1, 1.0)
    assert alone.master_computes()                      # one process: rank 0 is the only one


def test_batches_grow_to_keep_rank_0_within_its_load_and_within_the_time_cap():
    T, c, W = 0.03, 1e-3, 1023                          # 1024 ranks, 30 ms tasks, 1 ms per message
    p = Policy(range(10**6), {}, 10**6, workers=W)
    p.timed(1, T)
    p.served(1, c)
    b = p.batch_size()
    assert b == int(np.ceil(W * c / (policy.MASTER_LOAD_MAX * T)))      # 69 > b_time = 6
    assert p.load() <= policy.MASTER_LOAD_MAX < W * c / ((b - 1) * T)   # the smallest such batch
    slow = Policy(range(10**6), {}, 10**6, workers=W)
    slow.timed(1, 1.0)                                  # 1 s tasks, 1 s per message: b_load = 2046
    slow.served(1, 1.0)
    assert slow.batch_size() == int(policy.BATCH_S_MAX / 1.0)           # capped at 5 s of work


def test_the_threshold_is_the_served_share_of_rank_0s_time():
    T, W = 0.01, 2
    b = int(BATCH_S / T)                                # 20 tasks a batch by time
    c_edge = policy.MASTER_LOAD_MAX * b * T / W         # rho = W c / (b T) exactly at the limit
    p = Policy(range(1000), {}, 1000, workers=W)
    p.timed(1, T)
    p.served(1, c_edge * 0.99)
    assert p.batch_size() == b and p.master_computes()
    q = Policy(range(1000), {}, 1000, workers=W)
    q.timed(1, T)
    q.served(1, c_edge * 1.01)                          # b_load = b + 1: the batch grows instead
    assert q.batch_size() == b + 1 and q.master_computes()


def test_rank_0_takes_about_master_batch_s_of_tasks_at_once():
    """Rank 0 sends its own tasks to its task process ~MASTER_BATCH_S at a time:
    one before any task is timed, ⌊MASTER_BATCH_S / T̄⌋ (never more than a
    worker's batch) once timed, one for tasks longer than that; alone, a whole batch."""
    p = Policy(rows=range(100_000), waits={}, n=100_000, workers=1)
    assert p.master_batch() == 1
    for _ in range(50):
        p.timed(1000, 1000 * 1e-4)                          # 0.1 ms tasks
    assert p.master_batch() == math.floor(policy.MASTER_BATCH_S / p.task_s) <= p.batch_size()
    for _ in range(50):
        p.timed(10, 10 * 0.05)                              # 50 ms tasks: longer than MASTER_BATCH_S
    assert p.master_batch() == 1
    alone = Policy(rows=range(100_000), waits={}, n=100_000, workers=0)
    alone.timed(1000, 1000 * 1e-4)
    assert alone.master_batch() == alone.batch_size() > 1


def test_trials_are_timed_apart_from_the_compressions_before_them():
    """Instant compressions must not size the first batch of slow trial tasks: a
    batch holds one kind, each kind has its own T̄, and an untimed kind gets one
    task a batch. (A stop on a signal waits for the batches in flight; a batch of
    100 trials of 0.5 s sized by 0.1 ms compressions held a one-rank run 50 s.)"""
    p = Policy(rows=range(60), waits={j: [j % 60] for j in range(200)}, n=60, workers=0)
    while p.compressions_queued:
        batch = p.take(p.master_batch())
        assert all(t < 60 for t in batch)                    # no trial rides along with compressions
        p.timed(len(batch), len(batch) * 1e-4)               # instant compressions
        for t in batch:
            p.finished(t)
    assert len(p.todo) == 200 and p.task_s is None           # trials queued, none timed
    assert p.master_batch() == 1 and p.batch_size() == 1
    first = p.take(p.master_batch())
    p.timed(len(first), 0.5, trials=True)
    assert p.task_s == 0.5 and p.times[False] == pytest.approx(1e-4)
    assert p.batch_size() * p.task_s <= policy.BATCH_S_MAX   # at most 5 s of work in flight per batch
    mixed = Policy(rows=range(4), waits={0: [0]}, n=4, workers=1)
    mixed.finished(mixed.take(1)[0])                         # trial 0 ready, behind rows 1-3
    assert mixed.take(10) == [1, 2, 3] and mixed.take(10) == [4]
