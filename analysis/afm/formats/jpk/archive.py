"""Reader of binary JPK archives: `.jpk-force` (one force curve),
`.jpk-force-map` / `.jpk-qi-data` (one curve per pixel) and `.jpk-qi-series`.

An archive is a zip of properties files and big-endian channel files:

    header.properties                      type, file-format-version, (maps) force-scan-map.settings...
    shared-data/header.properties          (optional) lcd-info.K.* (channel encoders and conversions),
                                           force-segment-header-info.K.* (segment settings)
    [index/P/]segments/N/segment-header.properties
    [index/P/]segments/N/channels/NAME.dat

Pixels P exist in maps and QI data only. A segment's header gives
`force-segment-header.num-points` n and `.duration` T; its sample times are
t_i = t_N + (i + 1/2) T / n with t_N the sum of the durations before it
(`recording.segment_times`). Its kind comes from the settings' `style`
(`force-segment-header.settings.segment-settings.*`, in maps through the
reference `force-segment-header.force-segment-header-info.*=K`, or else from the
top-level `<type>.settings.force-settings.segment.N.*`); a `modulation`
segment (settings type `sine-z-modulation-segment-settings`) has `frequency`
(Hz) and `amplitude` (m) there. Channels are decoded by `channels`:
the force F = `vDeflection` in its `force` slot (N -> nN), the spring constant
k its force multiplier (N/m), the height z the first channel of
`recording.HEIGHT_CHANNELS` in its default slot (m -> µm).
"""

import re
import zipfile
import zlib
from pathlib import Path

import numpy as np
import numpy.typing as npt

from analysis.afm.formats.jpk.channels import convert, multiplier
from analysis.afm.formats.jpk.properties import parse_properties, resolve_shared, subtree
from analysis.afm.formats.recording import HEIGHT_CHANNELS, RecordedSegment, Recording, kind_of, segment_times
from common.errors import InputError

SUFFIXES = (".jpk-force", ".jpk-force-map", ".jpk-qi-data", ".jpk-qi-series")
_SEGMENT = re.compile(r"^(index/(\d+)/)?segments/(\d+)/")


class _Archive:
    """The zip, with every read turned into InputError on damage."""

    def __init__(self, path: Path) -> None:
        self.path = path
        try:
            self.zip = zipfile.ZipFile(path)
            self.names = set(self.zip.namelist())
        except (zipfile.BadZipFile, OSError, EOFError):
            raise InputError(f"{path}: not a JPK archive (not a zip file, or truncated)") from None

    def read(self, name: str) -> bytes:
        if name not in self.names:
            raise InputError(f"{self.path}: '{name}' missing from the archive")
        try:
            return self.zip.read(name)
        except (zipfile.BadZipFile, zlib.error, EOFError, OSError):
            raise InputError(f"{self.path}: '{name}' unreadable (truncated or corrupt archive)") from None

    def properties(self, name: str) -> dict[str, str]:
        try:
            text = self.read(name).decode("iso-8859-1")
        except UnicodeDecodeError:
            raise InputError(f"{self.path}: '{name}' is not a properties text") from None
        return parse_properties(text, f"{self.path}: {name}")


def _number(props: dict[str, str], keys: list[str], where: str) -> float:
    for key in keys:
        if key in props:
            try:
                return float(props[key])
            except ValueError:
                raise InputError(f"{where}: {key} = {props[key]!r} is not a number") from None
    raise InputError(f"{where}: header '{keys[0]}' missing")


def _settings(seg: dict[str, str], top: dict[str, str], index: int) -> dict[str, str]:
    """A segment's settings: its own header's, else the top-level header's copy."""
    own = subtree(seg, "force-segment-header.settings.segment-settings")
    if own:
        return own
    return subtree(top, f"{top.get('type', '')}.settings.force-settings.segment.{index}")


def _channel(arc: _Archive, seg: dict[str, str], folder: str, name: str, slot: str | None, where: str
             ) -> tuple[npt.NDArray[np.float64], str]:
    ch = subtree(seg, f"channel.{name}")
    raw = arc.read(folder + ch.get("data.file.name", f"channels/{name}.dat"))
    n = int(_number(seg, ["force-segment-header.num-points"], where))
    return convert(ch, raw, n, slot, f"{where}: channel {name}")


def _segment(arc: _Archive, top: dict[str, str], shared: dict[str, str], folder: str, index: int,
             start_s: float) -> tuple[RecordedSegment, float, str]:
    where = f"{arc.path}: {folder}"
    seg = resolve_shared(arc.properties(folder + "segment-header.properties"), shared, where)
    settings = _settings(seg, top, index)
    style = settings.get("style") or seg.get("force-segment-header.settings.style")
    kind = kind_of(style, where)
    n = int(_number(seg, ["force-segment-header.num-points"], where))
    duration = _number({**settings, **seg}, ["force-segment-header.duration", "duration"], where)
    channels = seg.get("channels.list", "").split()
    if "vDeflection" not in channels:
        raise InputError(f"{where}: no vDeflection channel (has {', '.join(channels) or 'none'})")
    height = next((c for c in HEIGHT_CHANNELS if c in channels), None)
    if height is None:
        raise InputError(f"{where}: no height channel ({', '.join(HEIGHT_CHANNELS)})")
    force, f_unit = _channel(arc, seg, folder, "vDeflection", "force", where)
    z, z_unit = _channel(arc, seg, folder, height, None, where)
    if f_unit != "N" or z_unit != "m":
        raise InputError(f"{where}: force in {f_unit!r}, height in {z_unit!r} (expected N and m)")
    k = multiplier(subtree(seg, "channel.vDeflection"), "force", f"{where}: channel vDeflection")
    out = RecordedSegment(kind=kind, duration_s=duration, time_s=segment_times(start_s, duration, n),
                          force_nN=force * 1e9, height_um=z * 1e6)
    if kind == "modulation":
        out.frequency_hz = _number(settings, ["frequency"], f"{where} modulation settings")
        out.amplitude_um = _number(settings, ["amplitude"], f"{where} modulation settings") * 1e6
    return out, k, seg.get("force-segment-header.time-stamp", "")


def _layout(arc: _Archive) -> dict[int | None, list[int]]:
    """{pixel (None for a single curve): [segment indices]}, every segment with its header."""
    found: dict[int | None, set[int]] = {}
    for name in arc.names:
        m = _SEGMENT.match(name)
        if m:
            pixel = int(m.group(2)) if m.group(2) is not None else None
            found.setdefault(pixel, set()).add(int(m.group(3)))
    if not found:
        raise InputError(f"{arc.path}: no segments/N/ in the archive")
    return {p: sorted(s) for p, s in sorted(found.items(), key=lambda kv: -1 if kv[0] is None else kv[0])}


def read_archive(path: str | Path) -> list[Recording]:
    """All recordings of a binary JPK archive (one, or one per map/QI pixel)."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such file")
    arc = _Archive(path)
    top = arc.properties("header.properties")
    shared = arc.properties("shared-data/header.properties") if "shared-data/header.properties" in arc.names else {}
    stem = path.name[:-len(path.suffix)] if path.suffix else path.name
    recordings = []
    for pixel, indices in _layout(arc).items():
        base = "" if pixel is None else f"index/{pixel}/"
        segs, springs, start, stamp = [], set(), 0.0, ""
        for i in indices:
            seg, k, t = _segment(arc, top, shared, f"{base}segments/{i}/", i, start)
            segs.append(seg)
            springs.add(k)
            start += seg.duration_s
            stamp = stamp or t
        if len(springs) != 1:
            raise InputError(f"{path}: pixel {pixel}: segments disagree on the spring constant {sorted(springs)}")
        recordings.append(Recording(cell_id=stem if pixel is None else f"{stem}-px{pixel}",
                                    spring_constant_N_per_m=springs.pop(), segments=segs,
                                    source=str(path), date=stamp))
    return recordings
