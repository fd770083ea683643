r"""The text header of a Bruker NanoScope file (force curves: `\*Force file list`).

The header is latin-1 text at the start of the file, lines `\key: value`
grouped in lists that open with `\*Name` (`\*Force file list`,
`\*Scanner list`, `\*Ciao scan list`, `\*Ciao force list`, one `\*Ciao
force image list` per recorded channel, ...) and close with `\*File list
end`; a Ctrl-Z (0x1a) and padding follow up to the binary data.

Values whose key starts with `@` are parameters with a scale:

    \@Sens. DeflSens: V 43.38853 nm/V                       a sensitivity S (soft scale), nm/V
    \@4:Z scale: V [Sens. DeflSens] (0.0003750000 V/LSB) 2.500000 V
                   ^ which S       ^ hard scale q, V/LSB ^ value in V

A stored integer n of a channel is the quantity n · q · S (in S's unit
times V, e.g. nm): q is the hard scale in parentheses of that channel's
`@4:Z scale`, S the sensitivity named in brackets. (The value after the
parentheses, 2.5 V here, is the display range, not a conversion.)
"""

import re
from dataclasses import dataclass, field
from pathlib import Path

from common.errors import InputError

MAGIC = b"\\*Force file list"
IMAGE_MAGIC = b"\\*File list"
END = "\\*File list end"
HEADER_MAX_BYTES = 1 << 20              # far beyond any header (tens of kB)

_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_SCALED = re.compile(rf"^(?P<type>[VCS])\s*(?:\[(?P<sens>[^\]]*)\])?\s*"
                     rf"(?:\((?P<q>{_NUMBER})\s*(?P<q_unit>[^)]*)\))?\s*(?P<value>{_NUMBER})?\s*(?P<unit>.*)$")

_ENTRY = re.compile(r"^(?P<key>(?:@\d+:)?[^:]*):(?P<value>.*)$")     # `@4:Z scale: ...` keeps its `@4:`


@dataclass
class Scaled:
    """One `@` parameter: the sensitivity it refers to, its hard scale q and its value."""
    sens: str
    hard_scale: float
    value: float
    unit: str


@dataclass
class Header:
    """The lists of a NanoScope header in file order: (name, {key: raw value})."""
    path: Path
    lists: list = field(default_factory=list)

    def all(self, name: str) -> list:
        return [d for n, d in self.lists if n == name]

    def first(self, name: str) -> dict:
        found = self.all(name)
        if not found:
            raise InputError(f"{self.path}: header without a '\\*{name}'")
        return found[0]

    def text(self, entries: dict, key: str, where: str) -> str:
        if key not in entries:
            raise InputError(f"{self.path}: header without '\\{key}' in its {where}")
        return entries[key]

    def number(self, entries: dict, key: str, where: str, index: int = 0) -> float:
        """The index-th number of a plain entry (`\\Samps/line: 5632 5026`)."""
        found = re.findall(_NUMBER, self.text(entries, key, where))
        if len(found) <= index:
            raise InputError(f"{self.path}: '\\{key}' in its {where} is not a number: {entries[key]!r}")
        return float(found[index])

    def scaled(self, entries: dict, key: str, where: str) -> Scaled:
        raw = self.text(entries, key, where)
        m = _SCALED.match(raw.strip())
        if m is None:
            raise InputError(f"{self.path}: '\\{key}' in its {where} is not a scaled value: {raw!r}")
        q, v = m["q"], m["value"]
        return Scaled(sens=(m["sens"] or "").strip(), hard_scale=float(q) if q else float("nan"),
                      value=float(v) if v else float("nan"), unit=m["unit"].strip())

    def sensitivity(self, name: str) -> tuple:
        r"""(S, unit) of `\@Sens. NAME`, the first one in the header (e.g. (43.38853, 'nm/V'))."""
        key = "@" + name
        for _, entries in self.lists:
            if key in entries:
                s = self.scaled(entries, key, "header")
                if s.value != s.value:
                    break
                return s.value, s.unit
        raise InputError(f"{self.path}: header without the sensitivity '\\{key}' (a number with its unit)")


def read_header(path: Path, data: bytes) -> Header:
    """Parse the header at the start of `data` (the file's bytes)."""
    if not data.startswith(MAGIC):
        if data.startswith(IMAGE_MAGIC):
            raise InputError(f"{path}: a NanoScope image file, not a force curve ('\\*Force file list')")
        raise InputError(f"{path}: not a NanoScope force file (does not start with '\\*Force file list')")
    text = data[:HEADER_MAX_BYTES].split(b"\x1a", 1)[0].decode("latin-1")
    header, ended = Header(path=Path(path)), False
    entries: dict[str, str] | None = None
    for line in text.splitlines():
        line = line.strip()
        if not line.startswith("\\"):
            continue
        if line == END:
            ended = True
            break
        if line.startswith("\\*"):
            entries = {}
            header.lists.append((line[2:].strip(), entries))
            continue
        m = _ENTRY.match(line[1:])
        if m and entries is not None:
            entries.setdefault(m["key"].strip(), m["value"].strip())
    if not ended:
        raise InputError(f"{path}: truncated NanoScope header (no '{END}' before the end of the file)")
    return header
