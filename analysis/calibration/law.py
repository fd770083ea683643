"""The calibration of SPEC section 4: from simulated K(h̃) curves to (λ, C, D)
per bending variant, and its inverse.

Per bending variant, with K̃_S = K_S/K_B and γ̃_a = γ_a/K_B:

1. every (K_S, γ_a) curve is fitted with K(h̃) = K_B (1 + α exp(h̃/c)),
   K_B known, α and c free; λ = mean of the fitted c;
2. every curve is refitted with c = λ: the table α(K̃_S, γ̃_a);
3. per γ̃_a, α ≈ C(γ̃_a) ln K̃_S + D(γ̃_a);
4. C and D as cubic polynomials in γ̃_a (coefficients lowest order first).

Inverse: K̃_S = exp((α - D(γ̃_a)) / C(γ̃_a)), ν = (1 - K̃_S)/(1 + K̃_S).

Every stage records its goodness of fit (R², largest residual); the whole
law is also checked end to end against the simulated α and K.
`Calibration.save` writes `calibration.json` (per variant: `lambda`, `C`, `D`,
the `alpha` table with its `K_S/K_B` and `gamma_a/K_B` axes, goodness);
`analysis.calibration.file.load_calibration` reads it.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from os import PathLike
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pandas as pd

from analysis.calibration import law_fits
from solver.elasticity import poisson_of_ratio as poisson, poisson_ratio, shear_ratio  # noqa: F401 (poisson, shear_ratio: this module's names for them)
from common.errors import InputError

FORMAT = "cortex-calibration"
NEEDED = ("bending", "bulk_mN_per_m", "shear_mN_per_m", "tension_mN_per_m", "h_tilde",
          "modulus_mN_per_m")
MIN_HEIGHTS = 3   # a curve with fewer heights cannot constrain α and c


@dataclass
class Law:
    """The calibration of one bending variant."""

    bending: str
    lam: float                       # λ, the characteristic height (units of h̃)
    C: list[float]                   # C(γ̃_a) coefficients, lowest order first
    D: list[float]                   # D(γ̃_a) coefficients, lowest order first
    ks_tilde: list[float] = field(default_factory=list)       # α table axis K_S/K_B
    gamma_tilde: list[float] = field(default_factory=list)    # α table axis γ_a/K_B
    alpha: list[list[float]] = field(default_factory=list)    # α[i_gamma][i_ks] (NaN: missing)
    goodness: dict[str, Any] = field(default_factory=dict)
    info: dict[str, Any] = field(default_factory=dict)

    def C_of(self, gamma_tilde: npt.ArrayLike) -> Any:
        return np.polynomial.polynomial.polyval(np.asarray(gamma_tilde, float), self.C)

    def D_of(self, gamma_tilde: npt.ArrayLike) -> Any:
        return np.polynomial.polynomial.polyval(np.asarray(gamma_tilde, float), self.D)

    def alpha_of(self, ks_tilde: npt.ArrayLike, gamma_tilde: npt.ArrayLike) -> Any:
        """α(K̃_S, γ̃_a) = C(γ̃_a) ln K̃_S + D(γ̃_a)."""
        return self.C_of(gamma_tilde) * np.log(np.asarray(ks_tilde, float)) + self.D_of(gamma_tilde)

    def invert(self, alpha: npt.ArrayLike, gamma_tilde: npt.ArrayLike) -> Any:
        """K̃_S = exp((α - D(γ̃_a)) / C(γ̃_a)) (arrays broadcast)."""
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            return np.exp((np.asarray(alpha, float) - self.D_of(gamma_tilde)) / self.C_of(gamma_tilde))

    def poisson(self, alpha: npt.ArrayLike, gamma_tilde: npt.ArrayLike) -> Any:
        """ν from α and γ̃_a."""
        return poisson(self.invert(alpha, gamma_tilde))

    def to_json(self) -> dict[str, Any]:
        return {"lambda": self.lam, "C": list(self.C), "D": list(self.D),
                "alpha": {"K_S/K_B": list(self.ks_tilde), "gamma_a/K_B": list(self.gamma_tilde),
                          "values": self.alpha},
                "goodness": self.goodness, **self.info}


@dataclass
class Calibration:
    """Calibration laws by bending variant (`standard`, `double`, `none`)."""

    laws: dict[str, Law]

    def __getitem__(self, bending: str) -> Law:
        if bending not in self.laws:
            raise InputError(f"the calibration has no '{bending}' bending variant "
                             f"(it has: {', '.join(self.laws) or 'none'})")
        return self.laws[bending]

    def law(self, bending: str = "standard") -> Law:
        return self[bending]

    def invert(self, alpha: npt.ArrayLike, gamma_tilde: npt.ArrayLike, bending: str = "standard") -> Any:
        """K̃_S from α and γ̃_a with the given variant's law."""
        return self[bending].invert(alpha, gamma_tilde)

    poisson = staticmethod(poisson)

    def to_json(self) -> dict[str, Any]:
        return {"format": FORMAT, "version": 1,
                "variants": {name: law.to_json() for name, law in self.laws.items()}}

    def save(self, path: str | PathLike[str], borrow: tuple[str, ...] = ()) -> Path:
        """Write `path` (JSON, NaN written as null); atomic replace. A law-only bundle: its manifest
        borrows the shipped bundle's parts `borrow` (e.g. "emulator"; `analysis.calibration.file`)."""
        path = Path(path)
        tmp = path.with_name(path.name + ".tmp")
        doc = self.to_json()
        if borrow:
            doc["parts"] = {"law": "embedded", **{name: "shipped" for name in borrow}}
        tmp.write_text(json.dumps(_nan_to_none(doc), indent=1) + "\n")
        tmp.replace(path)
        return path

    @classmethod
    def from_document(cls, path: str | PathLike[str], doc: dict[str, Any]) -> Calibration:
        """The laws of a calibration document (`read_document`) read from `path`."""
        variants = doc.get("variants")
        if not isinstance(variants, dict) or not variants:
            raise InputError(f"{path}: 'variants' must be a non-empty object")
        return cls({name: _law_from_json(path, name, v) for name, v in variants.items()})


def read_document(path: str | PathLike[str]) -> dict[str, Any]:
    """The JSON object of a calibration file (our `format` key checked);
    InputError (one line) for a folder, a file that is not text or not JSON,
    or another format."""
    path = Path(path)
    if path.is_dir():
        raise InputError(f"{path}: is a directory, not a calibration file")
    try:
        doc = json.loads(path.read_text())
    except UnicodeDecodeError:
        raise InputError(f"{path}: not a calibration file (not text)") from None
    except json.JSONDecodeError as err:
        raise InputError(f"{path}: not valid JSON ({err.msg} at line {err.lineno})") from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise InputError(f"{path}: not a calibration file (no \"format\": \"{FORMAT}\")")
    return doc


def _number(path: str | PathLike[str], where: str, value: Any, finite: bool = True) -> float:
    if value is None and not finite:
        return float("nan")
    if isinstance(value, bool) or not isinstance(value, (int, float)) or (finite and not math.isfinite(value)):
        raise InputError(f"{path}: {where} must be a finite number (got {value!r})")
    return float(value)


def _law_from_json(path: str | PathLike[str], name: str, v: Any) -> Law:
    if not isinstance(v, dict):
        raise InputError(f"{path}: variants.{name} must be an object")
    for key in ("lambda", "C", "D"):
        if key not in v:
            raise InputError(f"{path}: variants.{name} has no '{key}'")
    lam = _number(path, f"variants.{name}.lambda", v["lambda"])
    if lam == 0:
        raise InputError(f"{path}: variants.{name}.lambda must not be 0")
    coef = {}
    for key in ("C", "D"):
        if not isinstance(v[key], list) or not v[key]:
            raise InputError(f"{path}: variants.{name}.{key} must be a non-empty list of numbers")
        coef[key] = [_number(path, f"variants.{name}.{key}", c) for c in v[key]]
    table = v.get("alpha", {}) or {}
    if not isinstance(table, dict):
        raise InputError(f"{path}: variants.{name}.alpha must be an object")
    values = [[_number(path, f"variants.{name}.alpha.values", a, finite=False) for a in row]
              for row in table.get("values", [])]
    info = {k: x for k, x in v.items() if k not in ("lambda", "C", "D", "alpha", "goodness")}
    return Law(bending=name, lam=lam, C=coef["C"], D=coef["D"],
               ks_tilde=list(table.get("K_S/K_B", [])), gamma_tilde=list(table.get("gamma_a/K_B", [])),
               alpha=values, goodness=v.get("goodness", {}), info=info)


def _nan_to_none(x: Any) -> Any:
    if isinstance(x, dict):
        return {k: _nan_to_none(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_nan_to_none(v) for v in x]
    if isinstance(x, (float, np.floating)):
        return None if not math.isfinite(x) else float(x)
    if isinstance(x, np.integer):
        return int(x)
    return x


def _free_fits(results: pd.DataFrame, bending: str) -> pd.DataFrame:
    """Step 1 per (K_B, K_S, γ_a) curve with at least MIN_HEIGHTS heights: α and c
    free. One row per curve (its heights and moduli kept in `_h`, `_k`)."""
    df = results.dropna(subset=["h_tilde", "modulus_mN_per_m"])
    rows = []
    for (bulk, shear, tension), curve in df.groupby(["bulk_mN_per_m", "shear_mN_per_m",
                                                     "tension_mN_per_m"], sort=True):
        if len(curve) < MIN_HEIGHTS:
            continue
        curve = curve.sort_values("h_tilde")
        free = law_fits.fit_alpha_c(curve["h_tilde"], curve["modulus_mN_per_m"], bulk)
        rows.append({"bending": bending, "bulk_mN_per_m": bulk, "shear_mN_per_m": shear,
                     "tension_mN_per_m": tension, "ks_tilde": shear / bulk,
                     "gamma_tilde": round(tension / bulk, 12),
                     "nu_true": poisson_ratio(bulk, shear), "n_heights": len(curve),
                     "h_tilde_min": curve["h_tilde"].min(), "h_tilde_max": curve["h_tilde"].max(),
                     "c_free": free["c"], "c_free_sd": free["c_sd"], "alpha_free": free["alpha"],
                     "alpha_free_sd": free["alpha_sd"], "r2_free": free["r2"],
                     "max_residual_free_mN_per_m": free["max_residual_mN_per_m"],
                     "_h": curve["h_tilde"].to_numpy(), "_k": curve["modulus_mN_per_m"].to_numpy()})
    if len(rows) < 2:
        raise InputError(f"bending variant '{bending}': {len(rows)} complete K(h~) curve(s) "
                         f"(at least {MIN_HEIGHTS} heights each); a calibration needs at least 2")
    return pd.DataFrame(rows)


def _alpha_at_lambda(fits: pd.DataFrame, lam: float) -> None:
    """Step 2: α of every curve with c = λ (columns added to `fits`)."""
    step2 = [law_fits.fit_alpha(h, k, b, lam) for h, k, b in zip(fits["_h"], fits["_k"], fits["bulk_mN_per_m"])]
    fits["alpha"] = [f["alpha"] for f in step2]
    fits["r2_alpha"] = [f["r2"] for f in step2]
    fits["max_residual_alpha_mN_per_m"] = [f["max_residual_mN_per_m"] for f in step2]


def _log_laws(fits: pd.DataFrame, bending: str) -> pd.DataFrame:
    """Step 3: α = C ln K̃_S + D per γ̃_a with at least two K_S; one row each."""
    per_gamma = []
    for g, group in fits.groupby("gamma_tilde", sort=True):
        if group["ks_tilde"].nunique() < 2:
            continue
        f = law_fits.fit_log_law(group["ks_tilde"], group["alpha"])
        per_gamma.append({"bending": bending, "gamma_tilde": g, "C": f["C"], "D": f["D"],
                          "r2_log_law": f["r2"], "max_residual_log_law": f["max_residual"],
                          "n_shear": group["ks_tilde"].nunique()})
    if not per_gamma:
        raise InputError(f"bending variant '{bending}': the log law needs at least two K_S values "
                         "at one tension")
    return pd.DataFrame(per_gamma)


def _polynomials(loglaw: pd.DataFrame) -> tuple[dict[str, Any], dict[str, Any]]:
    """Step 4: C(γ̃_a) and D(γ̃_a) as polynomials (`C_poly`, `D_poly` added to `loglaw`)."""
    fit_C = law_fits.fit_polynomial(loglaw["gamma_tilde"], loglaw["C"])
    fit_D = law_fits.fit_polynomial(loglaw["gamma_tilde"], loglaw["D"])
    loglaw["C_poly"] = np.polynomial.polynomial.polyval(loglaw["gamma_tilde"], fit_C["coefficients"])
    loglaw["D_poly"] = np.polynomial.polynomial.polyval(loglaw["gamma_tilde"], fit_D["coefficients"])
    return fit_C, fit_D


def _check_law(law: Law, fits: pd.DataFrame) -> tuple[tuple[float, float], tuple[float, float]]:
    """The whole law against the curves: α_law, K's residual, K̃_S and ν
    inverted (columns added to `fits`); returns the R² and largest error of α and K."""
    fits["alpha_law"] = law.alpha_of(fits["ks_tilde"], fits["gamma_tilde"])
    k_law = [law_fits.modulus_law(h, b, a, law.lam) for h, b, a in
             zip(fits["_h"], fits["bulk_mN_per_m"], fits["alpha_law"])]
    fits["max_residual_law_mN_per_m"] = [float(np.max(np.abs(k - kl))) for k, kl in zip(fits["_k"], k_law)]
    fits["ks_tilde_law"] = law.invert(fits["alpha"], fits["gamma_tilde"])
    fits["nu_law"] = poisson(fits["ks_tilde_law"])
    return (law_fits.goodness(fits["alpha"], fits["alpha_law"]),
            law_fits.goodness(np.concatenate(list(fits["_k"])), np.concatenate(k_law)))


def _alpha_table(law: Law, fits: pd.DataFrame) -> None:
    """The fitted α on the (γ̃_a, K̃_S) grid, stored in `law`."""
    ks_axis = sorted(fits["ks_tilde"].unique())
    g_axis = sorted(fits["gamma_tilde"].unique())
    table = fits.pivot_table(index="gamma_tilde", columns="ks_tilde", values="alpha", aggfunc="mean")
    table = table.reindex(index=g_axis, columns=ks_axis)
    law.ks_tilde = [float(v) for v in ks_axis]
    law.gamma_tilde = [float(v) for v in g_axis]
    law.alpha = [[float(a) for a in row] for row in table.to_numpy()]


def _goodness(fits: pd.DataFrame, loglaw: pd.DataFrame, polys: tuple[dict[str, Any], dict[str, Any]],
              law_fit: tuple[tuple[float, float], tuple[float, float]]) -> dict[str, Any]:
    """The `goodness` document of a Law: every stage's R² and largest residual."""
    (fit_C, fit_D), ((r2_alpha_law, worst_alpha_law), (r2_k_law, worst_k_law)) = polys, law_fit
    return {
        "step1_free_c": {"r2_min": float(fits["r2_free"].min()),
                         "max_residual_mN_per_m": float(fits["max_residual_free_mN_per_m"].max()),
                         "c_min": float(fits["c_free"].min()), "c_max": float(fits["c_free"].max()),
                         "c_sd_over_grid": float(fits["c_free"].std(ddof=1)) if len(fits) > 1 else float("nan"),
                         "c_fit_sd_median": float(fits["c_free_sd"].median())},
        "step2_alpha": {"r2_min": float(fits["r2_alpha"].min()),
                        "max_residual_mN_per_m": float(fits["max_residual_alpha_mN_per_m"].max())},
        "step3_log_law": {"r2_min": float(loglaw["r2_log_law"].min()),
                          "max_residual": float(loglaw["max_residual_log_law"].max())},
        "step4_C": {"degree": fit_C["degree"], "r2": fit_C["r2"], "max_residual": fit_C["max_residual"]},
        "step4_D": {"degree": fit_D["degree"], "r2": fit_D["r2"], "max_residual": fit_D["max_residual"]},
        "law_alpha": {"r2": r2_alpha_law, "max_residual": worst_alpha_law},
        "law_K": {"r2": r2_k_law, "max_residual_mN_per_m": worst_k_law},
        "law_nu": {"max_abs_error": float(np.nanmax(np.abs(fits["nu_law"] - fits["nu_true"])))},
    }


def calibrate_variant(results: pd.DataFrame,
                      bending: str = "standard") -> tuple[Law, pd.DataFrame, pd.DataFrame]:
    """Steps 1-4 for one bending variant. `results`: rows with the columns of
    `NEEDED` (one per simulation). Returns (Law, per-curve fits DataFrame,
    per-γ̃_a log-law DataFrame)."""
    fits = _free_fits(results, bending)                              # step 1
    lam = float(fits["c_free"].mean())
    _alpha_at_lambda(fits, lam)                                      # step 2
    loglaw = _log_laws(fits, bending)                                # step 3
    fit_C, fit_D = _polynomials(loglaw)                              # step 4
    law = Law(bending=bending, lam=lam, C=fit_C["coefficients"], D=fit_D["coefficients"])
    law_fit = _check_law(law, fits)
    _alpha_table(law, fits)
    law.goodness = _goodness(fits, loglaw, (fit_C, fit_D), law_fit)
    bulks = fits["bulk_mN_per_m"].unique()
    law.info = {"bulk_mN_per_m": float(bulks[0]) if len(bulks) == 1 else None,
                "n_simulations": int(fits["n_heights"].sum()), "n_curves": int(len(fits)),
                "h_tilde_range": [float(fits["h_tilde_min"].min()), float(fits["h_tilde_max"].max())]}
    return law, fits.drop(columns=["_h", "_k"]), loglaw


def calibrate(results: pd.DataFrame, progress: Callable[[str], None] | None = None
              ) -> tuple[Calibration, pd.DataFrame, pd.DataFrame]:
    """All bending variants in `results` (rows with the columns of `NEEDED`).

    Returns (Calibration, fits DataFrame, log-law DataFrame)."""
    missing = [c for c in NEEDED if c not in results.columns]
    if missing:
        raise InputError(f"results lack column(s): {', '.join(missing)}")
    out, all_fits, all_log = {}, [], []
    for bending, group in results.groupby("bending", sort=False):
        if progress:
            progress(f"calibrating bending variant '{bending}' ({len(group)} simulations)")
        law, fits, loglaw = calibrate_variant(group, bending)
        out[bending] = law
        all_fits.append(fits)
        all_log.append(loglaw)
    if not out:
        raise InputError("no finished simulations to calibrate")
    return Calibration(out), pd.concat(all_fits, ignore_index=True), pd.concat(all_log, ignore_index=True)
