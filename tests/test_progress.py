"""The campaign's progress line (campaign.progress): the rate is that of this
run, also after a resume of a store that already held most of the tasks."""

import io

from campaign.progress import LOG_EVERY_S, Progress


class Clock:
    def __init__(self):
        self.t = 1000.0

    def __call__(self):
        return self.t


def test_rate_after_a_resume_counts_only_this_runs_tasks():
    clock, out = Clock(), io.StringIO()
    bar = Progress(total=1000, done=900, enabled=True, clock=clock, stream=out)   # resumed: 900 done before
    for _ in range(20):                       # 20 tasks in 10 s: 2 task/s
        clock.t += 0.5
        bar.update()
    assert bar.rate() == 2.0
    clock.t += LOG_EVERY_S                    # nothing more finished: 20 tasks in 20 s
    bar.update(0)
    line = out.getvalue().strip().splitlines()[-1]
    assert line == "campaign: 920/1000 tasks finished, 1.00 task/s", line


def test_fresh_run_rate_and_quiet_progress():
    clock, out = Clock(), io.StringIO()
    bar = Progress(total=10, done=0, enabled=False, clock=clock, stream=out)
    clock.t += 4.0
    bar.update(8)
    assert bar.rate() == 2.0 and bar.done == 8
    assert out.getvalue() == ""               # --quiet: nothing printed
