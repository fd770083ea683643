"""Binary channels of a JPK archive: raw numbers -> physical values.

A channel's properties (after `properties.resolve_shared`, all under
`channel.NAME.`) give its storage and a chain of linear conversions:

- data type: `data.type` (`short`, `integer`, `long`, `float`, `double`) or, in
  shared headers, `type` (`short-data`, `integer-data`, `float-data`, ...);
  values are big-endian.
- encoder (`data.encoder.*` or `encoder.*`) for integer data: type
  `signedshort`, `unsignedshort`, `signedinteger`, `unsignedinteger`,
  `signedlong`, `unsignedlong`; scaling `linear`/`offsetmultiplier`:
  x_base = offset + multiplier · raw (the base unit, e.g. V).
  Float data are stored in the base unit.
- conversions (`conversion-set.*`): each slot S (`distance`, `force`,
  `nominal`, `calibrated`, ...) is linear, x_S = offset_S + multiplier_S ·
  x_{base(S)}, where base(S) = `conversion.S.base-calibration-slot`; the chain
  ends at the set's base slot (`conversions.base`, e.g. `volts`). For the
  deflection: d = m_distance · V (sensitivity, m/V), F = m_force · d (spring
  constant k, N/m).

Anything else (an unknown data or encoder type, a scaling that is not
linear offset-multiplier, a slot that is not defined, a data length that is
not the sample count) raises InputError naming the channel.
"""

import numpy as np
import numpy.typing as npt

from analysis.afm.formats.jpk.properties import subtree
from common.errors import InputError

ENCODER_DTYPES = {"signedshort": ">i2", "unsignedshort": ">u2", "signedinteger": ">i4",
                  "unsignedinteger": ">u4", "signedlong": ">i8", "unsignedlong": ">u8"}
INTEGER_TYPES = {"short", "short-data", "integer", "integer-data", "long", "long-data"}
FLOAT_DTYPES = {"float": ">f4", "float-data": ">f4", "double": ">f8", "double-data": ">f8"}


def _number(props: dict[str, str], key: str, where: str) -> float:
    if key not in props:
        raise InputError(f"{where}: '{key}' missing")
    try:
        return float(props[key])
    except ValueError:
        raise InputError(f"{where}: {key} = {props[key]!r} is not a number") from None


def _linear(scaling: dict[str, str], where: str) -> tuple[float, float, str]:
    """(offset, multiplier, unit) of a `scaling.*` subtree."""
    kind, style = scaling.get("type"), scaling.get("style")
    if kind != "linear" or style != "offsetmultiplier":
        raise InputError(f"{where}: scaling {kind!r}/{style!r} (only linear offsetmultiplier is known)")
    return _number(scaling, "offset", where), _number(scaling, "multiplier", where), scaling.get("unit.unit", "")


def _storage(ch: dict[str, str], where: str) -> tuple[str, dict[str, str] | None]:
    """(numpy dtype, encoder scaling or None) of one channel."""
    dtype = ch.get("data.type") or ch.get("type")
    encoder = subtree(ch, "data.encoder") or subtree(ch, "encoder")
    if dtype in FLOAT_DTYPES:
        return FLOAT_DTYPES[dtype], None
    if dtype is not None and dtype not in INTEGER_TYPES:
        raise InputError(f"{where}: unknown data type {dtype!r}")
    if not encoder:
        raise InputError(f"{where}: integer data without an encoder")
    etype = encoder.get("type")
    if etype not in ENCODER_DTYPES:
        raise InputError(f"{where}: unknown encoder {etype!r} (known: {', '.join(ENCODER_DTYPES)})")
    return ENCODER_DTYPES[etype], subtree(encoder, "scaling")


def base_values(ch: dict[str, str], raw: bytes, n_samples: int, where: str
                ) -> tuple[npt.NDArray[np.float64], str]:
    """The stored samples in the channel's base unit (e.g. V): (values, unit)."""
    dtype, scaling = _storage(ch, where)
    itemsize = np.dtype(dtype).itemsize
    if len(raw) != n_samples * itemsize:
        raise InputError(f"{where}: {len(raw)} bytes, expected {n_samples} samples of {itemsize} "
                         "(truncated channel?)")
    x = np.frombuffer(raw, dtype).astype(float)
    if scaling is None:
        return x, ch.get("unit.unit", "")
    offset, mult, unit = _linear(scaling, f"{where} encoder")
    return offset + mult * x, unit


def conversion_chain(ch: dict[str, str], slot: str | None, where: str) -> list[tuple[float, float, str]]:
    """[(offset, multiplier, unit), ...] from the base slot up to `slot`."""
    cs = subtree(ch, "conversion-set")
    base = cs.get("conversions.base")
    if not cs or base is None:
        raise InputError(f"{where}: no conversion set")
    chain, seen = [], set()
    while slot != base:
        conv = subtree(cs, f"conversion.{slot}")
        if slot in seen or conv.get("defined") != "true":
            raise InputError(f"{where}: conversion to '{slot}' not defined in the file")
        seen.add(slot)
        chain.append(_linear(subtree(conv, "scaling"), f"{where} conversion {slot}"))
        slot = conv.get("base-calibration-slot")
        if slot is None:
            raise InputError(f"{where}: conversion without a base-calibration-slot")
    return chain[::-1]


def convert(ch: dict[str, str], raw: bytes, n_samples: int, slot: str | None, where: str
            ) -> tuple[npt.NDArray[np.float64], str]:
    """Samples converted to conversion slot `slot` (None: the set's default): (values, unit)."""
    x, unit = base_values(ch, raw, n_samples, where)
    slot = slot or subtree(ch, "conversion-set").get("conversions.default")
    if slot is None:
        raise InputError(f"{where}: no default conversion")
    for offset, mult, unit in conversion_chain(ch, slot, where):
        x = offset + mult * x
    return x, unit


def multiplier(ch: dict[str, str], slot: str, where: str) -> float:
    """The multiplier of one conversion slot (e.g. `force`: the spring constant, N/m)."""
    return conversion_chain(ch, slot, where)[-1][1]
