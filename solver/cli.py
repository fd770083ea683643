"""Command-line entry points of the physics: `cortex geometry`, `cortex compress`."""

import json


def register(sub):
    p = sub.add_parser(
        "geometry", help="the droplet shape of a confined cell (SPEC section 1)",
        description="Solve the stress-free droplet shape of a cell of volume V between plates "
                    "a gap h apart: contact and equator radii, mean curvature, areas, and the "
                    "force per unit tension F_a/gamma_a = 2 H A_c (um; times mN/m gives nN).")
    p.add_argument("--volume", type=float, required=True, metavar="UM3", help="cell volume V, um^3")
    p.add_argument("--height", type=float, nargs="+", required=True, metavar="UM",
                   help="plate gap h, um (several give one line each)")
    p.add_argument("--json", action="store_true", help="one JSON object per height")
    p.set_defaults(handler="solver.cli:geometry")


def geometry(args):
    from solver.geometry import Droplet, droplet
    d = droplet(args.volume, args.height)
    rows = [d.row(i) for i in range(len(args.height))]
    for row, ht in zip(rows, d.h_tilde):
        row["h_tilde"] = float(ht)
    if args.json:
        for row in rows:
            print(json.dumps(row))
        return 0
    cols = [("height_um", "h [um]"), ("h_tilde", "h~ [-]"), ("contact_radius_um", "R_c [um]"),
            ("equator_radius_um", "R_eq [um]"), ("mean_curvature_per_um", "H [1/um]"),
            ("surface_area_um2", "A [um^2]"), ("contact_area_um2", "A_c [um^2]"),
            ("force_per_tension_um", "F_a/gamma_a [um]")]
    print(f"droplet shape, V = {args.volume:g} um^3, R_cell = {float(d.cell_radius_um.flat[0]):.4f} um")
    print("  ".join(f"{label:>16}" for _, label in cols))
    for row in rows:
        print("  ".join(f"{row[key]:16.6g}" for key, _ in cols))
    return 0
