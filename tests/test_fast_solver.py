"""The fast equilibrium solver against the physics it must reproduce (SPEC 2, 3)."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from solver.compression import compress
from solver.geometry import droplet
from solver.model import Shell


def shell(**kw):
    base = dict(volume_um3=4300.0, h0_um=12.0, bulk_mN_per_m=25.0, shear_mN_per_m=8.33,
                tension_mN_per_m=1.5, bending="standard")
    base.update(kw)
    return Shell(**base)


def active_force(s, h):
    return s.tension_mN_per_m * float(droplet(s.volume_um3, h).force_per_tension_um)


def test_tension_only_force_is_the_droplets():
    s = shell(bulk_mN_per_m=0.0, shear_mN_per_m=0.0, bending="none")
    c = compress(s)
    assert c.solution.converged
    assert c.to_dict()["force_nN"] == pytest.approx(active_force(s, s.h1_um), rel=1e-4)


def test_elastic_shell_pushes_harder_than_tension_alone():
    c = compress(shell())
    d = c.to_dict()
    assert d["force_nN"] > d["active_force_nN"]
    assert 25.0 < d["modulus_mN_per_m"] < 200.0          # K of order K_B, rising with h~
    assert d["volume_error"] < 1e-3                       # mesh volume vs the droplet's V
    assert abs(d["area_strain_shell"] / d["area_strain"] - 1.0) < 0.06   # SPEC 3: within 6 %


def test_excess_tension_is_linear_in_the_compression():
    """SPEC 2: F_tot - F_a(h1) linear in Δh, and F_tot -> F_a(h0) as Δh -> 0.
    F_tot - F_a(h1) = 2 H(h1) A_c(h1) Δγ_eff, and the droplet factor 2 H A_c
    itself grows by ~10 % from Δh = 0.125 to 0.5 µm (the contact disc
    widens), so the elastic response is linear in Δγ_eff: measured to 1 %."""
    dgam, excess = [], []
    for dh in (0.0625, 0.125, 0.25, 0.5):
        s = shell(dh_um=dh)
        d = compress(s).to_dict()
        dgam.append(d["delta_gamma_mN_per_m"] / dh)
        excess.append(d["force_nN"] - active_force(s, s.h0_um))
    assert np.ptp(dgam[1:]) / np.mean(dgam[1:]) < 0.02
    # F_tot - F_a(h0) vanishes linearly: halving Δh halves it (to the same 2 %)
    assert excess[0] / excess[1] == pytest.approx(0.5, rel=0.02)


def test_virtual_work_force_is_minus_energy_derivative():
    """F_tot = -dE*/dh1: central differences of the constrained minimum energy."""
    from solver.fast import energy
    force = compress(shell()).to_dict()["force_nN"]
    e_lo, e_hi = energy(shell(dh_um=0.51)), energy(shell(dh_um=0.49))   # h1 = 11.49, 11.51
    assert force == pytest.approx(-(e_hi - e_lo) / 0.02, rel=1e-3)


def test_compress_cli_json_and_bad_input():
    cmd = [sys.executable, "-m", "cortex.cli", "compress", "--h0", "12", "--bulk", "25",
           "--shear", "8.33", "--tension", "1.5", "--json"]
    out = subprocess.run(cmd, capture_output=True, text=True, check=True)
    d = json.loads(out.stdout)
    for key in ("force_nN", "active_force_nN", "delta_gamma_mN_per_m", "area_strain",
                "modulus_mN_per_m", "h_mean_um", "h_tilde", "volume_error", "converged", "wall_s"):
        assert key in d
    assert d["h_mean_um"] == pytest.approx(11.75)
    bad = subprocess.run(cmd[:4] + ["--h0", "30", "--bulk", "25", "--shear", "8", "--tension", "1"],
                         capture_output=True, text=True)
    assert bad.returncode == 2 and len(bad.stderr.strip().splitlines()) == 1
    assert "free sphere" in bad.stderr


def test_a_compression_does_not_import_scipy_linalg_and_leaves_it_importable():
    """numba starts without scipy.linalg (solver.jit): a process that only
    compresses never imports it; one that wants it later still gets it."""
    code = ("import sys\n"
            "from solver.compression import compress\nfrom solver.model import Shell\n"
            "c = compress(Shell(volume_um3=4300.0, h0_um=12.0, bulk_mN_per_m=25.0,"
            " shear_mN_per_m=8.33, tension_mN_per_m=1.5))\n"
            "print('scipy.linalg' in sys.modules, c.solution.converged)\n"
            "import scipy.linalg\nprint(float(scipy.linalg.solve([[2.0]], [4.0])[0]))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False", "True", "2.0"]


def test_the_compile_cache_follows_every_compiled_source(tmp_path):
    """A compiled function carries the code it calls from other files, so the
    cache folder (solver.jit.cache_dir) changes with any module that compiles,
    and with no other."""
    from solver import jit
    package = tmp_path / "solver"
    (package / "fast").mkdir(parents=True)
    here = os.path.dirname(jit.__file__)
    for name in ("fast/kernel.py", "fast/newton.py", "model.py"):
        (package / name).write_bytes(open(os.path.join(here, name), "rb").read())
    before = jit.cache_dir("base", package)
    with open(package / "model.py", "a") as f:
        f.write("# an edit to a module that compiles nothing\n")
    assert jit.cache_dir("base", package) == before
    with open(package / "fast/kernel.py", "a") as f:
        f.write("# an edit to the kernel alone\n")
    after = jit.cache_dir("base", package)
    assert after != before and os.path.dirname(after) == "base"
