"""The protocol-aware reading's kept replays (`analysis.afm.replay_store`): a replay's result comes
back bit for bit, its key changes with anything that changes the replay, a damaged file is
replayed again, a full disk stops a write cleanly, and the folder is the reading's own."""

import errno
import math

import numpy as np
import pytest

from analysis.afm.cell import Cell, Segment
from analysis.afm.memory_fit import RELAXED
from analysis.afm.replay_store import NAME, ReplayStore, decoded, encoded, key, recording_digest
from analysis.afm.wait_relaxation import Waits
from common.errors import InputError, WriteError
from outputs.ownership import OutputDir
from test_full_disk import fill, tmpfs  # noqa: F401  (a fixture)

MEMORIES = (0.0, 10.0, math.inf, RELAXED)
LAW = {"cell_id": "c1", "bulk_1s": 30.0, "shear_1s": 15.0, "bulk_beta": 0.1, "shear_beta": 0.3, "tension": 1.2}


def _cell(force_last=0.5):
    t = np.linspace(0.0, 10.0, 101)
    return Cell("c1", 4000.0, t, np.r_[np.full(100, 0.4), force_last], np.linspace(20.0, 15.0, 101),
                [Segment("approach", 0, 50), Segment("oscillation", 50, 101, 1.0, 0.25)])


def _result(waits=True):
    rng = np.random.default_rng(1)
    factors = {0.0: np.tile([1.0, 0.0, 0.0], (3, 1)), 10.0: rng.normal(size=(3, 3)),
               math.inf: "the replay found no equilibrium (a test)", RELAXED: rng.normal(size=(3, 3))}
    if not waits:
        return factors, None
    model = {0.0: np.zeros(7), 10.0: rng.normal(size=7), RELAXED: rng.normal(size=7)}
    return factors, Waits(rng.normal(size=7), rng.normal(size=7), np.array([0, 0, 0, 1, 1, 1, 1]), (2, 5), model)


def _same(a, b):
    assert list(a[0]) == list(b[0])
    for m in a[0]:
        if isinstance(a[0][m], str):
            assert a[0][m] == b[0][m]
        else:
            assert a[0][m].tobytes() == b[0][m].tobytes()
    if a[1] is None:
        assert b[1] is None
        return
    for name in ("time_s", "force_nN", "wait"):
        assert getattr(a[1], name).tobytes() == getattr(b[1], name).tobytes()
    assert a[1].used == b[1].used and list(a[1].model) == list(b[1].model)
    assert all(a[1].model[m].tobytes() == b[1].model[m].tobytes() for m in a[1].model)


@pytest.mark.parametrize("waits", [True, False])
def test_a_result_comes_back_bit_for_bit(waits):
    result = _result(waits)
    _same(result, decoded(encoded(result, MEMORIES), MEMORIES))


def test_the_key_changes_with_anything_that_changes_the_replay():
    cell = _cell()
    job = (cell, LAW, "standard", None, True, MEMORIES)
    base = key(job, recording_digest(cell))
    assert key((cell, dict(LAW), "standard", None, True, MEMORIES), recording_digest(_cell())) == base
    nudged = dict(LAW, shear_beta=np.nextafter(0.3, 1.0))               # one bit of one law
    others = [(cell, nudged, "standard", None, True, MEMORIES), (cell, LAW, "none", None, True, MEMORIES),
              (cell, LAW, "standard", 30.0, True, MEMORIES), (cell, LAW, "standard", None, False, MEMORIES),
              (cell, LAW, "standard", None, True, MEMORIES[:-1])]
    keys = {key(j, recording_digest(cell)) for j in others} | {key(job, recording_digest(_cell(0.5000001)))}
    assert len(keys) == 6 and base not in keys


def test_a_store_reads_back_what_it_wrote_and_replays_a_damaged_file(tmp_path):
    store = ReplayStore(OutputDir(tmp_path / "out"))
    job = (_cell(), LAW, "standard", None, True, MEMORIES)
    assert store.get(job) is None and store.read_back == 0
    store.put(job, _result())
    _same(_result(), store.get(job))
    assert store.read_back == 1
    [path] = (tmp_path / "out" / NAME).iterdir()
    path.write_bytes(path.read_bytes()[:100])                # cut by a kill that no atomic write allows
    assert store.get(job) is None
    store.put(job, _result(False))
    _same(_result(False), ReplayStore(OutputDir(tmp_path / "out")).get(job))    # a second reading there


def test_a_replays_entry_cortex_did_not_write_is_refused(tmp_path):
    out = OutputDir(tmp_path / "out")
    out.claim("cells.csv").write_text("x\n")
    (tmp_path / "out" / NAME).write_text("someone else's\n")
    with pytest.raises(InputError, match="replays is there and cortex did not write it"):
        ReplayStore(OutputDir(tmp_path / "out"))
    assert (tmp_path / "out" / NAME).read_text() == "someone else's\n"


def test_a_full_disk_stops_a_replay_write_cleanly(tmpfs):
    """On a disk with no room for the next replay: WriteError (exit status 5 at the command) naming
    its file, no part of it left, and the replays kept before it read back whole."""
    store = ReplayStore(OutputDir(tmpfs / "out"))
    first, second = (_cell(), LAW, "standard", None, True, MEMORIES), (_cell(), LAW, "standard", None, True, (10.0,))
    store.put(first, _result())
    ballast = fill(tmpfs, 16 * 1024)
    with pytest.raises(WriteError) as refused:
        store.put(second, ({10.0: np.ones((5000, 3))}, None))       # 120 kB
    assert refused.value.errno == errno.ENOSPC and str(tmpfs / "out" / NAME) in str(refused.value)
    assert len(list((tmpfs / "out" / NAME).iterdir())) == 1
    ballast.unlink()
    _same(_result(), ReplayStore(OutputDir(tmpfs / "out")).get(first))
