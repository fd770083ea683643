"""The poroelastic layer (solver/poroelastic.py, SPEC section 8): the exact
K_eff = K x coth x against a finite-difference solution of the layer's
diffusion equation, its large-λ limit, the published inputs, and the
`cortex poroelastic` command (JSON keys, bad input: one line, exit 2)."""

import json

import numpy as np
import pytest
from scipy.sparse import diags
from scipy.sparse.linalg import spsolve

from conftest import cortex as run_cortex
from solver import poroelastic as pe
from common.errors import InputError


def layer_stress_fd(K, k_perm, eta, t, omega, n=4000):
    """σ̂/ε̂ from the biphasic layer solved by second-order finite differences:
    iω u = D u'' on (0, t/2), u(0) = 0, u(t/2) = t/2 (unit strain amplitude),
    σ̂ = K u'(t/2) (p = 0 at the porous plate), u' by a one-sided 2nd-order stencil."""
    D = K * k_perm / eta
    z = np.linspace(0.0, t / 2, n + 1)
    dz = z[1] - z[0]
    m = n - 1                                  # interior nodes
    A = diags([np.full(m - 1, D / dz**2), np.full(m, -2 * D / dz**2 - 1j * omega),
               np.full(m - 1, D / dz**2)], [-1, 0, 1], format="csc")
    rhs = np.zeros(m, complex)
    rhs[-1] = -D / dz**2 * (t / 2)
    u = np.concatenate([[0.0], spsolve(A, rhs), [t / 2]])
    du = (3 * u[-1] - 4 * u[-2] + u[-3]) / (2 * dz)
    return K * du


@pytest.mark.parametrize("K", [30.0, 300.0, 3000.0, 1e5])
def test_exact_form_solves_the_layer_equations(K):
    d, eta, t, f = 0.05, 1e-3, 0.2, 10.0
    exact = pe.effective_modulus_exact(K, d, eta, t, f)
    fd = layer_stress_fd(K, pe.permeability_m2(d), eta, t * 1e-6, 2 * np.pi * f)
    assert exact == pytest.approx(fd, rel=2e-5)


def test_large_lambda_limit_is_the_first_order_of_the_exact_form():
    d, eta, t, f = 0.05, 1e-3, 0.2, 10.0
    term = pe.dissipative_modulus_Pa(d, eta, t, f)
    errs = []
    for K in (1e2, 1e3, 1e4, 1e5):
        lam = pe.diffusion_ratio(K, d, eta, t, f)
        exact = pe.effective_modulus_exact(K, d, eta, t, f)
        limit = pe.effective_modulus_limit(K, d, eta, t, f)
        assert limit == complex(K, term)
        errs.append((lam, abs(exact - limit) / abs(exact - K)))
    # x coth x - (1 + x²/3) = -x⁴/45 + ...: the limit's error relative to its
    # dissipative term falls as |x|² = 1/λ² (a decade of K: a decade of error)
    for (lam1, e1), (lam2, e2) in zip(errs, errs[1:]):
        assert lam2 > lam1 > 1
        assert e2 / e1 == pytest.approx((lam1 / lam2) ** 2, rel=0.02)
    assert errs[-1][1] == pytest.approx(1.0 / (15.0 * errs[-1][0] ** 2), rel=0.01)


def test_small_lambda_the_layer_stiffens_like_a_boundary_layer():
    # λ << 1: x coth x -> x, |K_eff| = K |x| grows like sqrt(ω)
    d, eta, t, K = 0.05, 1.0, 0.2, 10.0
    a, b = (abs(pe.effective_modulus_exact(K, d, eta, t, f)) for f in (1e3, 4e3))
    assert pe.diffusion_ratio(K, d, eta, t, 1e3) < 0.05
    assert b / a == pytest.approx(2.0, rel=1e-3)


def test_published_inputs():
    # d_pore = 50 nm, η = 1e-3 Pa·s, t_c = 200 nm, f = 10 Hz
    k = (50e-9) ** 2 / 32
    assert pe.permeability_m2(0.05) == pytest.approx(k, rel=1e-12)
    term = pe.dissipative_modulus_Pa(0.05, 1e-3, 0.2, 10.0)
    assert term == pytest.approx(2 * np.pi * 10 * 1e-3 * (200e-9) ** 2 / (12 * k), rel=1e-12)
    assert 2.0 < term < 3.0                     # not the ≈100 Pa the supplement quotes
    # linear in ω and η, quadratic in t_c, inverse square in d_pore
    assert pe.dissipative_modulus_Pa(0.1, 2e-3, 0.4, 5.0) == pytest.approx(term, rel=1e-12)


@pytest.mark.parametrize("args", [(-0.05, 1e-3, 0.2, 10.0), (0.05, -1e-3, 0.2, 10.0),
                                  (0.05, 1e-3, 0.0, 10.0), (0.05, 1e-3, 0.2, 0.0),
                                  (0.05, 1e-3, 0.2, float("nan"))])
def test_impossible_parameters(args):
    with pytest.raises(InputError):
        pe.dissipative_modulus_Pa(*args)


def cortex(*args):
    """`cortex poroelastic ARGS`, run as a user runs it (the shared helper)."""
    return run_cortex("poroelastic", *args, timeout=60)


def test_cli_json():
    done = cortex("--pore-diameter-um", "0.05", "--viscosity", "1e-3", "--thickness-um", "0.2",
                  "--frequency", "10", "--json")
    assert done.returncode == 0, done.stderr
    row = json.loads(done.stdout)
    assert row["dissipative_modulus_Pa"] == pe.dissipative_modulus_Pa(0.05, 1e-3, 0.2, 10.0)
    assert row["permeability_um2"] == pytest.approx(0.05**2 / 32, rel=1e-12)
    assert "storage_modulus_Pa" not in row
    done = cortex("--pore-diameter-um", "0.05", "--viscosity", "1", "--thickness-um", "0.2",
                  "--frequency", "10", "--scaffold-modulus-Pa", "500", "--json")
    row = json.loads(done.stdout)
    exact = pe.effective_modulus_exact(500.0, 0.05, 1.0, 0.2, 10.0)
    assert (row["storage_modulus_Pa"], row["loss_modulus_Pa"]) == (exact.real, exact.imag)
    assert row["loss_modulus_limit_Pa"] == row["dissipative_modulus_Pa"]
    assert row["loss_angle_rad"] == pytest.approx(np.arctan2(exact.imag, exact.real), rel=1e-12)


@pytest.mark.parametrize("bad", [("--viscosity", "-1"), ("--frequency", "0"),
                                 ("--pore-diameter-um", "0"), ("--scaffold-modulus-Pa", "-5")])
def test_cli_bad_input_one_line_exit_2(bad):
    args = {"--pore-diameter-um": "0.05", "--viscosity": "1e-3", "--thickness-um": "0.2",
            "--frequency": "10"}
    args[bad[0]] = bad[1]
    done = cortex(*[x for kv in args.items() for x in kv], "--json")
    assert done.returncode == 2
    assert done.stdout == "" and len(done.stderr.strip().splitlines()) == 1
    assert "Traceback" not in done.stderr
