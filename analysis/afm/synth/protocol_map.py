"""The protocol's bias map (SPEC 12) from a finished protocol-bias campaign store
(`campaigns/protocol.toml`, nodes of `analysis.afm.synth.protocol_bias`): a JSON table and figures.

Per node (β_B, β_S, T_w, f, h̃, K̃_S, γ̃_a, V) the segment fit of the simulated recording against
the relaxed-state model:

    modulus_ratio = |K*|_td / |K*|_model,   loss_angle_error_rad = δ_td - δ_model,

h̃ = h_m / (2 R_cell(V)) with h_m = h0 - Δh/2, K̃_S = K_S/K_B, γ̃_a = γ_a/K_B. The model is called
off where |δ_td - δ_model| > LOSS_ANGLE_TOLERANCE_RAD or |modulus_ratio - 1| > MODULUS_TOLERANCE.
`summary` gives the largest of both over the done nodes (a failed node, where the time domain did
not converge, is listed apart), and per T_w and per f (over the other axes);
the figures (`figures`) plot, against T_w, per f (one panel each) and per (β_B, β_S) (one line
each) the node of the largest |error| over h̃, K̃_S, γ̃_a, signed.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from common.errors import InputError
from solver.geometry import cell_radius

if TYPE_CHECKING:
    from outputs.ownership import OutputDir

TASK = "protocol_bias"
LOSS_ANGLE_TOLERANCE_RAD = 0.005
MODULUS_TOLERANCE = 0.01
AXES = ("bulk_exponent", "shear_exponent", "wait_s", "frequency_hz", "h_tilde", "ks_tilde", "gamma_tilde",
        "volume_um3")
VALUES = ("modulus_mN_per_m", "model_modulus_mN_per_m", "modulus_ratio", "loss_angle_rad",
          "model_loss_angle_rad", "loss_angle_error_rad", "bulk_loss_angle_rad", "shear_loss_angle_rad",
          "gamma_eff_mN_per_m", "solves", "wall_s")
FIGURES = ("protocol_map_loss_angle", "protocol_map_modulus")


def nodes(path: str | os.PathLike[str]) -> pd.DataFrame:
    """One row per node of the finished store: `state`, `error`, AXES and VALUES (NaN where the
    node failed). InputError for a store of another campaign, or one with nodes still to run."""
    import tomllib

    from campaign.store.reader import read_provenance, read_results
    text = read_provenance(path).get("config_text", "")        # the campaign file, as run
    task = str((tomllib.loads(text) if text else {}).get("campaign", {}).get("task", ""))
    if task.rpartition(":")[2] != TASK:
        raise InputError(f"{path}: not a store of a protocol-bias campaign ([campaign] task = "
                         f"\"analysis.afm.synth.protocol_bias:{TASK}\": campaigns/protocol.toml)")
    rows = read_results(path)
    unfinished = int(rows["state"].isin(["pending", "running"]).sum())
    if unfinished or not (rows["state"] == "done").any():
        raise InputError(f"{path}: {unfinished or len(rows)} of {len(rows)} nodes not done; finish the "
                         "campaign (run it again: it resumes)")
    radius = np.array([float(cell_radius(v)) for v in rows["volume_um3"]])
    out = pd.DataFrame({"state": rows["state"], "error": rows["error"],
                        "bulk_exponent": rows["bulk_exponent"], "shear_exponent": rows["shear_exponent"],
                        "wait_s": rows["wait_s"], "frequency_hz": rows["protocol_frequency_hz"],
                        "h_tilde": ((rows["h0_um"] - 0.5 * rows["dh_um"]) / (2.0 * radius)).round(9),
                        "ks_tilde": (rows["shear_mN_per_m"] / rows["bulk_mN_per_m"]).round(9),
                        "gamma_tilde": (rows["tension_mN_per_m"] / rows["bulk_mN_per_m"]).round(9),
                        "volume_um3": rows["volume_um3"]})
    for key in VALUES:
        out[key] = rows[key]
    return out


def _worst(table: pd.DataFrame, by: str) -> list[dict[str, float]]:
    """Per value of `by`: the largest |loss-angle error| and |modulus ratio - 1| over the other axes."""
    g = table.assign(loss=table["loss_angle_error_rad"].abs(), modulus=(table["modulus_ratio"] - 1).abs())
    worst = g.groupby(by)[["loss", "modulus"]].max()
    return [{by: float(k), "largest_abs_loss_angle_error_rad": float(r["loss"]),
             "largest_abs_modulus_error": float(r["modulus"])} for k, r in worst.iterrows()]


def summary(table: pd.DataFrame) -> dict[str, Any]:
    """The largest errors, how many nodes pass the tolerances, and the worst per T_w and per f."""
    loss, modulus = table["loss_angle_error_rad"].abs(), (table["modulus_ratio"] - 1).abs()
    off = (loss > LOSS_ANGLE_TOLERANCE_RAD) | (modulus > MODULUS_TOLERANCE)
    return {"nodes": len(table), "loss_angle_tolerance_rad": LOSS_ANGLE_TOLERANCE_RAD,
            "modulus_tolerance": MODULUS_TOLERANCE,
            "largest_abs_loss_angle_error_rad": float(loss.max()), "largest_abs_modulus_error": float(modulus.max()),
            "nodes_off": int(off.sum()), "nodes_loss_angle_off": int((loss > LOSS_ANGLE_TOLERANCE_RAD).sum()),
            "nodes_modulus_off": int((modulus > MODULUS_TOLERANCE).sum()),
            "by_wait": _worst(table, "wait_s"), "by_frequency": _worst(table, "frequency_hz"),
            "total_wall_s": float(table["wall_s"].sum()), "total_solves": int(table["solves"].sum())}


def from_store(path: str | os.PathLike[str]) -> dict[str, Any]:
    """The map's document: each axis's values, the `summary` over the done nodes, every done node's
    row (`nodes`) and the failed ones (`failed`: their axes and the error: where the time domain
    did not converge)."""
    table = nodes(path)
    axes: dict[str, Any] = {k: sorted(set(table[k].tolist())) for k in AXES}
    axes["exponents"] = sorted(set(zip(table["bulk_exponent"].tolist(), table["shear_exponent"].tolist())))
    done = table["state"] == "done"
    return {"axes": axes, "summary": {**summary(table[done]), "nodes_failed": int((~done).sum())},
            "nodes": table[done].drop(columns=["state", "error"]).to_dict("records"),
            "failed": table.loc[~done, ["error", *AXES]].to_dict("records")}


def figures(doc: dict[str, Any], out: OutputDir) -> list[Path]:
    """The two figures (png and pdf): loss-angle error and |K*| ratio against T_w, panels per f,
    lines per (β_B, β_S), the node of the largest |error| over the other axes; grey: the tolerance."""
    from analysis.calibration.command.figures import _save, plt
    table = pd.DataFrame(doc["nodes"])
    table["modulus_error"] = table["modulus_ratio"] - 1.0
    paths: list[Path] = []
    for name, key, tol, label in (
            (FIGURES[0], "loss_angle_error_rad", LOSS_ANGLE_TOLERANCE_RAD, "loss angle: time domain - model [rad]"),
            (FIGURES[1], "modulus_error", MODULUS_TOLERANCE, "abs(K*) time domain / model - 1")):
        freqs = doc["axes"]["frequency_hz"]
        fig, axs = plt.subplots(1, len(freqs), figsize=(3.0 * len(freqs) + 1.5, 3.4), sharey=True,
                                constrained_layout=True, squeeze=False)
        for ax, f in zip(axs[0], freqs):
            _panel(ax, table[table["frequency_hz"] == f], key)
            ax.axhspan(-tol, tol, color="0.9", zorder=0)
            ax.set(xscale="log", xlabel="wait T_w [s]", title=f"f = {f:g} Hz")
        axs[0][0].set_ylabel(label)
        axs[0][-1].legend(fontsize=6, title="beta_B, beta_S", title_fontsize=6, loc="best")
        paths += _save(fig, out, name)
    return paths


def _panel(ax: Any, table: pd.DataFrame, key: str) -> None:
    """One line per (β_B, β_S): the signed error of largest magnitude over h̃, K̃_S, γ̃_a, V, per T_w."""
    for i, ((bb, bs), g) in enumerate(table.groupby(["bulk_exponent", "shear_exponent"])):
        worst = g.loc[g.groupby("wait_s")[key].apply(lambda s: s.abs().idxmax())]
        ax.plot(worst["wait_s"], worst[key], marker=".", color=f"C{i % 10}",
                ls="-" if i < 10 else "--", label=f"{bb:g}, {bs:g}")
