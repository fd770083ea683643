"""The scheduler in process under MPI (pytest-mpi): every rank of
`mpiexec -n N python -m pytest --with-mpi -m mpi` runs these tests and calls
`campaign.scheduler.run` itself, as `cortex campaign run` does.

Each test builds its own small campaign in a folder rank 0 makes and
broadcasts, and every rank checks what rank 0 read back from the store (so an
assertion fails on every rank together instead of leaving one waiting):
tasks spread over the ranks and each done once; one failing task leaves the
others done; SIGTERM stops the hand-outs cleanly (exit status 3) and the
rerun completes.
"""

import os
import signal
import threading
from pathlib import Path

import numpy as np
import pytest

from conftest import journal_counts

GRID = """
[campaign]
name = "mpi-test"
[grid]
h0_um = [15.0, 14.0, 13.0, 12.0, 11.0]
bulk_mN_per_m = 25.0
shear_mN_per_m = [8.33, 15.0, 25.0]
tension_mN_per_m = [0.5, 1.5, 2.5, 3.0]
[solver]
timeout_s = 60.0
"""
N_TASKS = 60
MONTECARLO = """
[montecarlo]
nu = [0.5, 0.25]
cells = 20
studies = 5
seed = 3
"""


def shared_campaign(tmp_path_factory, name, text):
    """(campaign, store path): the file written by rank 0 into a folder it
    broadcasts, then loaded by every rank."""
    from mpi4py import MPI
    from campaign import config
    comm = MPI.COMM_WORLD
    folder = comm.bcast(str(tmp_path_factory.mktemp(name)) if comm.Get_rank() == 0 else None)
    if comm.Get_rank() == 0:
        (Path(folder) / "c.toml").write_text(text)
    comm.Barrier()
    return config.load(str(Path(folder) / "c.toml")), str(Path(folder) / "s.h5")


def on_rank0(read):
    """`read()` on rank 0, its value on every rank."""
    from mpi4py import MPI
    comm = MPI.COMM_WORLD
    return comm.bcast(read() if comm.Get_rank() == 0 else None)


@pytest.fixture
def stop_flag():
    """The scheduler's stop flag and the SIGTERM handler, as they were after the test."""
    from campaign import signals
    before = signal.getsignal(signal.SIGTERM)
    signals.stop["flag"] = False
    yield signals
    signals.stop["flag"] = False
    signal.signal(signal.SIGTERM, before)


@pytest.mark.mpi(min_size=2)
def test_tasks_spread_over_ranks_each_done_once(tmp_path_factory, stop_flag):
    """60 compressions of the made-up law (each sleeps 20 ms first: a known
    wall time, so no rank can take them all) and the trial tasks that wait for
    them; every worker computes some, each task once, with the law's numbers."""
    from mpi4py import MPI
    import faults
    from campaign import scheduler
    from campaign.store.reader import read_results, read_trials
    size = MPI.COMM_WORLD.Get_size()
    campaign, store = shared_campaign(tmp_path_factory, "spread", GRID + MONTECARLO +
                                      "[test]\nfake_law = true\ncompression_sleep_s = 0.02\n")
    status = scheduler.run(campaign, store, progress=False, writes="rank0")
    assert on_rank0(lambda: status) == 0
    rows = on_rank0(lambda: read_results(store)[["state", "attempts", "rank", "force_nN"]].to_dict("list"))
    trials = on_rank0(lambda: read_trials(store)[["state", "attempts"]].to_dict("list"))
    assert rows["state"] == ["done"] * N_TASKS and rows["attempts"] == [1] * N_TASKS
    assert set(rows["rank"]) >= set(range(1, size)) and set(rows["rank"]) <= set(range(size))
    law = [faults.fake_law(s)["force_nN"] for s in campaign.shells]
    np.testing.assert_array_equal(rows["force_nN"], law)
    assert len(campaign.studies) == 20 and len(trials["state"]) > 0
    assert set(trials["state"]) == {"done"} and set(trials["attempts"]) == {1}


@pytest.mark.mpi(min_size=2)
def test_a_failing_task_leaves_the_others_done(tmp_path_factory, stop_flag):
    """Rows 2 and 7 raise, row 11 returns NaN, row 20 hangs past a 2 s timeout:
    those four fail with their messages, the other 56 are done (status 1)."""
    from campaign import scheduler
    from campaign.store.reader import read_results
    text = GRID.replace("timeout_s = 60.0", "timeout_s = 2.0") + \
        "[test]\nfake_law = true\nraise_task = [2, 7]\nnan_task = 11\nhang_task = 20\n"
    campaign, store = shared_campaign(tmp_path_factory, "faults", text)
    status = scheduler.run(campaign, store, progress=False, writes="rank0")
    assert on_rank0(lambda: status) == 1                # the workers return 0; rank 0 says how it went
    rows = on_rank0(lambda: read_results(store)[["state", "error", "force_nN"]].to_dict("list"))
    failed = {i: rows["error"][i] for i, s in enumerate(rows["state"]) if s == "failed"}
    assert sorted(failed) == [2, 7, 11, 20]
    assert "injected fault" in failed[2] and "injected fault" in failed[7]
    assert failed[11].startswith("non-finite result (rank ") and failed[20].startswith("timed out after 2 s (rank ")
    done = [i for i, s in enumerate(rows["state"]) if s == "done"]
    assert len(done) == N_TASKS - 4 and np.isfinite(np.take(rows["force_nN"], done)).all()


@pytest.mark.mpi(min_size=2)
def test_sigterm_stops_cleanly_and_the_rerun_completes(tmp_path_factory, stop_flag):
    """Tasks that sleep 0.1 s each (60 of them: at least 3 s on 2 ranks). Once
    the journal on disk holds an entry, rank 0 gets SIGTERM: the run returns 3
    with tasks left and none shown running; the rerun does only the rest."""
    from mpi4py import MPI
    from campaign import scheduler
    from campaign.store.reader import read_results
    rank = MPI.COMM_WORLD.Get_rank()
    campaign, store = shared_campaign(tmp_path_factory, "signal", GRID +
                                      "[test]\nfake_law = true\ncompression_sleep_s = 0.1\n")
    stop_flag.install()
    watcher = None
    if rank == 0:
        def signal_once_progress_shows():
            while journal_counts(store)[0] == 0:
                threading.Event().wait(0.01)
            os.kill(os.getpid(), signal.SIGTERM)
        watcher = threading.Thread(target=signal_once_progress_shows, daemon=True)
        watcher.start()
    status = scheduler.run(campaign, store, progress=False, writes="rank0")
    if watcher is not None:
        watcher.join(timeout=60)
    assert MPI.COMM_WORLD.allreduce(status == 3 if rank == 0 else status == 0, op=MPI.LAND)
    first = on_rank0(lambda: read_results(store)[["state", "attempts"]].to_dict("list"))
    assert "running" not in first["state"]
    assert 0 < first["state"].count("done") < N_TASKS
    stop_flag.stop["flag"] = False
    assert scheduler.run(campaign, store, progress=False, writes="rank0") == 0
    second = on_rank0(lambda: read_results(store)[["state", "attempts"]].to_dict("list"))
    assert second["state"] == ["done"] * N_TASKS
    assert second["attempts"] == [1] * N_TASKS          # nothing done twice


@pytest.mark.mpi(min_size=2)
def test_a_waiting_worker_naps_instead_of_holding_a_core():
    """A worker waiting for rank 0 polls with naps: while rank 0 sleeps a
    known 0.5 s before it sends, the worker's process uses under a quarter
    of that on the CPU, however late it starts waiting (MPI's blocking
    receive would poll it all away, which on a node with more ranks than
    cores starves the ranks that compute)."""
    import time
    from mpi4py import MPI
    from campaign import scheduler
    comm, status = MPI.COMM_WORLD, MPI.Status()
    comm.Barrier()
    if comm.Get_rank() == 0:
        time.sleep(0.5)
        for w in range(1, comm.Get_size()):
            comm.send("go", dest=w, tag=scheduler.TAG_TASK)
        cpu = 0.0
    else:
        cpu = time.process_time()
        assert scheduler._next_message(comm, status) == "go" and status.Get_tag() == scheduler.TAG_TASK
        cpu = time.process_time() - cpu
    assert comm.allreduce(cpu, op=MPI.MAX) < 0.25 * 0.5      # s


def test_the_scheduler_leaves_the_signal_handlers_to_the_command(tmp_path, stop_flag):
    """One process, no mpiexec: `scheduler.run` does not install handlers of its
    own (`cortex campaign run` installs them once, first thing), so a handler
    set before the run is the one in place during and after it."""
    from campaign import config, scheduler
    seen = []

    def mine(signum, frame):
        seen.append(signum)
    signal.signal(signal.SIGTERM, mine)
    (tmp_path / "c.toml").write_text(GRID + "[test]\nnoop = true\n")
    campaign = config.load(str(tmp_path / "c.toml"))
    assert scheduler.run(campaign, str(tmp_path / "s.h5"), progress=False) == 0
    assert signal.getsignal(signal.SIGTERM) is mine
    os.kill(os.getpid(), signal.SIGTERM)
    assert seen == [signal.SIGTERM] and not stop_flag.stop["flag"]
