"""Grids too big for the machine are refused before they are built: the task
count comes from the list lengths, above `[campaign] max_tasks` (default
`campaign.config.MAX_TASKS`) the campaign file is refused with one line
giving the count, and no compression is made (counted)."""

import subprocess

import pytest

from campaign import config, grid
from conftest import BIN, ROOT

HUGE = """
[grid]
h0_um = [{heights}]
bulk_mN_per_m = 25.0
shear_mN_per_m = [{shears}]
tension_mN_per_m = 1.0
"""


def huge(tmp_path, n_heights=100_000, n_shears=20_000, extra=""):
    heights = ", ".join(f"{10 + i * 1e-5:.5f}" for i in range(n_heights))
    shears = ", ".join(f"{1 + i * 1e-3:.3f}" for i in range(n_shears))
    path = tmp_path / "huge.toml"
    path.write_text(extra + HUGE.format(heights=heights, shears=shears))
    return path


@pytest.fixture
def shells_made(monkeypatch):
    """How many compressions `config.load` builds."""
    made = []
    real = grid.Shell

    class Counting:
        def __call__(self, **kw):                 # a checked shell
            made.append(1)
            return real(**kw)

        def unchecked(self, *args, **kw):         # a shell of a checked grid
            made.append(1)
            return real.unchecked(*args, **kw)
    monkeypatch.setattr(grid, "Shell", Counting())
    return made


def test_huge_grid_is_refused_before_anything_is_built(tmp_path, shells_made):
    path = huge(tmp_path)
    with pytest.raises(config.InputError) as err:
        config.load(path)
    assert "2,000,000,000 compressions" in str(err.value) and "max_tasks" in str(err.value)
    assert "\n" not in str(err.value)
    assert shells_made == []                          # refused from the list lengths alone


def test_the_command_says_it_in_one_line_with_status_2(tmp_path):
    store = tmp_path / "s.h5"
    done = subprocess.run([str(BIN / "cortex"), "campaign", "run", str(huge(tmp_path)), "--store", str(store)],
                          capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "2,000,000,000" in lines[0] and f"{config.MAX_TASKS:,}" in lines[0], lines
    assert not store.exists()


def test_max_tasks_in_the_campaign_file_overrides_the_limit(tmp_path, shells_made):
    small = huge(tmp_path, n_heights=3, n_shears=2, extra="[campaign]\nmax_tasks = 5\n")
    with pytest.raises(config.InputError, match="6 compressions exceed the limit of 5"):
        config.load(small)
    assert shells_made == []
    small.write_text(small.read_text().replace("max_tasks = 5", "max_tasks = 6"))
    assert len(config.load(small).shells) == 6


def test_monte_carlo_trial_tasks_count_too(tmp_path):
    path = huge(tmp_path, n_heights=4, n_shears=1, extra="[campaign]\nmax_tasks = 100\n")
    path.write_text(path.read_text().replace("shear_mN_per_m = [1.000]", "shear_mN_per_m = 8.33")
                    + "[montecarlo]\nnu = 0.5\ncells = 3\nstudies = 48\n")
    # 4 compressions + 1 bending x 1 nu x 2 height-error modes x 48 studies = 100 tasks: accepted
    assert len(config.load(path).studies) == 96
    path.write_text(path.read_text().replace("studies = 48", "studies = 49"))
    with pytest.raises(config.InputError, match="102 tasks"):
        config.load(path)


@pytest.mark.parametrize("value", ["0", "-3", "1.5", "true", '"many"'])
def test_max_tasks_must_be_a_positive_integer(tmp_path, value):
    path = huge(tmp_path, n_heights=2, n_shears=1, extra=f"[campaign]\nmax_tasks = {value}\n")
    with pytest.raises(config.InputError, match="max_tasks must be a positive integer"):
        config.load(path)
