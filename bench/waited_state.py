"""The waited-state model against the protocol in time on nodes of the bias map (SPEC 12).

Per node of `campaigns/protocol.toml` (chosen below, or `--nodes i,j,...`): the recording's
segment fit and the relaxed-state model (`analysis.afm.synth.protocol_bias.node_results`), and
the waited-state model (`studies.waited_state`, K_sec,w C_w) at t_w = T_w + t_r/2 (`waited`), its
linear response |K*_w| alone (`linear`), at the middle of the oscillation t_w + 2.5/f
(`waited_mid`), the same linearisation with the prestress of the moduli |K*(f)|
(`prestress_abs`), and two diagnostics from the time domain's own state at the end of the wait
(the node's protocol up to its oscillation, `solver.protocol_simulation.simulate`): its mean tension γ_0 against the waited state's
(`gamma0_ratio`), and the waited state re-solved at the time domain's contact label, the label
held in the response (`at_td_label`: K*_w, tangent). One JSON line per node, errors as
|K*|_td / model - 1 and δ_td - δ_model.

    python bench/waited_state.py [--nodes 0,5,... | --physiological] [--part 0 --parts 2] > nodes.jsonl

(`--physiological`: every shell at β_B 0.1, β_S 0.2 and 0.4, f 0.1 and 1 Hz, T_w = 100 s.)
"""

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from analysis.afm.synth.protocol_bias import node_results
from campaign.config import load
from solver.fast import _newton
from solver.protocol import Oscillate, Protocol
from solver.protocol_simulation import simulate
from solver.time_domain import power_law_cortex
from solver.viscous import Linearised, full_hessian, hold_label, linearise

sys.path.insert(1, str(Path(__file__).resolve().parents[1]))   # `studies`, beside bench/ (not installed)
from studies.prestressed_response import complex_response, prestressed_modulus  # noqa: E402
from studies.waited_state import waited_moduli, waited_state, waited_time_s  # noqa: E402

CAMPAIGN = "campaigns/protocol.toml"
PHYSIOLOGICAL = [(b, s, w, f) for b, s in ((0.1, 0.2), (0.1, 0.4)) for w in (10.0, 100.0) for f in (0.1, 1.0)]
WORST = [(0.4, 0.4, w, f) for w in (10.0, 100.0) for f in (1.0, 10.0)]
CONTROL = [(0.0, 0.0, 100.0, 1.0)]


def shell_key(shell: Any) -> tuple[float, float, float]:
    """(h̃ rounded, K̃_S, γ̃_a) of a grid shell."""
    from solver.geometry import cell_radius
    h_m = shell.h0_um - 0.5 * shell.dh_um
    return (round(h_m / (2 * float(cell_radius(shell.volume_um3))), 3),
            round(shell.shear_mN_per_m / shell.bulk_mN_per_m, 3),
            round(shell.tension_mN_per_m / shell.bulk_mN_per_m, 3))


def chosen(nodes: Any) -> list[int]:
    """Node indices: each physiological point on two shells (rotating through the 8), the worst
    points on the map's worst shell (h̃ 0.7, K̃_S 1.28, γ̃_a 0.032) and on (0.55, 0.16, 0.128),
    the elastic control on one shell."""
    index = {(shell_key(n.shell), (n.bulk_exponent, n.shear_exponent, n.wait_s, n.frequency_hz)): i
             for i, n in enumerate(nodes)}
    shells = sorted({k for k, _ in index})
    picks = [(shells[(2 * j + k * 5) % 8], p) for j, p in enumerate(PHYSIOLOGICAL) for k in (0, 1)]
    picks += [(s, p) for p in WORST for s in ((0.7, 1.28, 0.032), (0.55, 0.16, 0.128))]
    picks += [((0.7, 1.28, 0.032), p) for p in CONTROL]
    return [index[k] for k in picks]


def at_td_label(node: Any, cortex: Any, protocol: Protocol, t_w: float) -> tuple[complex, float]:
    """K*_w of the waited state re-solved at the time domain's contact label (held), and the
    time domain's γ_0 over the waited state's (both at the end of the wait)."""
    shell, f = node.shell, node.frequency_hz
    before = Protocol(protocol.start_um, tuple(s for s in protocol.steps if not isinstance(s, Oscillate)))
    simulated = simulate(shell, cortex, before)
    bulk, shear = waited_moduli(cortex, t_w)
    model = replace(shell, bulk_mN_per_m=bulk, shear_mN_per_m=shear)
    waited = linearise(model)
    u = waited.u.copy()
    u[-2] = simulated.contact_label
    u = _newton(waited.lag, u, waited.zp)[0]
    force = float(-0.5 * waited.lag.newton_system(u, waited.zp, hessian=False)[2])
    lin = Linearised(lag=waited.lag, u=u, zp=waited.zp, H=full_hessian(waited.lag, u, waited.zp),
                     force_nN=force, h_mean_um=waited.h_mean_um, shell=model, held=True)
    hold_label(lin.H, 1.0)
    K = complex_response(lin, model, cortex.bulk.complex_modulus(f), cortex.shear.complex_modulus(f), f)
    return K, float(simulated.force_nN[-1]) / waited.force_nN


def models(node: Any) -> dict[str, float]:
    """The waited-state variants at `node` (module docstring)."""
    shell, f = node.shell, node.frequency_hz
    cortex = power_law_cortex(shell.bulk_mN_per_m, shell.shear_mN_per_m, node.bulk_exponent, node.shear_exponent)
    protocol = node.protocol
    t_w = waited_time_s(protocol)
    out: dict[str, float] = {"waited_s": t_w}
    for name, t in (("waited", t_w), ("waited_mid", t_w + 2.5 / f)):
        start = time.perf_counter()
        keys = waited_state(shell, cortex, f, t)
        out[f"{name}_modulus_mN_per_m"] = keys["modulus_mN_per_m"]
        out[f"{name}_loss_angle_rad"] = keys["loss_angle_rad"]
        out[f"{name}_wall_s"] = time.perf_counter() - start
        if name == "waited":
            out["linear_modulus_mN_per_m"] = keys["linear_modulus_mN_per_m"]
            out["linear_loss_angle_rad"] = keys["loss_angle_rad"]
    Kb, Ks = cortex.bulk.complex_modulus(f), cortex.shear.complex_modulus(f)
    K = prestressed_modulus(replace(shell, bulk_mN_per_m=abs(Kb), shear_mN_per_m=abs(Ks)), Kb, Ks, f)
    out["prestress_abs_modulus_mN_per_m"], out["prestress_abs_loss_angle_rad"] = abs(K), float(np.angle(K))
    K, out["gamma0_ratio"] = at_td_label(node, cortex, protocol, t_w)
    out["at_td_label_modulus_mN_per_m"], out["at_td_label_loss_angle_rad"] = abs(K), float(np.angle(K))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--nodes", default=None)
    parser.add_argument("--physiological", action="store_true")
    parser.add_argument("--part", type=int, default=0)
    parser.add_argument("--parts", type=int, default=1)
    args = parser.parse_args()
    nodes = load(CAMPAIGN).shells
    ids = [int(i) for i in args.nodes.split(",")] if args.nodes else chosen(nodes)
    if args.physiological:
        ids = [i for i, n in enumerate(nodes) if (n.bulk_exponent, n.shear_exponent) in ((0.1, 0.2), (0.1, 0.4))
               and n.wait_s == 100.0 and n.frequency_hz in (0.1, 1.0)]
    for i in ids[args.part::args.parts]:
        node = nodes[i]
        start = time.perf_counter()
        row: dict[str, Any] = {"node": i, "shell": shell_key(node.shell), "beta_B": node.bulk_exponent,
                               "beta_S": node.shear_exponent, "wait_s": node.wait_s, "frequency_hz": node.frequency_hz}
        try:
            row.update(node_results(node))
        except Exception as exc:  # a failed recording is reported, not fatal
            row["error"] = repr(exc)
        row["time_domain_wall_s"] = time.perf_counter() - start
        row.update(models(node))
        if "modulus_mN_per_m" in row:
            for m in ("model", "waited", "linear", "waited_mid", "prestress_abs", "at_td_label"):
                row[f"{m}_modulus_error"] = row["modulus_mN_per_m"] / row[f"{m}_modulus_mN_per_m"] - 1.0
                row[f"{m}_loss_error_rad"] = row["loss_angle_rad"] - row[f"{m}_loss_angle_rad"]
        print(json.dumps(row), flush=True)


if __name__ == "__main__":
    main()
