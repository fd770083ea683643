r"""Reader for Bruker NanoScope force-curve files (`NAME.000`, `.001`, ...).

The file is a text header (`header`) and, for each recorded channel
(one `\*Ciao force image list` each: `\@4:Image Data: S [DeflectionError]
"Deflection Error"`, `[ZSensor] "Height Sensor"`, ...), a block of
`Data length` bytes at `Data offset`: little-endian signed integers of
`Bytes/pixel` bytes, two halves of n_ramp slots each (`Samps/line: n_ramp
[n_extend]`): the extend (approach) curve, stored from its last sample
back to its first and padded after its n_extend recorded samples (a
triggered ramp stops early), then the retract curve in time order
(`Samps/line, retrace`, else n_ramp, samples).

Conversions (units nm, V, s, N/m as in the header; the Recording in µm, nN, s):

    channel value c = n · q · S                   (nm; q V/LSB of its `@4:Z scale`, S its `Sens.`)
    force         F = k · d                        (nN = N/m · nm; d the deflection channel, k `Spring Constant`)
    height        z = −z_sensor / 1000             (µm; the height sensor grows as the piezo extends)
    ramp          Z_i = (n_ramp − n_extend + i) · L / n_ramp   (extend, nm; L = `@4:Ramp size` V · `Sens. Zsens`)
                  Z_j = (n_ramp − 1 − j) · L / n_ramp           (retract)
    times         extend over T_f = ramp size / `Forward vel.` (V / V/s) per n_ramp samples,
                  retract over T_r = ramp size / `Reverse vel.`; mid-sample, t = (i + 1/2) T / n_ramp

The ramp Z is the piezo's commanded travel, what NanoScope Analysis exports
as "Z"; z uses the height sensor (measured) where the file has it, else
−Z/1000. A surface hold (`Reverse delay` > 0 s) is not sampled in this
layout: it becomes a pause segment of that duration and no samples. The
force is the deflection as recorded (no baseline subtracted).
"""

import re
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path

import numpy as np

from analysis.afm.formats.bruker.header import Header, read_header
from analysis.afm.formats.recording import RecordedSegment, Recording
from common.errors import InputError

DEFLECTION_CHANNELS = ("DeflectionError", "Deflection")
HEIGHT_CHANNELS = ("ZSensor", "Height")
SUFFIX = re.compile(r"\.\d{3}$")               # NAME.000, NAME.001, ...: one curve each
INTEGERS = {2: "<i2", 4: "<i4"}
FORCE = "Ciao force list"
CHANNEL = "Ciao force image list"


def is_nanoscope_name(path: Path) -> bool:
    return bool(SUFFIX.search(Path(path).name))


@dataclass
class BrukerChannel:
    """One recorded channel, converted (unit as its sensitivity says, e.g. nm), in time order."""
    name: str
    unit: str
    sensitivity: float                # S of its conversion n · q · S (e.g. nm/V)
    extend: np.ndarray
    retract: np.ndarray


@dataclass
class BrukerCurve:
    """The header values that matter and the converted channels of one force curve."""
    path: Path
    version: str
    date: str
    spring_constant_N_per_m: float
    deflection_sensitivity_nm_per_V: float
    z_sensitivity_nm_per_V: float
    ramp_size_nm: float
    n_ramp: int
    n_extend: int
    n_retract: int
    extend_duration_s: float          # of a whole ramp (n_ramp samples)
    retract_duration_s: float
    hold_s: float
    channels: dict = field(default_factory=dict)

    def ramp_nm(self, kind: str) -> np.ndarray:
        """The commanded piezo travel Z (nm) of each sample of `extend` or `retract`."""
        step = self.ramp_size_nm / self.n_ramp
        if kind == "extend":
            return (self.n_ramp - self.n_extend + np.arange(self.n_extend)) * step
        return (self.n_ramp - 1 - np.arange(self.n_retract)) * step


def _channel(header: Header, entries: dict, data: bytes, counts: tuple) -> BrukerChannel:
    """One channel's data block, converted; `counts` (n_ramp, n_extend, n_retract) of the curve."""
    where = CHANNEL
    name = header.scaled(entries, "@4:Image Data", where).sens
    if not name:
        raise InputError(f"{header.path}: a channel without its name ('\\@4:Image Data: S [NAME] ...')")
    offset = int(header.number(entries, "Data offset", where))
    length = int(header.number(entries, "Data length", where))
    bpp = int(header.number(entries, "Bytes/pixel", where))
    n_ramp, n_extend, n_retract = counts
    if int(header.number(entries, "Samps/line", where)) != n_ramp:
        raise InputError(f"{header.path}: channel {name}: Samps/line differs from the first channel's {n_ramp}")
    if bpp not in INTEGERS:
        raise InputError(f"{header.path}: channel {name}: {bpp} bytes/pixel (expected 2 or 4)")
    if length != 2 * n_ramp * bpp:
        raise InputError(f"{header.path}: channel {name}: data length {length} bytes is not two curves of "
                         f"{n_ramp} samples of {bpp} bytes")
    if offset + length > len(data):
        raise InputError(f"{header.path}: channel {name}: data block shorter than stated (file ends at byte "
                         f"{len(data)}, the header says {offset} + {length})")
    z = header.scaled(entries, "@4:Z scale", where)
    if not z.hard_scale == z.hard_scale or not z.sens:
        raise InputError(f"{header.path}: channel {name}: '\\@4:Z scale' without [Sens. ...] and (V/LSB)")
    sens, unit = header.sensitivity(z.sens)
    raw = np.frombuffer(data, INTEGERS[bpp], 2 * n_ramp, offset).astype(float) * (z.hard_scale * sens)
    return BrukerChannel(name=name, unit=unit.split("/")[0].strip(), sensitivity=sens,
                         extend=raw[:n_extend][::-1].copy(),
                         retract=raw[n_ramp:n_ramp + n_retract].copy())


def _date(text: str) -> str:
    """`01:21:42 PM Wed May 05 2021` as ISO 8601; the text as it is if it has another form."""
    try:
        return datetime.strptime(text.strip(), "%I:%M:%S %p %a %b %d %Y").isoformat()
    except ValueError:
        return text.strip()


def _counts(header: Header, first: dict, force: dict) -> tuple:
    """(n_ramp, n_extend, n_retract): `Samps/line: n_ramp [n_extend]`, `Samps/line, retrace`."""
    counts = [int(c) for c in re.findall(r"\d+", header.text(first, "Samps/line", CHANNEL))]
    n_ramp = counts[0] if counts else 0
    n_extend = counts[1] if len(counts) > 1 else n_ramp
    n_retract = int(header.number(force, "Samps/line, retrace", FORCE)) if "Samps/line, retrace" in force \
        else n_ramp
    if not (0 < n_extend <= n_ramp and 0 < n_retract <= n_ramp):
        raise InputError(f"{header.path}: sample counts extend {n_extend}, retract {n_retract} outside "
                         f"1..{n_ramp} (Samps/line)")
    return n_ramp, n_extend, n_retract


def _channels(header: Header, lists: list, data: bytes, counts: tuple) -> dict:
    """{name: BrukerChannel} of every channel list; a deflection channel must be among them."""
    channels = {}
    for entries in lists:
        c = _channel(header, entries, data, counts)
        if c.name in DEFLECTION_CHANNELS + HEIGHT_CHANNELS and c.unit != "nm":
            raise InputError(f"{header.path}: channel {c.name} in {c.unit!r} (expected nm: a sensitivity in nm/V)")
        channels[c.name] = c
    if not any(name in channels for name in DEFLECTION_CHANNELS):
        raise InputError(f"{header.path}: no deflection channel ({', '.join(DEFLECTION_CHANNELS)}; "
                         f"has {', '.join(channels)})")
    return channels


def read_curve(path: Path, data: bytes) -> BrukerCurve:
    """The force curve of a NanoScope file's bytes (InputError, one line, if anything is missing)."""
    header = read_header(path, data)
    top, force = header.first("Force file list"), header.first(FORCE)
    if header.all("Ciao image list"):
        raise InputError(f"{path}: a NanoScope force volume (force curves with an image): not read, "
                         "only single force curves")
    lists = header.all(CHANNEL)
    if not lists:
        raise InputError(f"{path}: header without a '\\*{CHANNEL}' (no recorded channel)")
    n_ramp, n_extend, n_retract = counts = _counts(header, lists[0], force)
    k = header.number(lists[0], "Spring Constant", CHANNEL)
    if not k > 0:
        raise InputError(f"{path}: spring constant {k} N/m (must be > 0)")
    ramp = header.scaled(lists[0], "@4:Ramp size", CHANNEL)
    zsens, zunit = header.sensitivity(ramp.sens or "Sens. Zsens")
    forward, reverse = (header.number(force, key, FORCE) for key in ("Forward vel.", "Reverse vel."))
    if not (forward > 0 and reverse > 0 and ramp.value > 0):
        raise InputError(f"{path}: ramp size {ramp.value} V, velocities {forward}, {reverse} V/s (must be > 0)")
    if zunit.replace(" ", "") != "nm/V":
        raise InputError(f"{path}: Z sensitivity in {zunit!r} (expected nm/V)")
    channels = _channels(header, lists, data, counts)
    defl = next(channels[n] for n in DEFLECTION_CHANNELS if n in channels)
    hold = header.number(force, "Reverse delay", FORCE) if "Reverse delay" in force else 0.0
    return BrukerCurve(path=Path(path), version=top.get("Version", ""), date=_date(top.get("Date", "")),
                       spring_constant_N_per_m=k, deflection_sensitivity_nm_per_V=defl.sensitivity,
                       z_sensitivity_nm_per_V=zsens, ramp_size_nm=ramp.value * zsens, n_ramp=n_ramp,
                       n_extend=n_extend, n_retract=n_retract, extend_duration_s=ramp.value / forward,
                       retract_duration_s=ramp.value / reverse, hold_s=max(0.0, hold), channels=channels)


def _height_um(curve: BrukerCurve, kind: str) -> np.ndarray:
    for name in HEIGHT_CHANNELS:
        if name in curve.channels:
            return -getattr(curve.channels[name], kind) / 1000.0
    return -curve.ramp_nm(kind) / 1000.0


def to_recording(curve: BrukerCurve) -> Recording:
    """The curve as a `Recording`: approach, a pause if the ramp held, retract (µm, nN, s)."""
    defl = next(curve.channels[n] for n in DEFLECTION_CHANNELS if n in curve.channels)
    k = curve.spring_constant_N_per_m
    dt_e, dt_r = curve.extend_duration_s / curve.n_ramp, curve.retract_duration_s / curve.n_ramp
    t_e = (np.arange(curve.n_extend) + 0.5) * dt_e
    start = curve.n_extend * dt_e
    segments = [RecordedSegment("approach", curve.n_extend * dt_e, t_e, k * defl.extend, _height_um(curve, "extend"))]
    if curve.hold_s > 0:
        empty = np.zeros(0)
        segments.append(RecordedSegment("pause", curve.hold_s, empty, empty, empty))
        start += curve.hold_s
    t_r = start + (np.arange(curve.n_retract) + 0.5) * dt_r
    segments.append(RecordedSegment("retract", curve.n_retract * dt_r, t_r, k * defl.retract,
                                    _height_um(curve, "retract")))
    return Recording(cell_id=curve.path.name, spring_constant_N_per_m=k, segments=segments,
                     source=str(curve.path), date=curve.date)


def read_nanoscope(path: Path) -> Recording:
    """A NanoScope force-curve file as one `Recording`."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as err:
        raise InputError(f"{path}: cannot be read ({err.strerror})") from None
    return to_recording(read_curve(path, data))
