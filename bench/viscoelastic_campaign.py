"""The viscoelastic table's campaign on 1 and 2 ranks; prints one JSON object.

`campaigns/viscoelastic.toml` cut to the h̃ values of --h-tilde (default the
first three: 3 × 8 × 6 nodes at each volume of --volumes, default 4300 µm³)
runs under `mpiexec -n R cortex campaign run` for R = 1, 2 (wall clock, start-up
included: `wall_s_1`, `wall_s_2`, per node `node_s_1`, `node_s_2`), and the
full campaign's time is extrapolated from them (`full_s_1`, `full_s_2`). The
table built from each store (`cortex analysis build-viscoelastic-table`) is
compared with the shipped one on the same nodes: `same_bits` (1 and 2 ranks
give the same file bit for bit: `ranks_agree`), the largest coefficient
difference and the largest difference of ln C over the angle square [0, 1]²
(`max_coef_diff`, `max_ln_c_diff`). `--full` runs all 1440 nodes.
"""

import argparse
import json
import pathlib
import re
import subprocess
import sys
import tempfile
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
BIN = pathlib.Path(sys.executable).parent
CAMPAIGN = ROOT / "campaigns" / "viscoelastic.toml"
SHIPPED = ROOT / "analysis" / "data" / "viscoelastic_table.json"


def cut(text: str, h_tilde: str, volumes: str) -> str:
    """The campaign file with its h̃ and volume axes replaced."""
    text = re.sub(r"(?m)^h_tilde = .*$", f"h_tilde = [{h_tilde}]", text)
    return re.sub(r"(?m)^volume_um3 = .*$", f"volume_um3 = [{volumes}]", text)


def run(config: pathlib.Path, ranks: int, folder: pathlib.Path) -> tuple[float, dict]:
    """Wall time of the campaign on `ranks` ranks and the table built from its store."""
    store = folder / f"r{ranks}.h5"
    start = time.perf_counter()
    subprocess.run([str(BIN / "mpiexec"), "-n", str(ranks), str(BIN / "cortex"), "campaign", "run", str(config),
                    "--store", str(store), "--quiet"], check=True, cwd=ROOT)
    wall = time.perf_counter() - start
    subprocess.run([str(BIN / "cortex"), "analysis", "build-viscoelastic-table", str(store), "--out",
                    str(folder / f"t{ranks}")], check=True, cwd=ROOT, stdout=subprocess.DEVNULL)
    return wall, json.loads((folder / f"t{ranks}" / "viscoelastic_table.json").read_text())


def against_shipped(doc: dict) -> dict:
    """The table `doc` against the shipped one on `doc`'s nodes."""
    ship = json.loads(SHIPPED.read_text())
    cube = lambda d: np.array(d["ln_c_real"]) + 1j * np.array(d["ln_c_imag"])  # noqa: E731
    axes = ("volume_um3", "h_tilde", "ks_tilde", "gamma_tilde")
    c, s = cube(doc), cube(ship)[np.ix_(*[[ship[k].index(v) for v in doc[k]] for k in axes])]
    db, ds = np.meshgrid(np.linspace(0, 1, 21), np.linspace(0, 1, 21))
    monomials = np.stack([db ** i * ds ** j for i, j in ship["terms"]], -1)
    return {"same_bits": bool((c == s).all()), "max_coef_diff": float(np.abs(c - s).max()),
            "max_ln_c_diff": float(np.abs(np.tensordot(c - s, monomials, axes=([-1], [-1]))).max())}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--h-tilde", default="0.43, 0.475, 0.52", help="the h~ values run (default: %(default)s)")
    p.add_argument("--volumes", default="4300.0", help="the volumes run, um^3 (default: %(default)s)")
    p.add_argument("--full", action="store_true", help="all 1440 nodes")
    args = p.parse_args()
    text = CAMPAIGN.read_text() if args.full else cut(CAMPAIGN.read_text(), args.h_tilde, args.volumes)
    out: dict = {}
    with tempfile.TemporaryDirectory() as tmp:
        folder = pathlib.Path(tmp)
        config = folder / "viscoelastic.toml"
        config.write_text(text)
        docs = {}
        for ranks in (1, 2):
            out[f"wall_s_{ranks}"], docs[ranks] = run(config, ranks, folder)
    nodes = int(np.prod([len(docs[1][k]) for k in ("volume_um3", "h_tilde", "ks_tilde", "gamma_tilde")]))
    out["nodes"] = nodes
    for ranks in (1, 2):
        out[f"node_s_{ranks}"] = out[f"wall_s_{ranks}"] / nodes
        out[f"full_s_{ranks}"] = out[f"node_s_{ranks}"] * 1440
    out["ranks_agree"] = docs[1] == docs[2]
    out.update(against_shipped(docs[1]))
    print(json.dumps(out))


if __name__ == "__main__":
    main()
