"""Reader for NanoScope Analysis text exports of one force curve
(`NAME.000 - NanoScope Analysis.txt`, also gzip-compressed as `.txt.gz`).

The export is two tab-separated columns under one line of units (latin-1 or
UTF-8 `µ`): the ramp Z (a length: nm, µm, m) and the deflection (a length)
or the force (nN, pN, µN, N); NanoScope Analysis subtracts its baseline
before it writes them. It holds one segment: rows in order of rising Z (the
piezo extending) are the approach, of falling Z the retract. It holds
neither the spring constant nor the sampling, so these come from the
caller (`spring_constant_N_per_m`) or else from the NanoScope file it was
exported from (its name up to the curve number `.NNN`), where that lies
beside it; times are then mid-sample at that file's extend (or retract)
sample interval, and NaN without it.

    height z = −Z (µm; falls as the cantilever approaches, like a JPK height)
    force  F = k · d (nN = N/m · nm) for a deflection d; as written for a force
"""

import re
from pathlib import Path

import numpy as np

from analysis.afm.formats.bruker.nanoscope import read_curve
from analysis.afm.formats.recording import RecordedSegment, Recording
from analysis.afm.formats.textfiles import export_name, read_bytes
from common.errors import InputError

LENGTH_TO_NM = {"nm": 1.0, "µm": 1e3, "um": 1e3, "m": 1e9}
FORCE_TO_NN = {"nN": 1.0, "pN": 1e-3, "µN": 1e3, "uN": 1e3, "N": 1e9}


def _unit(token: str) -> str:
    """A unit token with its micro sign normalised (U+03BC and U+00B5 both µ)."""
    return token.strip().replace("\u03bc", "µ")


def _lines(path: Path) -> list:
    data = read_bytes(path)
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        text = data.decode("latin-1")
    if "\x00" in text:
        raise InputError(f"{path}: not a NanoScope Analysis text export (binary data)")
    return [line for line in text.splitlines() if line.strip()]


def read_columns(path: Path) -> tuple:
    """(Z in nm, the second column, its unit) of an export; InputError (one line) if malformed."""
    lines = _lines(path)
    if not lines:
        raise InputError(f"{path}: empty NanoScope Analysis text export")
    units = [_unit(u) for u in lines[0].split()]
    if len(units) != 2 or units[0] not in LENGTH_TO_NM or units[1] not in {**LENGTH_TO_NM, **FORCE_TO_NN}:
        raise InputError(f"{path}: first line {lines[0].strip()[:40]!r} is not two units (Z: nm, µm or m; "
                         "deflection nm or force nN)")
    rows = []
    for lineno, line in enumerate(lines[1:], 2):
        parts = line.split()
        try:
            if len(parts) != 2:
                raise ValueError
            rows.append((float(parts[0]), float(parts[1])))
        except ValueError:
            raise InputError(f"{path}:{lineno}: not two numbers: {line.strip()[:40]!r}") from None
    if len(rows) < 2:
        raise InputError(f"{path}: {len(rows)} data row(s) under the units line (an empty export?)")
    a = np.array(rows)
    if not np.all(np.isfinite(a)):
        raise InputError(f"{path}: NaN or infinite value in row {int(np.argwhere(~np.isfinite(a))[0][0]) + 2}")
    return a[:, 0] * LENGTH_TO_NM[units[0]], a[:, 1], units[1]


def source_file(path: Path) -> Path | None:
    """The NanoScope file an export was made from (`X.000 - NanoScope Analysis.txt` -> `X.000`), if beside it."""
    m = re.match(r"^(.*?\.\d{3})(?!\d)", export_name(path))
    if m is None:
        return None
    candidate = Path(path).with_name(m.group(1))
    return candidate if candidate.is_file() else None


def read_nanoscope_text(path: Path, spring_constant_N_per_m: float | None = None) -> Recording:
    """A NanoScope Analysis export as a `Recording` of one segment (µm, nN, s)."""
    path = Path(path)
    z_nm, values, unit = read_columns(path)
    kind = "approach" if z_nm[-1] > z_nm[0] else "retract" if z_nm[-1] < z_nm[0] else None
    if kind is None:
        raise InputError(f"{path}: Z does not change from the first row to the last (not a ramp)")
    origin = source_file(path)
    curve = read_curve(origin, origin.read_bytes()) if origin is not None else None
    k = spring_constant_N_per_m if spring_constant_N_per_m is not None else \
        curve.spring_constant_N_per_m if curve is not None else None
    if k is None:
        raise InputError(f"{path}: a NanoScope Analysis export holds no spring constant: give "
                         "--spring-constant N_PER_M, or keep the NanoScope file it was exported from beside it")
    if not k > 0:
        raise InputError(f"{path}: spring constant {k} N/m (must be > 0)")
    force = values * LENGTH_TO_NM[unit] * k if unit in LENGTH_TO_NM else values * FORCE_TO_NN[unit]
    n = len(z_nm)
    if curve is not None:
        ramp_s = curve.extend_duration_s if kind == "approach" else curve.retract_duration_s
        dt = ramp_s / curve.n_ramp
    else:
        dt = float("nan")
    seg = RecordedSegment(kind, n * dt, (np.arange(n) + 0.5) * dt, force, -z_nm / 1000.0)
    return Recording(cell_id=export_name(path), spring_constant_N_per_m=float(k), segments=[seg],
                     source=str(path), date=curve.date if curve is not None else "")
