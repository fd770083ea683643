"""A campaign's grid is checked on a cover of its points (`grid.check`) and
its shells made when asked for without checking each again (`grid.Grid`,
`Shell.unchecked`): the shells, in order, by index and by slice, are
exactly those `Shell(**point)` makes, and a grid with an
impossible point is refused with the same first error as checking every
point in grid order, for random small grids, dimensionless axes among them,
with bad values placed anywhere in them."""

import itertools
import random

import pytest

from campaign import config, grid
from common.errors import InputError
from solver.model import Shell

BAD = {"volume_um3": [-1.0, 0.0], "h0_um": [30.0, 0.4, -2.0], "dh_um": [13.0, 0.0],
       "bulk_mN_per_m": [-1.0], "shear_mN_per_m": [-0.5], "tension_mN_per_m": [0.0, -1.0],
       "thickness_um": [0.0], "viscosity_Pa_s": [-1.0], "frequency_hz": [0.0]}
GOOD = {"volume_um3": [4300.0, 3000.0, 6000.0], "h0_um": [10.0, 12.0, 15.0, 17.5], "dh_um": [0.5, 1.0, 2.0],
        "bulk_mN_per_m": [25.0, 0.0, 10.0], "shear_mN_per_m": [8.33, 0.0, 25.0],
        "tension_mN_per_m": [0.5, 1.0, 3.0], "thickness_um": [0.2, 0.1], "bending": ["standard", "none"],
        "viscosity_Pa_s": [1.0, 5.0], "frequency_hz": [1.0, 10.0]}
TILDE = {"h0_um": [0.3, 0.45, 0.52], "shear_mN_per_m": [0.3, 1.0], "tension_mN_per_m": [0.02, 0.1]}


def _grid_text(axes, ratios):
    names = {k: config.RATIO_AXES[k] if k in ratios else k for k in axes}
    lines = [f"{names[k]} = {v!r}" if isinstance(v[0], float) else f"{names[k]} = {v!r}".replace("'", '"')
             for k, v in axes.items()]
    return "[grid]\n" + "\n".join(lines) + "\n"


def _random_axes(rng):
    ratios = set(rng.sample(sorted(TILDE), rng.randint(0, 2))) if rng.random() < 0.4 else set()
    viscous = rng.random() < 0.3
    axes = {}
    for key, values in GOOD.items():
        if key in grid.OPTIONAL and not viscous:
            continue
        pool = TILDE[key] if key in ratios else values
        axes[key] = rng.sample(pool, rng.randint(1, min(3, len(pool))))
        if key in BAD and key not in ratios and rng.random() < 0.15:
            axes[key].insert(rng.randint(0, len(axes[key])), rng.choice(BAD[key]))
    return axes, ratios


def _one_by_one(path, axes, ratios):
    """What the grid's shells were before: each point checked by Shell itself, in grid order."""
    full = {k: axes.get(k, [None]) for k in grid.GRID_KEYS}
    out = []
    for combo in itertools.product(*(full[k] for k in grid.GRID_KEYS)):
        p = grid.absolute(dict(zip(grid.GRID_KEYS, combo)), {k: None for k in ratios})
        try:
            out.append(Shell(**p, resolution=1.0))
        except InputError as err:
            raise InputError(f"{path}: [grid] {err}") from None
    return out


@pytest.mark.parametrize("seed", range(6))
def test_cover_check_gives_the_same_shells_and_first_error(tmp_path, seed):
    rng, refused, accepted = random.Random(seed), 0, 0
    for i in range(60):
        axes, ratios = _random_axes(rng)
        path = tmp_path / f"g{i}.toml"
        path.write_text(_grid_text(axes, ratios))
        try:
            expected = _one_by_one(path, axes, ratios)
        except InputError as err:
            with pytest.raises(InputError) as got:
                config.load(path)
            assert str(got.value) == str(err)
            refused += 1
            continue
        shells = config.load(path).shells
        assert len(shells) == len(expected) and list(shells) == expected
        assert [shells[i] for i in range(len(shells))] == expected            # by index, as a task is made
        k = rng.randrange(len(expected))
        assert shells[-1 - k] == expected[-1 - k] and shells[k:k + 3] == expected[k:k + 3]
        with pytest.raises(IndexError):
            shells[len(expected)]
        assert [s.to_dict() for s in shells] == [s.to_dict() for s in expected]     # values, not just equality
        assert [type(v) for s in shells for v in s.to_dict().values()] == \
            [type(v) for s in expected for v in s.to_dict().values()]
        accepted += 1
    assert refused >= 5 and accepted >= 5          # both paths were exercised


def test_a_bad_point_deep_in_the_grid_is_refused_with_its_own_error(tmp_path):
    """h0 = 17.5 µm is above the free sphere of the smallest volume only, last in the grid."""
    path = tmp_path / "deep.toml"
    path.write_text("[grid]\nvolume_um3 = [6000.0, 1500.0]\nh0_um = [10.0, 17.5]\nbulk_mN_per_m = 25.0\n"
                    "shear_mN_per_m = [5.0, 10.0]\ntension_mN_per_m = [1.0, 2.0]\n")
    with pytest.raises(InputError, match=r"\[grid\] h0 = 17.5 um exceeds the free sphere's diameter .* "
                                         r"for V = 1500 um\^3"):
        config.load(path)


def test_unchecked_shell_equals_checked_one():
    p = dict(volume_um3=4300.0, h0_um=12.0, bulk_mN_per_m=25.0, shear_mN_per_m=10.0, tension_mN_per_m=1.0)
    made = Shell.unchecked(p, {"resolution": 2.0})
    assert made == Shell(**p, resolution=2.0) and hash(made) == hash(Shell(**p, resolution=2.0))
    assert made.dh_um == 0.5 and made.viscosity_Pa_s is None and made.bending_stiffness > 0
    with pytest.raises(AttributeError):
        made.h0_um = 3.0                        # still frozen


def test_a_campaign_holds_its_axes_not_its_shells(tmp_path):
    """100,000 compressions: loading the campaign allocates well under what
    100,000 shells take (~600 bytes each, 60 MB), on every rank; each is made
    when asked for, the same by index as in order."""
    import tracemalloc
    axes = {"h0_um": [10.0 + 0.1 * i for i in range(50)], "shear_mN_per_m": [5.0 + 0.5 * i for i in range(40)],
            "tension_mN_per_m": [0.5 + 0.05 * i for i in range(50)]}
    path = tmp_path / "big.toml"
    path.write_text(_grid_text(axes, set()).replace("[grid]\n", "[grid]\nbulk_mN_per_m = 25.0\n"))
    config.load(path)                                    # imports and caches out of the count
    tracemalloc.start()
    try:
        shells = config.load(path).shells
        held = tracemalloc.get_traced_memory()[0]
    finally:
        tracemalloc.stop()
    assert len(shells) == 100_000 and held < 1_000_000
    assert shells[54_321] == list(shells)[54_321] == Shell(
        volume_um3=4300.0, h0_um=axes["h0_um"][27], bulk_mN_per_m=25.0, shear_mN_per_m=axes["shear_mN_per_m"][6],
        tension_mN_per_m=axes["tension_mN_per_m"][21])
