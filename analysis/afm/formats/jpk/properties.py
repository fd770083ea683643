"""Java `.properties` text, as JPK archives store every header, and the
`.*` references by which map and QI archives share one header among pixels.

A properties file is one `key=value` (or `key: value`) per logical line;
lines starting with `#` or `!` are comments, a trailing backslash continues
the line, and `\\:`, `\\=`, `\\uXXXX`, `\\t`, `\\n` are escapes (JPK writes `µ`
as `\\u00B5` and the colons of time stamps as `\\:`).

A reference `P.NAME.*=K` (e.g. `channel.height.lcd-info.*=1` or
`force-segment-header.force-segment-header-info.*=0`) stands for every shared
entry `NAME.K.REST` (from `shared-data/header.properties`), which
`resolve_shared` adds as `P.REST`.
"""

import re
from collections.abc import Iterator

from common.errors import InputError

_ESCAPES = {"t": "\t", "n": "\n", "r": "\r", "f": "\f"}
_ESCAPE = re.compile(r"\\(u[0-9a-fA-F]{4}|.)")


def _unescape(s: str) -> str:
    def sub(m: re.Match[str]) -> str:
        c = m.group(1)
        if len(c) == 5 and c[0] == "u":
            return chr(int(c[1:], 16))
        return _ESCAPES.get(c, c)
    return _ESCAPE.sub(sub, s)


def _logical_lines(text: str) -> Iterator[str]:
    buf = ""
    for raw in text.splitlines():
        line = raw.lstrip()
        if not buf and (not line or line[0] in "#!"):
            continue
        trailing = len(line) - len(line.rstrip("\\"))
        if trailing % 2:
            buf += line[:-1]
            continue
        yield buf + line
        buf = ""
    if buf:
        yield buf


def _split(line: str) -> tuple[str, str]:
    """(key, value) at the first unescaped `=`, `:` or blank."""
    i = 0
    while i < len(line) and line[i] not in "=: \t":
        i += 2 if line[i] == "\\" else 1
    key, rest = line[:i], line[i:].lstrip(" \t")
    if rest[:1] in ("=", ":"):
        rest = rest[1:].lstrip(" \t")
    return key, rest


def parse_properties(text: str, where: str) -> dict[str, str]:
    """The entries of a properties text as a dict of str (InputError if it holds none)."""
    props = {}
    for line in _logical_lines(text):
        key, value = _split(line)
        props[_unescape(key)] = _unescape(value)
    if not props:
        raise InputError(f"{where}: empty header (no key=value lines)")
    return props


def resolve_shared(props: dict[str, str], shared: dict[str, str], where: str) -> dict[str, str]:
    """`props` with every `P.NAME.*=K` reference replaced by the shared entries
    `NAME.K.*`, renamed `P.*` (entries of `props` itself win)."""
    out = dict(props)
    for key, value in props.items():
        if not key.endswith(".*"):
            continue
        parent, _, name = key[:-2].rpartition(".")
        prefix = f"{name}.{value.strip()}."
        found = {f"{parent}.{k[len(prefix):]}": v for k, v in shared.items() if k.startswith(prefix)}
        if not found:
            raise InputError(f"{where}: {key}={value} refers to shared header entries '{prefix}*' "
                             "that shared-data/header.properties does not have")
        for k, v in found.items():
            out.setdefault(k, v)
        del out[key]
    return out


def subtree(props: dict[str, str], prefix: str) -> dict[str, str]:
    """The entries under `prefix` (a dotted key, without the trailing dot), prefix removed."""
    p = prefix + "."
    return {k[len(p):]: v for k, v in props.items() if k.startswith(p)}
