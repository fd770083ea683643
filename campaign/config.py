"""Campaign files (TOML): the grid of compressions and the solver settings.

    [campaign]  name, store (default path of the HDF5 store), max_tasks
                (the largest campaign accepted, default MAX_TASKS = 100,000),
                task (what one grid point computes, a task kind:
                `campaign.kinds`): `compression` (the default), or
                "MODULE:NAME", the kind NAME that MODULE registers (the
                tables': "analysis.calibration.viscoelastic_table:viscoelastic_table",
                "analysis.afm.tension.shell_table:ramp_table",
                "analysis.afm.tension.powerlaw_grid:powerlaw_table",
                "analysis.afm.synth.protocol_bias:protocol_bias"); a kind other
                than compression needs the fast solver and an elastic grid
                without [montecarlo]
    [grid]      volume_um3, h0_um, dh_um, bulk_mN_per_m, shear_mN_per_m,
                tension_mN_per_m, thickness_um: a number or a list of numbers;
                bending: a name or a list of `standard`, `double`, `none`;
                optional viscosity_Pa_s and frequency_hz (both or neither): a
                viscous interior oscillated at f, K*(ω) (`solver.viscous`).
                Dimensionless axes in place of the absolute ones (one of each
                pair): h_tilde for h0_um (h0 = 2 R_cell(V) h̃ + Δh/2, so the
                compression's mean height is h̃), ks_tilde for shear_mN_per_m
                (K_S = K̃_S K_B), gamma_tilde for tension_mN_per_m
                (γ_a = γ̃_a K_B): a grid over (h̃, K̃_S, γ̃_a) at any V and K_B
    [solver]    method (`fast`|`explicit`), resolution, timeout_s (per task,
                600), memory_limit_mb (per task process, default the node's
                memory shared among its ranks: `campaign.isolation`), retries
                (of a task that crashed its process or did not answer, 0)
    [montecarlo] the Monte-Carlo error trials (SPEC 5, `campaign.trials`):
                nu (true Poisson ratios, each mapped to the grid's K_S closest to
                K_B (1-ν)/(1+ν), within 0.01 in ν), cells (N per study, 55),
                studies (repetitions, 100), volume_error_rel_sd (0.075),
                height_error_sd_um (0.5), height_error_mode (`per_cell`,
                `per_height` or both, default both), tension_mN_per_m (the γ_a
                values a model cell draws from, default all of the grid's),
                bending (default all of the grid's), seed (0). The grid must
                hold one volume_um3, dh_um, bulk_mN_per_m and thickness_um.
    [protocol]  a kind's whose parameters are the protocol's (and only its,
                `campaign.protocol_grid.PROTOCOL_PARAMS`): exponents (pairs
                [β_B, β_S]), wait_s, frequency_hz (a number or a list each;
                `campaign.protocol_grid`); the campaign's tasks are the grid's
                shells times their product, the protocol fastest
    [params]    a kind's with parameters of its own (`campaign.kinds.Kind.params`,
                not the protocol's): each of them, and only them, a number or a
                list (`campaign.params_grid`); the campaign's tasks are the
                grid's shells times their product, the parameters fastest
    [test]      for the test suite only: read by the module the environment
                variable CORTEX_TASK_HOOKS names (`campaign.task_hooks`; the
                suite's `tests/faults.py`: injected faults, no-op tasks, a
                made-up law, sleeps); refused (exit status 2) without it

The grid is the Cartesian product of the lists (`campaign.grid.Grid`, whose
shells are made when asked for). Every compression is checked with
`solver.model.Shell`'s checks (on a cover of the grid, `campaign.grid.check`),
so an impossible point (Δh ≥ h0, h0 above the free sphere, a negative
modulus) is refused before anything is written.

Too big a campaign is refused before it is built: its task count, the
product of the grid's list lengths n = Π_k len(list_k) plus the Monte-Carlo
trial tasks (len(bending) · len(nu) · len(height_error_mode) · studies), is
counted from the list lengths alone and must not exceed `[campaign]
max_tasks`. The default, MAX_TASKS = 100,000, makes a store of about 50 MB
(some 500 bytes a row); checking 100,000 compressions takes 16 ms here,
fingerprinting and naming them (as a store is made, from the grid's axes:
`campaign.grid.Grid.texts`) 0.07 and 0.1 s.
"""

import hashlib
import itertools
import math
import os
import tomllib
from dataclasses import dataclass, field
from functools import cached_property

from campaign import task_hooks
from campaign.kinds import Kind, find as find_kind
from campaign.grid import GRID_KEYS, OPTIONAL, Grid, check as check_grid
from campaign.params_grid import ParamGrid, params_axes
from campaign.store.schema import PARAMS, RESULTS
from campaign.protocol_grid import PROTOCOL_KEYS, PROTOCOL_PARAMS, BiasGrid, protocol_axes
from campaign.task_key import TaskNumbers
from campaign.trials import MODES, Study, grid_shear
from solver.compression import METHODS
from solver.elasticity import poisson_ratio, shear_modulus
from common.errors import InputError
from solver.model import BENDING_VARIANTS

RATIO_AXES = {"h0_um": "h_tilde", "shear_mN_per_m": "ks_tilde", "tension_mN_per_m": "gamma_tilde"}
DEFAULTS = {"volume_um3": 4300.0, "dh_um": 0.5, "thickness_um": 0.2, "bending": "standard"}
MAX_TASKS = 100_000
SECTIONS = {"campaign": {"name", "store", "max_tasks", "task"},
            "grid": set(GRID_KEYS) | set(RATIO_AXES.values()),
            "solver": {"method", "resolution", "timeout_s", "memory_limit_mb", "retries"},
            "montecarlo": {"nu", "cells", "studies", "volume_error_rel_sd", "height_error_sd_um",
                           "height_error_mode", "tension_mN_per_m", "bending", "seed"},
            "protocol": set(PROTOCOL_KEYS),
            "params": None,     # its keys: the task kind's parameters (`campaign.params_grid`)
            "test": None}       # its keys: the hooks' module's to check (`campaign.task_hooks`)
MC_DEFAULTS = {"cells": 55, "studies": 100, "volume_error_rel_sd": 0.075, "height_error_sd_um": 0.5,
               "height_error_mode": list(MODES), "seed": 0}


@dataclass(frozen=True)
class Campaign:
    name: str
    store: str | None
    method: str
    resolution: float
    timeout_s: float
    shells: Grid | BiasGrid | ParamGrid   # every compression (or protocol node, parameter point), in grid order (made when asked for)
    text: str              # the file's text, kept in the store
    test: task_hooks.TaskHooks | None = None   # the [test] section (the test suite's only)
    studies: tuple = ()    # Monte-Carlo trial tasks (`campaign.trials.Study`), after the compressions
    trial_cells: int = 0   # N, cells per study
    memory_limit_mb: float | None = None   # per task process; None: the node's share (`campaign.isolation`)
    retries: int = 0       # of a task that crashed its process or did not answer
    kind: Kind = field(default_factory=lambda: find_kind("compression"))   # what a grid point computes


    @property
    def task(self) -> str:
        """The name of its task kind."""
        return self.kind.name

    @cached_property
    def fingerprint(self):
        """What identifies the campaign's compressions: refuses a store made from another grid.
        sha256 of repr([shell.to_dict(), ...]) + method + repr(resolution), fed to the hash
        4,096 shells at a time so that a million tasks never make one long text;
        the task kind's name and version ('NAME@VERSION', `campaign.kinds.Kind.stamp`) after them."""
        h, texts = hashlib.sha256(b"["), self.shells.reprs()
        for i, chunk in enumerate(iter(lambda: list(itertools.islice(texts, 4096)), [])):
            h.update(((", " if i else "") + ", ".join(chunk)).encode())
        h.update(("]" + self.method + repr(self.resolution) + self.kind.stamp()).encode())
        return h.hexdigest()

    @cached_property
    def numbers(self) -> TaskNumbers:
        """Its tasks' numbers (`campaign.task_key`): the compressions, then the trial tasks."""
        return TaskNumbers(len(self.shells), len(self.studies))

    @property
    def trials_fingerprint(self):
        """What identifies its Monte-Carlo trials ('' without any)."""
        if not self.studies:
            return ""
        from campaign.trials import TRIAL_KIND
        key = repr([s.task_id for s in self.studies]) + repr(self.trial_cells) + TRIAL_KIND.stamp()
        return hashlib.sha256(key.encode()).hexdigest()


def _numbers(path, key, value):
    values = value if isinstance(value, list) else [value]
    if not values:
        raise InputError(f"{path}: [grid] {key} is an empty list: the grid would be empty")
    for v in values:
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise InputError(f"{path}: [grid] {key} must be numbers (got {v!r})")
    return [float(v) for v in values]


def load(path: str | os.PathLike[str]) -> Campaign:
    """Read and validate a campaign file; InputError with one line if it is wrong."""
    raw, data = _read_toml(path)
    grid = _grid_section(path, data)
    ratios = _ratio_axes(path, grid)
    axes = _axes(path, grid, ratios)
    method, resolution, timeout = _solver_section(path, data.get("solver", {}))
    memory_limit_mb, retries = _isolation_settings(path, data.get("solver", {}))
    meta = _campaign_section(path, data.get("campaign", {}))
    kind = _kind(path, meta, grid, method, "montecarlo" in data)
    limit = _max_tasks(path, meta)
    protocol = _protocol(path, data, kind)
    own = params_axes(path, data["params"], tuple(kind.params)) if "params" in data else {}
    points = math.prod(len(v) for v in (protocol or own).values())
    _refuse_above(path, math.prod(len(axes[k]) for k in GRID_KEYS) * points, limit, "compressions")
    shells = check_grid(path, axes, ratios, resolution)
    if protocol:
        shells = BiasGrid(shells, protocol)
    elif own:
        shells = ParamGrid(shells, own)
    test = task_hooks.parse(path, data["test"], len(shells)) if "test" in data else None
    mc = data.get("montecarlo")
    _check_montecarlo_grid(path, mc, grid, ratios)
    studies = _studies(path, {**MC_DEFAULTS, **mc}, axes, shells, limit) if mc is not None else ()
    return Campaign(test=test, name=meta.get("name", str(path)), store=meta.get("store"), method=method,
                    resolution=resolution, timeout_s=timeout, shells=shells,
                    text=raw.decode(), studies=studies, trial_cells=mc["cells"] if studies else 0,
                    memory_limit_mb=memory_limit_mb, retries=retries, kind=kind)


def _read_toml(path):
    """The file's bytes and its TOML tables, every section and key a known one."""
    try:
        with open(path, "rb") as fh:
            raw = fh.read()
        data = tomllib.loads(raw.decode())
    except FileNotFoundError:
        raise InputError(f"{path}: no such campaign file") from None
    except IsADirectoryError:
        raise InputError(f"{path}: is a folder, not a campaign file") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as err:
        raise InputError(f"{path}: not valid TOML ({err})") from None
    for section, value in data.items():
        if section not in SECTIONS:
            raise InputError(f"{path}: unknown section [{section}] (known: {', '.join(SECTIONS)})")
        if not isinstance(value, dict):
            raise InputError(f"{path}: {section} must be a table [{section}]")
        allowed = SECTIONS[section]
        unknown = set(value) - allowed if allowed is not None else set()
        if unknown:
            raise InputError(f"{path}: unknown key {sorted(unknown)[0]!r} in [{section}]")
    return raw, data


def _grid_section(path, data):
    """[grid] with the defaults filled in."""
    if "grid" not in data:
        raise InputError(f"{path}: no [grid] section")
    grid = {**DEFAULTS, **data["grid"]}
    if "bulk_mN_per_m" not in grid:
        raise InputError(f"{path}: [grid] needs bulk_mN_per_m")
    return grid


def _axes(path, grid, ratios):
    """Each grid key's list of values (dimensionless ones where given in their place)."""
    axes = {}
    for key in GRID_KEYS:
        if key in ratios:
            axes[key] = ratios[key]
        elif key == "bending":
            names = grid[key] if isinstance(grid[key], list) else [grid[key]]
            bad = [n for n in names if n not in BENDING_VARIANTS]
            if bad or not names:
                raise InputError(f"{path}: [grid] bending must be among {', '.join(BENDING_VARIANTS)} (got {bad or names})")
            axes[key] = names
        elif key in OPTIONAL and key not in grid:
            axes[key] = [None]
        else:
            axes[key] = _numbers(path, key, grid[key])
    return axes


def _solver_section(path, solver):
    """[solver]: method (one of `solver.compression.METHODS`), resolution, timeout_s."""
    method = solver.get("method", "fast")
    if method not in METHODS:
        raise InputError(f"{path}: [solver] method must be one of {', '.join(METHODS)} (got {method!r})")
    resolution, timeout = solver.get("resolution", 1.0), solver.get("timeout_s", 600.0)
    for key, value in (("resolution", resolution), ("timeout_s", timeout)):
        if isinstance(value, bool) or not isinstance(value, (int, float)) or value <= 0:
            raise InputError(f"{path}: [solver] {key} must be a positive number (got {value!r})")
    return method, float(resolution), float(timeout)


def _isolation_settings(path, solver):
    """[solver] memory_limit_mb (a positive number or absent) and retries (an integer >= 0)."""
    limit, retries = solver.get("memory_limit_mb"), solver.get("retries", 0)
    if limit is not None and (isinstance(limit, bool) or not isinstance(limit, (int, float))
                              or not 0 < limit < math.inf):
        raise InputError(f"{path}: [solver] memory_limit_mb must be a positive number of MB (got {limit!r})")
    if isinstance(retries, bool) or not isinstance(retries, int) or retries < 0:
        raise InputError(f"{path}: [solver] retries must be an integer >= 0 (got {retries!r})")
    return (None if limit is None else float(limit)), retries


def _campaign_section(path, meta):
    for key in ("name", "store"):
        if key in meta and not isinstance(meta[key], str):
            raise InputError(f"{path}: [campaign] {key} must be a string")
    return meta


def _kind(path, meta, grid, method, montecarlo):
    """[campaign] task: its kind (`campaign.kinds.find`); a kind other than compression (a table's
    node: a linearisation, a continuation, a recording) needs the fast solver and an elastic cell,
    and has no trials."""
    kind = find_kind(meta.get("task", "compression"), f"{path}: [campaign] task")
    if kind.compute is not None:
        if method != "fast":
            raise InputError(f"{path}: [campaign] task {kind.name} needs [solver] method = \"fast\"")
        if montecarlo or any(key in grid for key in OPTIONAL):
            raise InputError(f"{path}: [campaign] task {kind.name} takes elastic cells without "
                             "[montecarlo] (drop viscosity_Pa_s, frequency_hz and [montecarlo])")
    taken = set(kind.params) & set(PARAMS + RESULTS + tuple(kind.results))
    if taken:
        raise InputError(f"{path}: [campaign] task {kind.name}: its parameters {', '.join(sorted(taken))} "
                         "are a store's columns already")
    return kind


def _protocol(path, data, kind):
    """The [protocol] axes of a campaign whose kind takes the protocol's parameters
    (`campaign.protocol_grid`), {} for another; the section belongs to such a kind alone, as
    `[params]` to a kind with parameters of its own (`campaign.params_grid`)."""
    own = bool(kind.params) and tuple(kind.params) != PROTOCOL_PARAMS
    if own != ("params" in data):
        raise InputError(f"{path}: [campaign] task ({kind.name!r} here) is a kind with parameters of its own "
                         f"({', '.join(kind.params) or 'none here'}), and a [params] section giving them go together")
    if own:
        return {}
    if bool(kind.params) != ("protocol" in data):
        raise InputError(f"{path}: [campaign] task ({kind.name!r} here) is a kind with the protocol's "
                         "parameters, as \"analysis.afm.synth.protocol_bias:protocol_bias\", "
                         "and a [protocol] section go together")
    return protocol_axes(path, data["protocol"]) if "protocol" in data else {}


def _check_montecarlo_grid(path, mc, grid, ratios):
    """Trials need elastic cells on absolute axes."""
    if mc is not None and any(key in grid for key in OPTIONAL):
        raise InputError(f"{path}: [montecarlo] trials use elastic cells: drop viscosity_Pa_s and "
                         "frequency_hz from [grid] (or the [montecarlo] section)")
    if mc is not None and ratios:
        raise InputError(f"{path}: [montecarlo] needs the absolute [grid] axes h0_um, shear_mN_per_m and "
                         f"tension_mN_per_m (got {', '.join(RATIO_AXES[k] for k in ratios)})")


def _max_tasks(path, meta):
    """[campaign] max_tasks (a positive integer), MAX_TASKS without it."""
    limit = meta.get("max_tasks", MAX_TASKS)
    if isinstance(limit, bool) or not isinstance(limit, int) or limit < 1:
        raise InputError(f"{path}: [campaign] max_tasks must be a positive integer (got {limit!r})")
    return limit


def _refuse_above(path, count, limit, what):
    """InputError if a campaign of `count` tasks (`what`) exceeds `limit`; nothing is built."""
    if count > limit:
        raise InputError(f"{path}: {count:,} {what} exceed the limit of {limit:,} tasks; make the grid "
                         "smaller, or raise [campaign] max_tasks if this machine can hold it")


def _ratio_axes(path, grid):
    """The dimensionless axes given in place of absolute ones: {absolute key: values}."""
    ratios = {}
    for key, ratio in RATIO_AXES.items():
        if (key in grid) == (ratio in grid):
            raise InputError(f"{path}: [grid] needs exactly one of {key} and {ratio}")
        if ratio in grid:
            values = _numbers(path, ratio, grid[ratio])
            if any(v <= 0 for v in values):
                raise InputError(f"{path}: [grid] {ratio} must be > 0 (got {min(values):g})")
            ratios[key] = values
    return ratios


def _mc_number(path, key, value, low, high=float("inf"), integer=False):
    kind = int if integer else (int, float)
    if isinstance(value, bool) or not isinstance(value, kind) or not low <= value < high:
        what = "an integer" if integer else "a number"
        raise InputError(f"{path}: [montecarlo] {key} must be {what} in [{low:g}, {high:g}) (got {value!r})")
    return value


def _mc_names(path, key, value, allowed):
    names = value if isinstance(value, list) else [value]
    bad = [n for n in names if n not in allowed]
    if bad or not names or len(set(names)) < len(names):
        raise InputError(f"{path}: [montecarlo] {key} must be distinct values among "
                         f"{', '.join(map(str, allowed))} (got {value!r})")
    return names


def _studies(path, mc, axes, shells, limit=MAX_TASKS):
    """The Monte-Carlo trial tasks: one `Study` per (bending, ν, mode, repetition);
    refused if they and the compressions exceed `limit` tasks."""
    for key in ("volume_um3", "dh_um", "bulk_mN_per_m", "thickness_um"):
        if len(axes[key]) != 1:
            raise InputError(f"{path}: [montecarlo] needs one [grid] {key} (got {len(axes[key])}): "
                             "a model cell has one")
    if "nu" not in mc:
        raise InputError(f"{path}: [montecarlo] needs nu, the true Poisson ratios")
    nus = mc["nu"] if isinstance(mc["nu"], list) else [mc["nu"]]
    if not nus:
        raise InputError(f"{path}: [montecarlo] nu is an empty list")
    bulk = axes["bulk_mN_per_m"][0]
    if bulk <= 0:
        raise InputError(f"{path}: [montecarlo] needs [grid] bulk_mN_per_m > 0 (ν is undefined)")
    shears: dict[float, float] = {}
    for nu in nus:
        _mc_number(path, "nu", nu, -1.0, 1.0)
        hit = grid_shear(nu, bulk, axes["shear_mN_per_m"])
        if hit is None:
            want = shear_modulus(nu, bulk)
            raise InputError(f"{path}: [montecarlo] nu = {nu:g} has no [grid] shear_mN_per_m within "
                             f"0.01 in nu; add K_S = {want:.4g} mN/m (K_B (1-nu)/(1+nu)) to the grid")
        if hit[0] in shears:
            raise InputError(f"{path}: [montecarlo] nu = {nu:g} and {shears[hit[0]]:g} both map to "
                             f"K_S = {hit[0]:g} mN/m")
        shears[hit[0]] = nu
    cells = _mc_number(path, "cells", mc["cells"], 1, 100_001, integer=True)
    repeats = _mc_number(path, "studies", mc["studies"], 1, 100_001, integer=True)
    sd_v = float(_mc_number(path, "volume_error_rel_sd", mc["volume_error_rel_sd"], 0.0, 0.5))
    top = min(axes["h0_um"]) - axes["dh_um"][0]
    sd_h = float(_mc_number(path, "height_error_sd_um", mc["height_error_sd_um"], 0.0, top))
    seed = _mc_number(path, "seed", mc["seed"], 0, 2**63, integer=True)
    modes = _mc_names(path, "height_error_mode", mc["height_error_mode"], MODES)
    bendings = _mc_names(path, "bending", mc.get("bending", axes["bending"]), axes["bending"])
    tensions = mc.get("tension_mN_per_m", axes["tension_mN_per_m"])
    tensions = tensions if isinstance(tensions, list) else [tensions]
    if not tensions or any(t not in axes["tension_mN_per_m"] or isinstance(t, bool) for t in tensions) \
            or len(set(tensions)) < len(tensions):
        raise InputError(f"{path}: [montecarlo] tension_mN_per_m must be distinct values of [grid] "
                         f"tension_mN_per_m {axes['tension_mN_per_m']} (got {mc['tension_mN_per_m']!r})")
    _refuse_above(path, len(shells) + len(bendings) * len(shears) * len(modes) * repeats, limit,
                  "tasks (compressions and Monte-Carlo trial tasks)")
    row = {(s.h0_um, s.shear_mN_per_m, s.tension_mN_per_m, s.bending): i for i, s in enumerate(shells)}
    heights = tuple(axes["h0_um"])
    studies = []
    for bending, (shear, nu), mode in itertools.product(bendings, shears.items(), modes):
        for rep in range(repeats):
            studies.append(Study(
                bending=bending, nu_true=poisson_ratio(bulk, shear), height_error_mode=mode, study=rep,
                n_cells=cells, volume_um3=axes["volume_um3"][0], dh_um=axes["dh_um"][0],
                bulk_mN_per_m=bulk, shear_mN_per_m=shear, heights_um=heights,
                tensions_mN_per_m=tuple(float(t) for t in tensions), volume_error_rel_sd=sd_v,
                height_error_sd_um=sd_h, seed=seed,
                rows=tuple(tuple(row[(h, shear, float(t), bending)] for h in heights) for t in tensions)))
    return tuple(studies)
