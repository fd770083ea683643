"""What `cortex afm tension`'s elastic-shell reading gives for the approach ramp of a power-law
cortex (SPEC 11-12): one simulated ramp, read as the command reads it.

The cell: volume V (R = R_cell), active tension γ_a, a cortex

    K_B(t) = K_B (t/1 s)^-β,   K_S(t) = K̃_S K_B (t/1 s)^-β

(both moduli one β; Prony series, `solver.time_domain.power_law_cortex`), stress-free as the
droplet at the gap h0 (the shell's `h0_um`, just below the free sphere's 2R). The plate ramps at
v from h0 down by Δh (the shell's `dh_um`), simulated in time (`solver.protocol_simulation.simulate`,
FINE: 0.02 µm a step) and sampled every 1/SAMPLES_PER_UM µm. Above h0 the approach is the
tension-only droplet's (`studies.tension_synth.droplet_force_nN`: 0 above 2R), from h0 + Δh + 0.2
µm, so that the window (as deep above the contact as below) finds its baseline. White noise of SD
`NOISE_NN` (seeded by `seed`) is added to every sample. The recording, the gap x as its height
(the dish known), is read by `analysis.afm.tension.pipeline.analyse` by the elastic shell alone
(`Options(power_law=False)`: K̃_S fitted by its profile): the β = 0 reading of the row
`cortex afm tension` writes (`tension_mN_per_m`).

Results: γ_a read/true (`tension_ratio`) with its 95 % interval over the truth (`tension_lo95_ratio`,
`tension_hi95_ratio`), `tension_covered` (1 if the interval holds γ_a, else 0), K_B read
(`bulk_read_mN_per_m`, against K_B at 1 s; 0 where the droplet is returned), K̃_S read
(`shear_ratio_read`, 0 there), the elastic term's Λ, the droplet's T over γ_a on the same window,
`depth_moves` (1 where the nested windows flag the reading), the samples and the window's h̃.

One ramp is one task of the kind `KIND` (`campaign.kinds`; `[campaign] task =
"studies.shell_reading_bias:shell_reading_bias"`, the grid's shells and a `[params]` section of
`beta`, `speed_um_per_s` and `seed`: `campaigns/tension-bias.toml`); `bias_table` turns the store
into the table of docs/tension.md (median γ_a read/true and the intervals' coverage per β and v),
`python -m studies.shell_reading_bias STORE [--json]` prints it (`markdown`, `make tension-bias`).
"""

import math
import sys
from typing import Any

import numpy as np
import pandas as pd

from analysis.afm.tension.pipeline import Options, Trace, analyse
from campaign.kinds import Kind, register
from solver.model import Shell
from solver.protocol import Protocol, Ramp
from solver.protocol_simulation import Sampling, simulate
from solver.time_domain import power_law_cortex
from studies.tension_synth import droplet_force_nN

SAMPLES_PER_UM = 500.0       # samples a µm of plate travel (2 nm apart), at every speed
NOISE_NN = 0.02              # SD of the white force noise (nN)
FREE_ABOVE_UM = 0.2          # the free approach starts this far above h0 + Δh

PARAMS = {"beta": "1", "speed_um_per_s": "µm/s", "seed": "1"}
RESULTS = {"tension_ratio": "1", "tension_lo95_ratio": "1", "tension_hi95_ratio": "1", "tension_covered": "1",
           "bulk_read_mN_per_m": "mN/m", "shear_ratio_read": "1", "elastic_term_lr": "1",
           "droplet_tension_ratio": "1", "depth_moves": "1", "ramp_samples": "1"}


def ramp_recording(shell: Shell, beta: float, speed_um_per_s: float, seed: int) -> tuple[np.ndarray, ...]:
    """(t_s, x_um, F_nN) of the approach ramp (module docstring): the free part, then the simulated one."""
    cortex = power_law_cortex(shell.bulk_mN_per_m, shell.shear_mN_per_m, beta, beta)
    rec = simulate(shell, cortex, Protocol(shell.h0_um, (Ramp(to_um=shell.h0_um - shell.dh_um,
                                                               speed_um_per_s=speed_um_per_s),)),
                   sampling=Sampling(approach_hz=SAMPLES_PER_UM * speed_um_per_s))
    above = np.arange(shell.h0_um + shell.dh_um + FREE_ABOVE_UM, shell.h0_um, -1.0 / SAMPLES_PER_UM)
    x = np.r_[above, rec.height_um]
    force = np.r_[droplet_force_nN(shell.volume_um3, shell.tension_mN_per_m, above), rec.force_nN]
    t = (x[0] - x) / speed_um_per_s
    force = force + NOISE_NN * np.random.default_rng(int(seed)).standard_normal(x.size)
    return t, x, force


def read_ramp(shell: Shell, beta: float, speed_um_per_s: float, seed: int) -> dict[str, float]:
    """One ramp simulated and read by the shell as `cortex afm tension` reads it (module docstring)."""
    t, x, force = ramp_recording(shell, beta, speed_um_per_s, seed)
    trace = Trace("ramp", "simulated", shell.volume_um3, "given", [(0, "approach", t, force, x)], dish_known=True)
    row = analyse(trace, Options(power_law=False)).rows[0]
    gamma = shell.tension_mN_per_m
    lo, hi = row["tension_lo95_mN_per_m"], row["tension_hi95_mN_per_m"]
    return {"tension_ratio": row["tension_mN_per_m"] / gamma,
            "tension_lo95_ratio": lo / gamma, "tension_hi95_ratio": hi / gamma,
            "tension_covered": float(lo <= gamma <= hi), "bulk_read_mN_per_m": row["bulk_modulus_mN_per_m"],
            "shear_ratio_read": _or_zero(row["shear_ratio"]), "elastic_term_lr": row["elastic_term_lr"],
            "droplet_tension_ratio": row["droplet_tension_mN_per_m"] / gamma,
            "depth_moves": float(row["depth_test"] == "moves"), "ramp_samples": float(x.size),
            "h_tilde": row["h_tilde"]}


def _or_zero(value: float) -> float:
    """`value`, 0 where it is NaN (a task's results are finite: K̃_S where the droplet was returned)."""
    return 0.0 if math.isnan(value) else float(value)


def ramp_task(point: Any) -> dict[str, float]:
    """The kind's compute function: a grid point (`campaign.params_grid.ParamPoint`) into its results."""
    v = point.values
    return read_ramp(point.shell, float(v["beta"]), float(v["speed_um_per_s"]), int(v["seed"]))


KIND = register(Kind("shell_reading_bias", 1, RESULTS, ramp_task, params=PARAMS,
                     doc="one power-law ramp read by afm tension's elastic shell"))


def bias_table(rows: pd.DataFrame) -> pd.DataFrame:
    """Per β and v of the finished rows: ramps, median and range of γ_a read/true, the share of
    intervals holding γ_a, median K_B read over K_B(1 s), the share the nested windows flag."""
    done = rows[rows["state"] == "done"].assign(bulk_ratio=lambda d: d["bulk_read_mN_per_m"] / d["bulk_mN_per_m"])
    g = done.groupby(["beta", "speed_um_per_s"])
    return pd.DataFrame({"ramps": g.size(), "tension_ratio_median": g["tension_ratio"].median(),
                         "tension_ratio_min": g["tension_ratio"].min(), "tension_ratio_max": g["tension_ratio"].max(),
                         "coverage": g["tension_covered"].mean(), "bulk_ratio_median": g["bulk_ratio"].median(),
                         "depth_moves": g["depth_moves"].mean()}).reset_index()


def markdown(table: pd.DataFrame) -> str:
    """`bias_table` as the Markdown table of docs/tension.md: per β a row, per speed γ_a read/true
    (median, and min-max over the cells and seeds) and the intervals' coverage."""
    speeds = sorted(table["speed_um_per_s"].unique())
    head = "| β | " + " | ".join(f"{v:g} µm/s: γ_a read/true (range), coverage" for v in speeds) + " |"
    lines = [head, "|---|" + "---|" * len(speeds)]
    for beta, rows in table.groupby("beta"):
        cells = []
        for v in speeds:
            r = rows[rows["speed_um_per_s"] == v].iloc[0]
            cells.append(f"{r.tension_ratio_median:.2f} ({r.tension_ratio_min:.2f}-{r.tension_ratio_max:.2f}), "
                         f"{r.coverage:.0%}".replace("%", " %"))
        lines.append(f"| {beta:g} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    """`python -m studies.shell_reading_bias STORE [--json]`: the store's table (Markdown, or JSON rows)."""
    import argparse

    from campaign.store.reader import read_results
    parser = argparse.ArgumentParser(description="the bias table of a tension-bias campaign's store")
    parser.add_argument("store", help="the campaign's HDF5 store (campaigns/tension-bias.toml)")
    parser.add_argument("--json", action="store_true", help="the table's rows as JSON")
    args = parser.parse_args(argv)
    rows = read_results(args.store)
    table = bias_table(rows)
    failed = int((rows["state"] == "failed").sum())
    print(table.to_json(orient="records", indent=1) if args.json else markdown(table))
    if failed:
        print(f"{failed} ramps failed", file=sys.stderr)


if __name__ == "__main__":
    main()
