"""`cortex analysis viscosity STORE --out DIR`: the viscous-interior study of a campaign
with viscosity_Pa_s and frequency_hz axes (SPEC 7, `solver.viscous`).

Per task the relative change of the measured modulus, |K*(ω)|/K - 1 with K the
same cell without viscosity (`elastic_modulus_mN_per_m`), and the loss angle
arg K*. Since the interior is quasi-static Stokes flow, K* depends on η and ω
only through ωη; the elastic calibration is valid to 1 % where
|K*|/K - 1 < 0.01 at every height. Writes DIR/viscosity.csv, the figure
DIR/viscosity.png/.pdf (|K*|/K - 1 and the loss angle against η, one line per
frequency, one line style per h0) and DIR/viscosity.md (the table and the
validity limit per frequency).
"""

from __future__ import annotations

from os import PathLike
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from analysis.calibration.command.figures import _save, plt
from campaign.store.reader import read_results
from common.errors import InputError

if TYPE_CHECKING:
    from outputs.ownership import OutputDir

TOLERANCE = 0.01      # the 1 % of "the elastic calibration is valid"
STYLES = ("-", "--", ":", "-.")
FLOOR = 1e-9          # |K*|/K - 1 below this is round-off (the elastic K is solved to ~1e-10)


def table(store: str | PathLike[str]) -> pd.DataFrame:
    """The done viscous tasks: h0, h̃, η, f, |K*|, K, |K*|/K, loss angle."""
    frame = read_results(store)
    frame = frame[(frame["state"] == "done") & frame["viscosity_Pa_s"].notna()]
    if frame.empty:
        raise InputError(f"{store}: no finished task with a viscosity (grid axes viscosity_Pa_s, "
                         "frequency_hz)")
    out = frame[["h0_um", "h_tilde", "viscosity_Pa_s", "frequency_hz", "modulus_mN_per_m",
                 "elastic_modulus_mN_per_m", "loss_angle_rad"]].copy()
    out["modulus_ratio"] = out["modulus_mN_per_m"] / out["elastic_modulus_mN_per_m"]
    return out.sort_values(["frequency_hz", "h0_um", "viscosity_Pa_s"]).reset_index(drop=True)


def validity(tab: pd.DataFrame, tolerance: float = TOLERANCE) -> list[dict[str, float]]:
    """Per frequency: the largest η of the grid with |K*|/K - 1 < tolerance at every
    height (and every smaller η), NaN if even the smallest fails; and ω η there."""
    rows = []
    for f, group in tab.groupby("frequency_hz"):
        worst = group.groupby("viscosity_Pa_s")["modulus_ratio"].agg(lambda r: np.max(np.abs(r - 1)))
        ok = (worst < tolerance).to_numpy()
        n = len(ok) if ok.all() else int(np.argmin(ok))
        eta = float(worst.index[n - 1]) if n else float("nan")
        rows.append({"frequency_hz": f, "largest_valid_viscosity_Pa_s": eta,
                     "omega_eta_Pa": 2 * np.pi * f * eta,
                     "worst_change_at_largest_viscosity": float(worst.iloc[-1] if len(worst) else np.nan)})
    return rows


def figure(tab: pd.DataFrame, out: OutputDir) -> list[Path]:
    """|K*|/K and the loss angle against η, one colour per frequency, one style per h0."""
    fig, (a, b) = plt.subplots(1, 2, figsize=(9.0, 3.6), constrained_layout=True)
    heights = sorted(tab["h0_um"].unique())
    for i, (f, group) in enumerate(tab.groupby("frequency_hz")):
        colour = f"C{i}"
        for j, h0 in enumerate(heights):
            g = group[group["h0_um"] == h0]
            label = f"f = {f:g} Hz" if j == 0 else None
            style = STYLES[j % len(STYLES)]
            change = np.maximum(g["modulus_ratio"] - 1, FLOOR)      # round-off below FLOOR
            a.plot(g["viscosity_Pa_s"], change, style, color=colour, marker=".", label=label)
            b.plot(g["viscosity_Pa_s"], g["loss_angle_rad"], style, color=colour, marker=".")
    a.axhline(TOLERANCE, color="grey", lw=0.8)
    a.set_ylim(FLOOR, None)
    a.set(xscale="log", yscale="log", xlabel="interior viscosity eta [Pa s]",
          ylabel="|K*| / K - 1 (K: same cell without viscosity) [dimensionless]",
          title="change of the measured modulus; grey: 1 %")
    b.set(xscale="log", xlabel="interior viscosity eta [Pa s]", ylabel="loss angle arg K* [rad]",
          title="h0 = " + ", ".join(f"{h:g}" for h in heights) + " um: " + ", ".join(
              STYLES[j % len(STYLES)] for j in range(len(heights))))
    a.legend(fontsize=7)
    return _save(fig, out, "viscosity")


def _markdown(tab: pd.DataFrame, limits: Any) -> str:
    lines = ["# Viscous interior: |K*|/K and loss angle", "",
             "| f [Hz] | eta [Pa s] | h0 [um] | h~ | K [mN/m] | abs(K*) [mN/m] | abs(K*)/K - 1 | loss angle [rad] |",
             "|---|---|---|---|---|---|---|---|"]
    for r in tab.itertuples():
        lines.append(f"| {r.frequency_hz:g} | {r.viscosity_Pa_s:.3g} | {r.h0_um:g} | {r.h_tilde:.3f} | "
                     f"{r.elastic_modulus_mN_per_m:.4g} | {r.modulus_mN_per_m:.4g} | "
                     f"{r.modulus_ratio - 1:.3g} | {r.loss_angle_rad:.3g} |")
    lines += ["", f"## Where the elastic calibration is valid to {TOLERANCE:.0%}", "",
              "| f [Hz] | largest eta of the grid [Pa s] | omega eta [Pa] |", "|---|---|---|"]
    for r in limits:
        lines.append(f"| {r['frequency_hz']:g} | {r['largest_valid_viscosity_Pa_s']:.3g} | "
                     f"{r['omega_eta_Pa']:.3g} |")
    return "\n".join(lines) + "\n"


def run(store: str | PathLike[str], out: str | PathLike[str]) -> Path:
    """Write DIR/viscosity.csv, .png, .pdf and .md; returns the report's path.
    DIR holds only what cortex wrote there (`outputs.ownership.OutputDir`)."""
    from outputs.ownership import OutputDir
    store = Path(store)
    if not store.is_file():
        raise InputError(f"{store}: no such campaign store")
    folder = OutputDir(out)
    folder.check(["viscosity.csv", "viscosity.png", "viscosity.pdf", "viscosity.md"])
    tab = table(store)
    limits = validity(tab)
    with folder.writing("viscosity.csv") as path:
        tab.to_csv(path, index=False)
    figure(tab, folder)
    with folder.writing("viscosity.md") as path:
        path.write_text(_markdown(tab, limits))
    return path
