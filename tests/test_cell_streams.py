"""Each Monte-Carlo cell's random stream is numpy's
default_rng(SeedSequence(seed)), however it is built (campaign.cell_streams)."""

import numpy as np
import pytest

from campaign import cell_streams
from campaign.trials import draws
from test_campaign_montecarlo import _study

EDGES = [0, 1, 2, 0xFFFFFFFF, 1 << 32, (1 << 32) + 1, (1 << 63), (1 << 64) - 1]


def _first_numbers(rng):
    return int(rng.integers(6)), float(rng.standard_normal()), rng.standard_normal(6).tolist()


def _numpy_numbers(seeds):
    return [_first_numbers(np.random.default_rng(np.random.SeedSequence(s))) for s in seeds]


@pytest.mark.parametrize("fast", [True, False])
def test_streams_are_numpys_own_for_every_seed(fast, monkeypatch):
    """3,000 random 64-bit seeds and the word edges: the same integers and
    normals, bit for bit; also on the path for a numpy whose seeding differs."""
    if not fast:
        monkeypatch.setattr(cell_streams, "matches_numpy", lambda: False)
    seeds = np.random.default_rng(11).integers(0, (1 << 64) - 1, 3000, np.uint64, endpoint=True)
    seeds = seeds.tolist() + EDGES
    ours = [_first_numbers(rng) for rng in cell_streams.streams(seeds)]
    assert ours == _numpy_numbers(seeds)


def test_the_seeding_matches_this_numpy():
    assert cell_streams.matches_numpy()


@pytest.mark.parametrize("mode", ["per_cell", "per_height"])
def test_a_studys_draws_come_from_each_cells_own_numpy_generator(mode):
    """SPEC 5's contract, checked against numpy's objects built per cell."""
    study = _study(mode, n_cells=40)
    index, eps_v, eps_h = draws(study)
    m = len(study.heights_um)
    for c, tid in enumerate(study.trial_ids()):
        rng = np.random.default_rng(np.random.SeedSequence(int(tid, 16)))
        assert index[c] == rng.integers(len(study.tensions_mN_per_m))
        assert eps_v[c] == rng.standard_normal()
        want = np.full(m, rng.standard_normal()) if mode == "per_cell" else rng.standard_normal(m)
        assert np.array_equal(eps_h[c], want)
