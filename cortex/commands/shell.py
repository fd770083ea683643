"""`cortex geometry`, `cortex compress`, `cortex poroelastic`: the physics of one
cell from the command line (the solver imported when the command runs)."""

from __future__ import annotations

import argparse
import json
import sys

from common.names import SOLVERS
from cortex.options import Commands, add_bending


def register(sub: Commands) -> None:
    for add in (_add_geometry, _add_compress, _add_poroelastic):
        add(sub)


def _add_geometry(sub: Commands) -> None:
    p = sub.add_parser(
        "geometry", help="the droplet shape of a confined cell (SPEC section 1)",
        description="Solve the stress-free droplet shape of a cell of volume V between plates "
                    "a gap h apart: contact and equator radii, mean curvature, areas, and the "
                    "force per unit tension F_a/gamma_a = 2 H A_c (um; times mN/m gives nN). With "
                    "--equator-radius instead of --volume, V is the volume of the droplet of that "
                    "height and equatorial radius (as an image of the confined cell measures them).")
    v = p.add_mutually_exclusive_group(required=True)
    v.add_argument("--volume", type=float, metavar="UM3", help="cell volume V, um^3")
    v.add_argument("--equator-radius", type=float, metavar="UM",
                   help="equatorial radius R_eq of the confined cell, um: V follows from (h, R_eq)")
    p.add_argument("--height", type=float, nargs="+", required=True, metavar="UM",
                   help="plate gap h, um (several give one line each)")
    p.add_argument("--json", action="store_true", help="one JSON object per height")
    p.set_defaults(handler=geometry)


def _add_compress(sub: Commands) -> None:
    p = sub.add_parser(
        "compress", help="one compression h0 -> h0 - dh of the elastic cortical shell",
        description="Compress the elastic cortex shell (SPEC section 2) from gap h0 to h0 - dh at "
                    "constant volume and report the plate force and the effective area modulus "
                    "K = delta_gamma_eff / eps_A of SPEC section 3. Moduli of 0 are valid "
                    "(a tension-only cell).")
    p.add_argument("--volume", type=float, default=4300.0, metavar="UM3", help="cell volume V, um^3 (4300)")
    p.add_argument("--h0", type=float, required=True, metavar="UM", help="initial plate gap, um")
    p.add_argument("--dh", type=float, default=0.5, metavar="UM", help="compression, um (0.5)")
    p.add_argument("--bulk", type=float, required=True, metavar="MN_PER_M", help="area bulk modulus K_B, mN/m")
    p.add_argument("--shear", type=float, required=True, metavar="MN_PER_M", help="area shear modulus K_S, mN/m")
    p.add_argument("--tension", type=float, required=True, metavar="MN_PER_M", help="active tension gamma_a, mN/m")
    add_bending(p, "bending variant, B = t^2 (K_B + K_S)/24 (standard), twice that (double) or 0 (none)")
    p.add_argument("--bending-pN-um", type=float, default=None, metavar="B",
                   help="explicit bending stiffness, pN um (overrides --bending)")
    p.add_argument("--thickness", type=float, default=0.2, metavar="UM", help="cortex thickness t_c, um (0.2)")
    p.add_argument("--solver", choices=SOLVERS, default="fast", metavar="SOLVER",
                   help="%(choices)s; fast: direct equilibrium (default); explicit: the published gradient "
                        "flow (the campaign file's [solver] method)")
    p.add_argument("--resolution", type=float, default=1.0, help="mesh refinement factor (1)")
    p.add_argument("--viscosity", type=float, default=None, metavar="PA_S",
                   help="interior viscosity eta, Pa s: also oscillate around h0 - dh/2 at --frequency "
                        "and report the complex modulus K* (modulus_mN_per_m = |K*|, storage, loss, "
                        "loss angle, elastic_modulus_mN_per_m without viscosity; the secant K becomes "
                        "compression_modulus_mN_per_m); fast solver only")
    p.add_argument("--frequency", type=float, default=None, metavar="HZ",
                   help="oscillation frequency f, Hz (needed with --viscosity or the loss angles)")
    p.add_argument("--bulk-loss-angle", type=float, default=None, metavar="RAD",
                   help="viscoelastic cortex: K_B* = K_B e^(i delta_B); with --shear-loss-angle and --frequency "
                        "(and optionally --viscosity) report K* = K C by the correspondence principle "
                        "(docs/viscoelastic.md; the secant K becomes compression_modulus_mN_per_m)")
    p.add_argument("--shear-loss-angle", type=float, default=None, metavar="RAD",
                   help="viscoelastic cortex: K_S* = K_S e^(i delta_S)")
    p.add_argument("--json", action="store_true", help="one JSON object")
    p.set_defaults(handler=compress)


def _add_poroelastic(sub: Commands) -> None:
    p = sub.add_parser(
        "poroelastic", help="the poroelastic layer's effective modulus (SPEC section 8)",
        description="Effective compression modulus of a poroelastic layer of thickness t_c "
                    "between porous plates, oscillated at f: the large-lambda term "
                    "omega eta t_c^2 / (12 k_perm) with k_perm = d_pore^2/32 and, given the "
                    "scaffold modulus K, the exact K_eff = K x coth x, "
                    "x = (t_c/2) sqrt(i omega eta / (K k_perm)). Moduli in Pa (3D).")
    p.add_argument("--pore-diameter-um", type=float, required=True, metavar="D",
                   help="pore diameter d_pore, um")
    p.add_argument("--viscosity", type=float, required=True, metavar="PA_S",
                   help="fluid viscosity eta, Pa s")
    p.add_argument("--thickness-um", type=float, required=True, metavar="T",
                   help="layer thickness t_c, um")
    p.add_argument("--frequency", type=float, required=True, metavar="HZ", help="frequency f, Hz")
    p.add_argument("--scaffold-modulus-Pa", type=float, default=None, metavar="K",
                   help="drained compression modulus of the scaffold, Pa (adds the exact K_eff)")
    p.add_argument("--json", action="store_true", help="one JSON object")
    p.set_defaults(handler=poroelastic)


def geometry(args: argparse.Namespace) -> int:
    from solver.geometry import droplet, volume_from_image
    if args.equator_radius is not None:
        volume = [volume_from_image(h, args.equator_radius) for h in args.height]
    else:
        volume = args.volume
    d = droplet(volume, args.height)
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
    if args.equator_radius is not None:
        cols.insert(1, ("volume_um3", "V [um^3]"))
        print(f"droplet shape, R_eq = {args.equator_radius:g} um")
    else:
        print(f"droplet shape, V = {args.volume:g} um^3, R_cell = {float(d.cell_radius_um.flat[0]):.4f} um")
    print("  ".join(f"{label:>16}" for _, label in cols))
    for row in rows:
        print("  ".join(f"{row[key]:16.6g}" for key, _ in cols))
    return 0


def compress(args: argparse.Namespace) -> int:
    from solver.compression import compress as run
    from common.errors import EXIT_NO_EQUILIBRIUM, SolverError
    from solver.model import Shell
    angles = _loss_angles(args)
    shell = Shell(volume_um3=args.volume, h0_um=args.h0, dh_um=args.dh,
                  bulk_mN_per_m=args.bulk, shear_mN_per_m=args.shear,
                  tension_mN_per_m=args.tension, bending=args.bending,
                  bending_pN_um=args.bending_pN_um, thickness_um=args.thickness, resolution=args.resolution,
                  **({} if angles else dict(viscosity_Pa_s=args.viscosity, frequency_hz=args.frequency)))
    try:
        result = run(shell, args.solver).to_dict()
        if angles:
            from solver.viscoelastic import viscoelastic_keys
            result["compression_modulus_mN_per_m"] = result["modulus_mN_per_m"]
            result.update(viscoelastic_keys(shell, result["modulus_mN_per_m"], args.frequency, *angles,
                                            viscosity_Pa_s=args.viscosity or 0.0))
    except SolverError as err:
        print(f"cortex compress: the {args.solver} solver failed: {err}", file=sys.stderr)
        return EXIT_NO_EQUILIBRIUM
    if args.json:
        print(json.dumps(result))
        return 0
    width = max(map(len, result))
    for key, value in result.items():
        print(f"{key:<{width}}  {value:.6g}" if isinstance(value, float) else f"{key:<{width}}  {value}")
    return 0


def _loss_angles(args: argparse.Namespace) -> tuple[float, float] | None:
    """(δ_B, δ_S) of a viscoelastic compression, or None; InputError if incomplete."""
    from common.errors import InputError
    from solver.model import check_viscous_inputs
    given = (args.bulk_loss_angle, args.shear_loss_angle)
    if given == (None, None):
        return None
    if None in given or args.frequency is None:
        raise InputError("--bulk-loss-angle and --shear-loss-angle go together, with --frequency")
    if args.solver != "fast":
        raise InputError("a viscoelastic cell needs the fast solver (its linear response uses the Hessian)")
    check_viscous_inputs(args.viscosity or 0.0, args.frequency)
    from solver.viscoelastic import check_loss_angles
    check_loss_angles(*given)
    return given


def poroelastic(args: argparse.Namespace) -> int:
    import numpy as np

    from solver import poroelastic as pe
    inputs = (args.pore_diameter_um, args.viscosity, args.thickness_um, args.frequency)
    out = {"pore_diameter_um": args.pore_diameter_um, "viscosity_Pa_s": args.viscosity,
           "thickness_um": args.thickness_um, "frequency_hz": args.frequency,
           "permeability_um2": pe.permeability_m2(args.pore_diameter_um) / pe.UM**2,
           "dissipative_modulus_Pa": pe.dissipative_modulus_Pa(*inputs)}
    if args.scaffold_modulus_Pa is not None:
        K = args.scaffold_modulus_Pa
        exact, limit = pe.effective_modulus_exact(K, *inputs), pe.effective_modulus_limit(K, *inputs)
        out.update(scaffold_modulus_Pa=K, diffusion_ratio_lambda=pe.diffusion_ratio(K, *inputs),
                   storage_modulus_Pa=exact.real, loss_modulus_Pa=exact.imag,
                   modulus_Pa=abs(exact), loss_angle_rad=float(np.angle(exact)),
                   storage_modulus_limit_Pa=limit.real, loss_modulus_limit_Pa=limit.imag)
    if args.json:
        print(json.dumps(out))
        return 0
    width = max(map(len, out))
    for key, value in out.items():
        print(f"{key:<{width}}  {value:.6g}")
    return 0
