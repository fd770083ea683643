"""Task kinds registered by their owners (`campaign.kinds`): a kind defined here, in the test
suite (not in campaign/ or analysis/), runs as a campaign on one rank, under `mpiexec -n 2`
(the command, and the scheduler in process under pytest-mpi), and its store holds its columns with
their units; its version is in the fingerprint, so a store made by another version is refused in
one line; a campaign file that names no registered kind is refused in one line. The engine imports
nothing of analysis (tests/test_architecture_map.py checks the package map)."""

import json

import h5py
import numpy as np
import pytest

from conftest import cortex

H0 = [15.0, 14.0, 13.0, 12.0]
SHEARS = [8.33, 15.0, 25.0]
CAMPAIGN = f"""
[campaign]
name = "kinds"
task = "made_up_kinds:squares"
[grid]
h0_um = {H0}
bulk_mN_per_m = 25.0
shear_mN_per_m = {SHEARS}
tension_mN_per_m = 1.5
[solver]
timeout_s = 60.0
"""


def _expected():
    """(h0², K_S/K_B) per row, in grid order (h0 slowest over these two axes)."""
    h0, shear = np.meshgrid(H0, SHEARS, indexing="ij")
    return h0.ravel() ** 2, shear.ravel() / 25.0


def _read(store):
    """What the checks look at: the rows' columns and the store's kind attributes."""
    with h5py.File(store, "r") as f:
        kind = (str(f.attrs["task_kind"]), int(f.attrs["task_version"]), json.loads(f.attrs["task_results"]))
    return _read_rows(store), kind


def _check(read):
    rows, kind = read
    squared, ratio = _expected()
    assert rows["state"] == ["done"] * len(squared)
    np.testing.assert_array_equal(rows["h0_squared_um2"], squared)
    np.testing.assert_array_equal(rows["shear_over_bulk"], ratio)
    assert np.isnan(rows["force_nN"]).all()          # no compression was solved
    assert kind == ("squares", 1, {"h0_squared_um2": "µm²", "shear_over_bulk": "1"})


@pytest.mark.parametrize("ranks", [1, 2])
def test_a_kind_from_a_test_module_runs_as_a_campaign(tmp_path, ranks):
    config = tmp_path / "c.toml"
    config.write_text(CAMPAIGN)
    store = tmp_path / "s.h5"
    done = cortex("campaign", "run", config, "--store", store, "--quiet", mpi=ranks if ranks > 1 else 0)
    assert done.returncode == 0, done.stderr
    _check(_read(store))


def test_a_store_of_another_kind_version_is_refused_in_one_line(tmp_path):
    config = tmp_path / "c.toml"
    config.write_text(CAMPAIGN.replace('name = "kinds"', 'name = "kinds"\nmax_tasks = 12'))
    store = tmp_path / "s.h5"
    assert cortex("campaign", "run", config, "--store", store, "--quiet").returncode == 0
    before = store.read_bytes()
    again = cortex("campaign", "run", config, "--store", store, "--quiet", env={"MADE_UP_KIND_VERSION": "2"})
    assert again.returncode == 2 and len(again.stderr.strip().splitlines()) == 1, again.stderr
    assert "squares version 1, not squares version 2" in again.stderr
    assert store.read_bytes() == before


@pytest.mark.parametrize("task, says", [("made_up_kinds:cubes", "registers no task kind 'cubes'"),
                                        ("no_such_module:squares", "cannot be imported"),
                                        ("squares", "name the module that registers the kind")])
def test_a_kind_not_registered_is_refused_in_one_line(tmp_path, task, says):
    config = tmp_path / "c.toml"
    config.write_text(CAMPAIGN.replace("made_up_kinds:squares", task))
    done = cortex("campaign", "run", config, "--store", tmp_path / "s.h5")
    assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1, done.stderr
    assert says in done.stderr and not (tmp_path / "s.h5").exists()


def test_a_name_has_one_owner_and_the_fingerprint_holds_the_version(tmp_path):
    from dataclasses import replace

    import made_up_kinds
    from campaign import config, kinds
    with pytest.raises(ValueError, match="registered already"):
        kinds.register(replace(made_up_kinds.KIND, version=7))
    assert kinds.register(made_up_kinds.KIND) is made_up_kinds.KIND        # the same kind again
    path = tmp_path / "c.toml"
    path.write_text(CAMPAIGN)
    campaign = config.load(path)
    assert campaign.kind is made_up_kinds.KIND and campaign.task == "squares"
    assert replace(campaign, kind=replace(campaign.kind, version=2)).fingerprint != campaign.fingerprint


@pytest.mark.mpi(min_size=2)
def test_a_kind_from_a_test_module_runs_under_the_scheduler(tmp_path_factory):
    """Every rank of `mpiexec -n 2 python -m pytest --with-mpi` loads the campaign (importing the
    kind's module) and runs the scheduler, as `cortex campaign run` does."""
    from mpi4py import MPI
    from test_scheduler_mpi import on_rank0, shared_campaign
    from campaign import scheduler
    campaign, store = shared_campaign(tmp_path_factory, "kinds", CAMPAIGN)
    status = scheduler.run(campaign, store, progress=False, writes="rank0")
    assert on_rank0(lambda: status) == 0
    read = on_rank0(lambda: _read(store))
    _check(read)
    assert set(read[0]["rank"]) <= set(range(MPI.COMM_WORLD.Get_size()))


def test_a_store_made_before_kinds_is_refused_for_a_run_and_still_read(tmp_path):
    """A store without `task_kind`/`task_version` and without checksums (as made before kinds):
    a run refuses it in one line, leaving it as it was; the readers read it, unchecked."""
    config = tmp_path / "c.toml"
    config.write_text(CAMPAIGN)
    store = tmp_path / "s.h5"
    assert cortex("campaign", "run", config, "--store", store, "--quiet").returncode == 0
    with h5py.File(store, "r+") as f:
        for key in ("task_kind", "task_version", "task_params", "task_results"):
            del f.attrs[key]
        del f["checksum"]
    before = store.read_bytes()
    again = cortex("campaign", "run", config, "--store", store, "--quiet")
    assert again.returncode == 2 and len(again.stderr.strip().splitlines()) == 1, again.stderr
    assert "made by an older cortex" in again.stderr and store.read_bytes() == before
    _check((_read_rows(store), ("squares", 1, {"h0_squared_um2": "µm²", "shear_over_bulk": "1"})))  # as made


def _read_rows(store):
    from campaign.store.reader import read_results
    return read_results(store)[["state", "h0_squared_um2", "shear_over_bulk", "force_nN", "rank"]].to_dict("list")


PARAMS_CAMPAIGN = CAMPAIGN.replace("made_up_kinds:squares", "made_up_kinds:shifted") + """
[params]
offset_um = [0.5, -1.0]
scale = [1.0, 2.0, 3.0]
"""


@pytest.mark.parametrize("ranks", [1, 2])
def test_a_kind_with_parameters_of_its_own_runs_over_the_params_product(tmp_path, ranks):
    """`[params]` (`campaign.params_grid`): every shell under every point of the product, the
    parameters fastest, each task with its own id, the parameters as columns with their units."""
    config = tmp_path / "c.toml"
    config.write_text(PARAMS_CAMPAIGN)
    store = tmp_path / "s.h5"
    done = cortex("campaign", "run", config, "--store", store, "--quiet", mpi=ranks if ranks > 1 else 0)
    assert done.returncode == 0, done.stderr
    from campaign.store.reader import read_results
    rows = read_results(store)
    h0, shear, offset, scale = (a.ravel() for a in np.meshgrid(H0, SHEARS, [0.5, -1.0], [1.0, 2.0, 3.0],
                                                                indexing="ij"))
    assert list(rows["state"]) == ["done"] * 72 and rows["task_id"].nunique() == 72
    np.testing.assert_array_equal(rows["h0_um"], h0)
    np.testing.assert_array_equal(rows["shear_mN_per_m"], shear)
    np.testing.assert_array_equal(rows["offset_um"], offset)
    np.testing.assert_array_equal(rows["shifted_um"], (h0 + offset) * scale)
    with h5py.File(store, "r") as f:
        assert json.loads(f.attrs["task_params"]) == {"offset_um": "µm", "scale": "1"}


@pytest.mark.parametrize("change, says", [
    (lambda t: t.replace("scale = [1.0, 2.0, 3.0]", ""), "missing: scale"),
    (lambda t: t + "speed = 1.0\n", "unknown: speed"),
    (lambda t: t.replace("[1.0, 2.0, 3.0]", "[]"), "[params] scale must be a finite number"),
    (lambda t: t.split("[params]")[0], "a [params] section giving them go together"),
    (lambda t: t.replace("made_up_kinds:shifted", "made_up_kinds:squares"), "go together")])
def test_a_params_section_that_does_not_fit_its_kind_is_refused_in_one_line(tmp_path, change, says):
    config = tmp_path / "c.toml"
    config.write_text(change(PARAMS_CAMPAIGN))
    done = cortex("campaign", "run", config, "--store", tmp_path / "s.h5")
    assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1, done.stderr
    assert says in done.stderr and not (tmp_path / "s.h5").exists()
