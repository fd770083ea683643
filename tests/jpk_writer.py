"""Test scaffolding: JPK-like archives with modulation segments, written from
native cells of known truth (not a production path).

Each native segment becomes a JPK segment (approach -> extend, oscillation ->
modulation with its frequency and amplitude); its samples are written as
JPK would record them: vDeflection as big-endian int32 counts with an
encoder (V) and conversions distance (sensitivity, m/V) and force (k, N/m),
measuredHeight as int32 counts of an encoder in m, z = h - F/k + Z (the
inverse of `formats.instruments`'s h = z + F/k - Z). The duration of a segment is its
sample count times its sampling interval, so the reader's mid-sample times
differ from the cell's by half an interval, a shift that no fit depends on.

`write_force` writes one `.jpk-force` per cell with every setting inline;
`write_map` writes one `.jpk-force-map` with one pixel per cell, channel and
segment settings shared through `lcd-info.*` and `force-segment-header-info.*`
references, or (`settings_at_top`) only in the top-level header.
"""

import dataclasses
import zipfile

import numpy as np

STYLE = {"approach": "extend", "pause": "pause", "retract": "retract", "oscillation": "modulation"}
SENSITIVITY, VOLT_COUNT, METRE_COUNT = 5e-8, 1e-8, 1e-13      # m/V, V per count, m per count


def _props(d):
    return "".join(f"{k}={v}\n" for k, v in d.items()).encode("iso-8859-1")


def _linear(prefix, offset, mult, unit):
    return {f"{prefix}.type": "linear", f"{prefix}.style": "offsetmultiplier",
            f"{prefix}.offset": repr(float(offset)), f"{prefix}.multiplier": repr(float(mult)),
            f"{prefix}.unit.type": "metric-unit", f"{prefix}.unit.unit": unit}


def channel_settings(name, k):
    """Encoder and conversion set of vDeflection or measuredHeight (keys without a prefix)."""
    if name == "vDeflection":
        d = {"type": "integer-data", "encoder.type": "signedinteger",
             **_linear("encoder.scaling", 0.0, VOLT_COUNT, "V"),
             "conversion-set.conversions.list": "distance force", "conversion-set.conversions.default": "force",
             "conversion-set.conversions.base": "volts", "conversion-set.conversion.volts.defined": "false"}
        for slot, base, mult, unit in (("distance", "volts", SENSITIVITY, "m"), ("force", "distance", k, "N")):
            d |= {f"conversion-set.conversion.{slot}.defined": "true",
                  f"conversion-set.conversion.{slot}.base-calibration-slot": base,
                  **_linear(f"conversion-set.conversion.{slot}.scaling", 0.0, mult, unit)}
        return d
    return {"type": "integer-data", "encoder.type": "signedinteger",
            **_linear("encoder.scaling", 0.0, METRE_COUNT, "m"),
            "conversion-set.conversions.list": "nominal", "conversion-set.conversions.default": "nominal",
            "conversion-set.conversions.base": "absolute", "conversion-set.conversion.nominal.defined": "true",
            "conversion-set.conversion.nominal.base-calibration-slot": "absolute",
            **_linear("conversion-set.conversion.nominal.scaling", 0.0, 1.0, "m")}


def _counts(cell, seg, dish_um):
    f = cell.force_nN[seg.start:seg.stop] * 1e-9
    k = cell.spring_constant_N_per_m
    z = (cell.height_um[seg.start:seg.stop] * 1e-6 - f / k + dish_um * 1e-6)
    volts = f / k / SENSITIVITY
    return {"vDeflection": np.round(volts / VOLT_COUNT).astype(">i4").tobytes(),
            "measuredHeight": np.round(z / METRE_COUNT).astype(">i4").tobytes()}


def segment_settings(cell, seg):
    n = seg.stop - seg.start
    dt = (cell.time_s[seg.stop - 1] - cell.time_s[seg.start]) / (n - 1) if n > 1 else 1.0
    s = {"style": STYLE[seg.kind], "duration": repr(float(n * dt)), "num-points": str(n)}
    if seg.kind == "oscillation":
        s |= {"type": "sine-z-modulation-segment-settings", "frequency": repr(float(seg.frequency_hz)),
              "amplitude": repr(float(seg.amplitude_um if np.isfinite(seg.amplitude_um) else 0.25) * 1e-6)}
    return s


def _segment_files(cell, seg, dish_um, shared):
    """{name in the segment folder: bytes}; `shared`: (lcd index of each channel, settings index) or None."""
    st = segment_settings(cell, seg)
    head = {"force-segment-header.type": "spm-force-segment-header", "force-segment-header.duration": st["duration"],
            "force-segment-header.num-points": st["num-points"], "channels.list": "vDeflection measuredHeight"}
    if shared is None:
        head |= {f"force-segment-header.settings.segment-settings.{k}": v for k, v in st.items()}
    elif shared[1] is not None:
        head["force-segment-header.force-segment-header-info.*"] = str(shared[1])
    files = {}
    for i, (name, raw) in enumerate(_counts(cell, seg, dish_um).items()):
        head[f"channel.{name}.data.file.name"] = f"channels/{name}.dat"
        head[f"channel.{name}.data.num-points"] = st["num-points"]
        if shared is None:
            head |= {f"channel.{name}.data.{k}" if k.startswith(("type", "encoder")) else f"channel.{name}.{k}": v
                     for k, v in channel_settings(name, cell.spring_constant_N_per_m).items()}
        else:
            head[f"channel.{name}.lcd-info.*"] = str(shared[0] + i)
        files[f"channels/{name}.dat"] = raw
    files["segment-header.properties"] = _props(head)
    return files


def write_force(path, cell, dish_um=0.0):
    """One cell as a `.jpk-force` archive, settings inline."""
    with zipfile.ZipFile(path, "w") as z:
        z.writestr("header.properties", _props({"jpk-data-file": "spm-forcefile", "type": "force-scan-series",
                                                "force-scan-series.force-segments.count": len(cell.segments)}))
        for j, seg in enumerate(cell.segments):
            for name, data in _segment_files(cell, seg, dish_um, None).items():
                z.writestr(f"segments/{j}/{name}", data)
    return path


def write_map(path, cells, dish_um=0.0, settings_at_top=False, scan_type="force-scan-map"):
    """Cells as the pixels of one `.jpk-force-map` (`scan_type` quantitative-imaging-map: `.jpk-qi-data`),
    settings in shared-data (or the top-level header);
    one cantilever, so every pixel is written with the first cell's spring constant."""
    cells = [dataclasses.replace(c, spring_constant_N_per_m=cells[0].spring_constant_N_per_m) for c in cells]
    shared, infos, top = {"lcd-infos.count": 2}, {}, {"jpk-data-file": "spm-forcemapfile", "type": scan_type}
    for i, name in enumerate(("vDeflection", "measuredHeight")):
        settings = channel_settings(name, cells[0].spring_constant_N_per_m)
        shared |= {f"lcd-info.{i}.channel.name": name, **{f"lcd-info.{i}.{k}": v for k, v in settings.items()}}
    with zipfile.ZipFile(path, "w") as z:
        for p, cell in enumerate(cells):
            for j, seg in enumerate(cell.segments):
                st = segment_settings(cell, seg)
                if settings_at_top:
                    top |= {f"{scan_type}.settings.force-settings.segment.{j}.{k}": v for k, v in st.items()}
                    info = None
                else:
                    info = infos.setdefault(tuple(sorted(st.items())), len(infos))
                    shared |= {f"force-segment-header-info.{info}.settings.segment-settings.{k}": v
                               for k, v in st.items()}
                for name, data in _segment_files(cell, seg, dish_um, (0, info)).items():
                    z.writestr(f"index/{p}/segments/{j}/{name}", data)
        z.writestr("header.properties", _props(top))
        z.writestr("shared-data/header.properties", _props(shared))
    return path
