"""Reader for JPK text exports (`force-save-*.txt`, JPK instrument software;
also gzip-compressed, `.txt.gz`, read as they are).

The file is a sequence of segments, each a block of `# key: value` header
lines (`segment`, `columns`, `units`, `springConstant` (N/m), `sensitivity`
(m/V), ...) followed by whitespace-separated numbers, one row per sample.
Lines before the first `segmentIndex` are the global header.

Units are converted to the project's: lengths m -> µm, force N -> nN. The
vertical deflection is force when its unit is N; when it is V (raw) it is
converted as F = V · sensitivity · k (sensitivity m/V, k spring constant N/m);
in m, as F = d · k. Any other unit raises InputError.

`read_jpk_recording` turns an export into a `recording.Recording`: each
segment's kind from its `segment` header (extend, pause, modulation, retract),
its duration and, for a modulation, frequency (Hz) and amplitude (m -> µm)
from the global header's `force-settings.segment.N.*`; the time is
`seriesTime` (from the start of the recording) where present, else the
segment's `time` plus the durations of the segments before it. Binary
archives are read by `archive`.
"""

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from analysis.afm.formats.recording import HEIGHT_CHANNELS, RecordedSegment, Recording, kind_of
from analysis.afm.formats.textfiles import export_name, open_text
from common.errors import InputError

LENGTH_TO_UM = {"m": 1e6, "um": 1.0, "µm": 1.0, "nm": 1e-3}
FORCE_TO_NN = {"N": 1e9, "nN": 1.0, "pN": 1e-3}
HEIGHT_COLUMNS = HEIGHT_CHANNELS


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
    header: dict[str, str]
    segments: list[JpkSegment]


def _blocks(path: Path) -> tuple[dict[str, str], list[dict[str, Any]]]:
    """Split the file into (header lines, data lines) per segment."""
    glob: dict[str, str] = {}
    blocks: list[dict[str, Any]] = []
    cur: dict[str, Any] | None = None
    with open_text(path, encoding="utf-8") as fh:
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


def _float(path: Path, seg: str, header: dict[str, str], key: str) -> float:
    if key not in header:
        raise InputError(f"{path}: segment {seg}: header '{key}' missing")
    try:
        return float(header[key])
    except ValueError:
        raise InputError(f"{path}: segment {seg}: {key} = {header[key]!r} is not a number") from None


def _numbers(path: Path, seg: str, h: dict[str, str], block: dict[str, Any], cols: list[str]) -> Any:
    """The segment's data lines as a (rows, columns) array, checked against the header."""
    rows = []
    for lineno, line in block["data"]:
        parts = line.split()
        if len(parts) != len(cols):
            raise InputError(f"{path}:{lineno}: {len(parts)} values, the header names {len(cols)} columns")
        try:
            rows.append([float(p) for p in parts])
        except ValueError:
            raise InputError(f"{path}:{lineno}: not a number in {line[:40]!r}") from None
    a = np.array(rows, float).reshape(-1, len(cols))
    if "recorded-num-points" in h and int(float(h["recorded-num-points"])) != len(a):
        raise InputError(f"{path}: segment {seg}: {len(a)} rows, header says recorded-num-points "
                         f"{h['recorded-num-points']} (truncated file?)")
    if not np.all(np.isfinite(a)):
        r = np.argwhere(~np.isfinite(a))[0]
        raise InputError(f"{path}: segment {seg}: NaN or infinite value in column {cols[r[1]]}, row {r[0]}")
    return a


def _force_nN(where: str, deflection: Any, u: str, k: float, sens: float) -> Any:
    """The deflection column in nN: a force, a voltage (× sensitivity m/V × k N/m)
    or a length (× k N/m)."""
    if u in FORCE_TO_NN:
        return deflection * FORCE_TO_NN[u]
    if u == "V":
        if not np.isfinite(sens):
            raise InputError(f"{where}: vDeflection in V but no sensitivity header")
        return deflection * sens * k * 1e9
    if u in LENGTH_TO_UM:
        return deflection * LENGTH_TO_UM[u] * 1e-6 * k * 1e9
    raise InputError(f"{where}: vDeflection in unknown unit {u!r} (expected N, V or m)")


def _columns(where: str, raw: dict[str, Any], unit: dict[str, str], cols: list[str], k: float,
             sens: float) -> dict[str, Any]:
    """{column name with unit: values}: time, force and every height column in µm."""
    out = {}
    if "time" not in raw:
        raise InputError(f"{where}: no 'time' column")
    out["time_s"] = raw["time"]
    if "seriesTime" in raw:
        out["series_time_s"] = raw["seriesTime"]
    if "vDeflection" not in raw:
        raise InputError(f"{where}: no 'vDeflection' column")
    out["force_nN"] = _force_nN(where, raw["vDeflection"], unit["vDeflection"], k, sens)
    for c in cols:
        if c in HEIGHT_COLUMNS:
            if unit[c] not in LENGTH_TO_UM:
                raise InputError(f"{where}: column {c} in unit {unit[c]!r} (expected a length)")
            out[f"{c}_um"] = raw[c] * LENGTH_TO_UM[unit[c]]
    hcol = next((c for c in HEIGHT_COLUMNS if c in raw), None)
    if hcol is None:
        raise InputError(f"{where}: no height column ({', '.join(HEIGHT_COLUMNS)})")
    out["height_um"] = out[f"{hcol}_um"]
    return out


def _segment(path: Path, block: dict[str, Any], position: int) -> JpkSegment:
    """One `JpkSegment` of a parsed block (`position`: its place, if the header has no index)."""
    h = block["header"]
    seg = h.get("segmentIndex", "?")
    cols, units = h.get("columns", "").split(), h.get("units", "").split()
    if not cols or len(cols) != len(units):
        raise InputError(f"{path}: segment {seg}: 'columns' and 'units' headers missing or of "
                         f"different length ({len(cols)} vs {len(units)})")
    k = _float(path, seg, h, "springConstant")
    sens = _float(path, seg, h, "sensitivity") if "sensitivity" in h else float("nan")
    a = _numbers(path, seg, h, block, cols)
    unit = dict(zip(cols, units))
    out = _columns(f"{path}: segment {seg}", dict(zip(cols, a.T)), unit, cols, k, sens)
    return JpkSegment(index=int(float(seg)) if seg != "?" else position,
                      name=h.get("segment", ""), header=h, data=pd.DataFrame(out),
                      spring_constant_N_per_m=k, sensitivity_m_per_V=sens, units=unit)


def read_jpk(path: str | Path) -> JpkExport:
    """Parse a JPK text export into a `JpkExport` (units µm, nN, s)."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such file")
    try:
        glob, blocks = _blocks(path)
    except UnicodeDecodeError:
        raise InputError(f"{path}: not a JPK text export (binary data; a binary JPK archive is read by its "
                         "suffix: .jpk-force, .jpk-force-map, .jpk-qi-data)") from None
    except (OSError, EOFError) as err:
        raise InputError(f"{path}: cannot be read ({err})") from None
    if not blocks:
        raise InputError(f"{path}: no segments (no '# segmentIndex:' header)")
    segments: list[JpkSegment] = []
    for b in blocks:
        segments.append(_segment(path, b, len(segments)))
    return JpkExport(path=path, header=glob, segments=segments)


def _segment_setting(glob: dict[str, str], seg: JpkSegment, key: str) -> float:
    """`force-settings.segment.N.key` of a segment: its block's header, else the file's first lines."""
    name = f"force-settings.segment.{seg.index}.{key}"
    v = seg.header.get(name, glob.get(name))
    try:
        return float(v) if v is not None else float("nan")
    except ValueError:
        raise InputError(f"segment {seg.index}: force-settings.segment.{seg.index}.{key} = {v!r} "
                         "is not a number") from None


def read_jpk_recording(path: str | Path) -> Recording:
    """A JPK text export as one `Recording` (units s, nN, µm)."""
    export = read_jpk(path)
    segments, start = [], 0.0
    for seg in export.segments:
        where = f"{export.path}: segment {seg.index}"
        kind = kind_of(seg.name, where)
        d = seg.data
        try:
            duration = _segment_setting(export.header, seg, "duration")
            freq = _segment_setting(export.header, seg, "frequency")
            amp = _segment_setting(export.header, seg, "amplitude") * 1e6
        except InputError as err:
            raise InputError(f"{export.path}: {err}") from None
        if not np.isfinite(duration):
            dt = np.diff(d["time_s"]).mean() if len(d) > 1 else 0.0
            duration = float(d["time_s"].iat[-1] - d["time_s"].iat[0] + dt) if len(d) else 0.0
        if kind == "modulation" and not (np.isfinite(freq) and np.isfinite(amp)):
            raise InputError(f"{where}: modulation without force-settings.segment.{seg.index}.frequency "
                             "and .amplitude")
        t = d["series_time_s"] if "series_time_s" in d else d["time_s"] + start
        segments.append(RecordedSegment(kind=kind, duration_s=duration, time_s=t.to_numpy(float),
                                        force_nN=d["force_nN"].to_numpy(float),
                                        height_um=d["height_um"].to_numpy(float),
                                        frequency_hz=freq if kind == "modulation" else float("nan"),
                                        amplitude_um=amp if kind == "modulation" else float("nan")))
        start += duration
    k = {s.spring_constant_N_per_m for s in export.segments}
    if len(k) != 1:
        raise InputError(f"{export.path}: segments disagree on the spring constant {sorted(k)}")
    return Recording(cell_id=export_name(export.path), spring_constant_N_per_m=k.pop(), segments=segments,
                     source=str(export.path), date=export.header.get("date", ""))
