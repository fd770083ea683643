"""Reader for JPK text exports (`force-save-*.txt`, JPK instrument software).

The file is a sequence of segments, each a block of `# key: value` header
lines (`segment`, `columns`, `units`, `springConstant` (N/m), `sensitivity`
(m/V), ...) followed by whitespace-separated numbers, one row per sample.
Lines before the first `segmentIndex` are the global header.

Units are converted to the project's: lengths m -> µm, force N -> nN. The
vertical deflection is force when its unit is N; when it is V (raw) it is
converted as F = V · sensitivity · k (sensitivity m/V, k spring constant N/m);
in m, as F = d · k. Any other unit raises InputError.

Binary `.jpk-force` archives are not read here (see the README: the PyPI
package `afmformats` reads them; export to text from the JPK software or
convert with afmformats first).
"""

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from solver.errors import InputError

LENGTH_TO_UM = {"m": 1e6, "um": 1.0, "µm": 1.0, "nm": 1e-3}
FORCE_TO_NN = {"N": 1e9, "nN": 1.0, "pN": 1e-3}
HEIGHT_COLUMNS = ("smoothedMeasuredHeight", "measuredHeight", "height", "capacitiveSensorHeight")


@dataclass
class JpkSegment:
    index: int
    name: str                           # extend, pause, retract, ...
    header: dict
    data: pd.DataFrame                  # time_s, force_nN, height_um (+ other columns, converted)
    spring_constant_N_per_m: float
    sensitivity_m_per_V: float
    units: dict = field(default_factory=dict)   # column -> unit as in the file


@dataclass
class JpkExport:
    path: Path
    header: dict
    segments: list


def _blocks(path):
    """Split the file into (header lines, data lines) per segment."""
    glob, blocks, cur = {}, [], None
    with open(path, encoding="utf-8", errors="strict") as fh:
        for lineno, line in enumerate(fh, 1):
            s = line.strip()
            if not s:
                continue
            if s.startswith("#"):
                key, sep, value = s[1:].partition(":")
                key = key.strip()
                new = cur is None and key == "segmentIndex"
                if cur is not None and (cur["data"] or (key == "segmentIndex" and key in cur["header"])):
                    new = True
                if new:
                    cur = {"header": {}, "data": [], "line": lineno}
                    blocks.append(cur)
                if sep:
                    (cur["header"] if cur is not None else glob)[key] = value.strip()
            else:
                if cur is None:
                    raise InputError(f"{path}:{lineno}: numbers before any segment header")
                cur["data"].append((lineno, s))
    return glob, blocks


def _float(path, seg, header, key):
    if key not in header:
        raise InputError(f"{path}: segment {seg}: header '{key}' missing")
    try:
        return float(header[key])
    except ValueError:
        raise InputError(f"{path}: segment {seg}: {key} = {header[key]!r} is not a number") from None


def read_jpk(path):
    """Parse a JPK text export into a `JpkExport` (units µm, nN, s)."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such file")
    try:
        glob, blocks = _blocks(path)
    except UnicodeDecodeError:
        raise InputError(f"{path}: not a JPK text export (binary; .jpk-force archives need afmformats)") from None
    if not blocks:
        raise InputError(f"{path}: no segments (no '# segmentIndex:' header)")
    segments = []
    for b in blocks:
        h = b["header"]
        seg = h.get("segmentIndex", "?")
        cols, units = h.get("columns", "").split(), h.get("units", "").split()
        if not cols or len(cols) != len(units):
            raise InputError(f"{path}: segment {seg}: 'columns' and 'units' headers missing or of "
                             f"different length ({len(cols)} vs {len(units)})")
        k = _float(path, seg, h, "springConstant")
        sens = _float(path, seg, h, "sensitivity") if "sensitivity" in h else float("nan")
        rows = []
        for lineno, s in b["data"]:
            parts = s.split()
            if len(parts) != len(cols):
                raise InputError(f"{path}:{lineno}: {len(parts)} values, the header names {len(cols)} columns")
            try:
                rows.append([float(p) for p in parts])
            except ValueError:
                raise InputError(f"{path}:{lineno}: not a number in {s[:40]!r}") from None
        a = np.array(rows, float).reshape(-1, len(cols))
        if "recorded-num-points" in h and int(float(h["recorded-num-points"])) != len(a):
            raise InputError(f"{path}: segment {seg}: {len(a)} rows, header says recorded-num-points "
                             f"{h['recorded-num-points']} (truncated file?)")
        if not np.all(np.isfinite(a)):
            r = np.argwhere(~np.isfinite(a))[0]
            raise InputError(f"{path}: segment {seg}: NaN or infinite value in column {cols[r[1]]}, row {r[0]}")
        raw = dict(zip(cols, a.T))
        unit = dict(zip(cols, units))
        out = {}
        if "time" not in raw:
            raise InputError(f"{path}: segment {seg}: no 'time' column")
        out["time_s"] = raw["time"]
        if "seriesTime" in raw:
            out["series_time_s"] = raw["seriesTime"]
        if "vDeflection" not in raw:
            raise InputError(f"{path}: segment {seg}: no 'vDeflection' column")
        u = unit["vDeflection"]
        if u in FORCE_TO_NN:
            out["force_nN"] = raw["vDeflection"] * FORCE_TO_NN[u]
        elif u == "V":
            if not np.isfinite(sens):
                raise InputError(f"{path}: segment {seg}: vDeflection in V but no sensitivity header")
            out["force_nN"] = raw["vDeflection"] * sens * k * 1e9
        elif u in LENGTH_TO_UM:
            out["force_nN"] = raw["vDeflection"] * LENGTH_TO_UM[u] * 1e-6 * k * 1e9
        else:
            raise InputError(f"{path}: segment {seg}: vDeflection in unknown unit {u!r} (expected N, V or m)")
        for c in cols:
            if c in HEIGHT_COLUMNS:
                if unit[c] not in LENGTH_TO_UM:
                    raise InputError(f"{path}: segment {seg}: column {c} in unit {unit[c]!r} (expected a length)")
                out[f"{c}_um"] = raw[c] * LENGTH_TO_UM[unit[c]]
        hcol = next((c for c in HEIGHT_COLUMNS if c in raw), None)
        if hcol is None:
            raise InputError(f"{path}: segment {seg}: no height column ({', '.join(HEIGHT_COLUMNS)})")
        out["height_um"] = out[f"{hcol}_um"]
        segments.append(JpkSegment(index=int(float(seg)) if seg != "?" else len(segments),
                                   name=h.get("segment", ""), header=h, data=pd.DataFrame(out),
                                   spring_constant_N_per_m=k, sensitivity_m_per_V=sens, units=unit))
    return JpkExport(path=path, header=glob, segments=segments)
