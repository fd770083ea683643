"""Campaign files (TOML): the grid of compressions and the solver settings.

    [campaign]  name, store (default path of the HDF5 store)
    [grid]      volume_um3, h0_um, dh_um, bulk_mN_per_m, shear_mN_per_m,
                tension_mN_per_m, thickness_um: a number or a list of numbers;
                bending: a name or a list of `standard`, `double`, `none`
    [solver]    method (`fast`|`explicit`), resolution, timeout_s (per task)
    [test]      fault injection for tests only: raise_task, hang_task, nan_task,
                each a list of grid indices whose task raises, sleeps past its
                timeout, or returns NaN instead of being solved; noop = true
                makes every task return zeros at once (throughput benchmark)

The grid is the Cartesian product of the lists. Every compression is checked
with `solver.model.Shell`, so an impossible point (Δh ≥ h0, h0 above the free
sphere, a negative modulus) is refused before anything is written.
"""

import hashlib
import itertools
import tomllib
from dataclasses import dataclass

from solver.errors import InputError
from solver.model import BENDING_VARIANTS, Shell

GRID_KEYS = ("volume_um3", "h0_um", "dh_um", "bulk_mN_per_m", "shear_mN_per_m",
             "tension_mN_per_m", "thickness_um", "bending")
DEFAULTS = {"volume_um3": 4300.0, "dh_um": 0.5, "thickness_um": 0.2, "bending": "standard"}
SECTIONS = {"campaign": {"name", "store"}, "grid": set(GRID_KEYS),
            "solver": {"method", "resolution", "timeout_s"},
            "test": {"raise_task", "hang_task", "nan_task", "noop"}}


@dataclass(frozen=True)
class Campaign:
    name: str
    store: str | None
    method: str
    resolution: float
    timeout_s: float
    shells: tuple          # every compression, in grid order
    text: str              # the file's text, kept in the store
    faults: dict = None    # grid index -> "raise" | "hang" | "nan" ([test] section only)

    @property
    def fingerprint(self):
        """What identifies the campaign's tasks: refuses a store made from another grid."""
        key = repr([(s.to_dict()) for s in self.shells]) + self.method + repr(self.resolution)
        return hashlib.sha256(key.encode()).hexdigest()


def _numbers(path, key, value):
    values = value if isinstance(value, list) else [value]
    if not values:
        raise InputError(f"{path}: [grid] {key} is an empty list: the grid would be empty")
    for v in values:
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise InputError(f"{path}: [grid] {key} must be numbers (got {v!r})")
    return [float(v) for v in values]


def load(path):
    """Read and validate a campaign file; InputError with one line if it is wrong."""
    try:
        with open(path, "rb") as fh:
            raw = fh.read()
        data = tomllib.loads(raw.decode())
    except FileNotFoundError:
        raise InputError(f"{path}: no such campaign file") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as err:
        raise InputError(f"{path}: not valid TOML ({err})") from None
    for section, value in data.items():
        if section not in SECTIONS:
            raise InputError(f"{path}: unknown section [{section}] (known: {', '.join(SECTIONS)})")
        if not isinstance(value, dict):
            raise InputError(f"{path}: {section} must be a table [{section}]")
        unknown = set(value) - SECTIONS[section]
        if unknown:
            raise InputError(f"{path}: unknown key {sorted(unknown)[0]!r} in [{section}]")
    if "grid" not in data:
        raise InputError(f"{path}: no [grid] section")
    grid = {**DEFAULTS, **data["grid"]}
    for key in ("h0_um", "bulk_mN_per_m", "shear_mN_per_m", "tension_mN_per_m"):
        if key not in grid:
            raise InputError(f"{path}: [grid] needs {key}")
    axes = {}
    for key in GRID_KEYS:
        if key == "bending":
            names = grid[key] if isinstance(grid[key], list) else [grid[key]]
            bad = [n for n in names if n not in BENDING_VARIANTS]
            if bad or not names:
                raise InputError(f"{path}: [grid] bending must be among {', '.join(BENDING_VARIANTS)} (got {bad or names})")
            axes[key] = names
        else:
            axes[key] = _numbers(path, key, grid[key])
    solver = data.get("solver", {})
    method = solver.get("method", "fast")
    if method not in ("fast", "explicit"):
        raise InputError(f"{path}: [solver] method must be fast or explicit (got {method!r})")
    resolution, timeout = solver.get("resolution", 1.0), solver.get("timeout_s", 600.0)
    for key, value in (("resolution", resolution), ("timeout_s", timeout)):
        if isinstance(value, bool) or not isinstance(value, (int, float)) or value <= 0:
            raise InputError(f"{path}: [solver] {key} must be a positive number (got {value!r})")
    shells = []
    for combo in itertools.product(*(axes[k] for k in GRID_KEYS)):
        p = dict(zip(GRID_KEYS, combo))
        try:
            shells.append(Shell(volume_um3=p["volume_um3"], h0_um=p["h0_um"], dh_um=p["dh_um"],
                                bulk_mN_per_m=p["bulk_mN_per_m"], shear_mN_per_m=p["shear_mN_per_m"],
                                tension_mN_per_m=p["tension_mN_per_m"], thickness_um=p["thickness_um"],
                                bending=p["bending"], resolution=float(resolution)))
        except InputError as err:
            raise InputError(f"{path}: [grid] {err}") from None
    meta = data.get("campaign", {})
    for key in ("name", "store"):
        if key in meta and not isinstance(meta[key], str):
            raise InputError(f"{path}: [campaign] {key} must be a string")
    faults = {}
    tests = dict(data.get("test", {}))
    noop = tests.pop("noop", False)
    if not isinstance(noop, bool):
        raise InputError(f"{path}: [test] noop must be true or false (got {noop!r})")
    if noop:
        faults.update({row: "noop" for row in range(len(shells))})
    for key, value in tests.items():
        rows = value if isinstance(value, list) else [value]
        for row in rows:
            if isinstance(row, bool) or not isinstance(row, int) or not 0 <= row < len(shells):
                raise InputError(f"{path}: [test] {key} must be grid indices 0..{len(shells) - 1} (got {row!r})")
            faults[row] = key.removesuffix("_task")
    return Campaign(faults=faults, name=meta.get("name", str(path)), store=meta.get("store"), method=method,
                    resolution=float(resolution), timeout_s=float(timeout), shells=tuple(shells),
                    text=raw.decode())
