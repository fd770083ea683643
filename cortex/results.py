"""A command's result on stdout: as one JSON object with `--json` (`say_result`), numpy
scalars as Python numbers and NaN as null (`plain`), else one line for a reader."""

from __future__ import annotations

import argparse
import json
import math
from typing import Any


def say_result(args: argparse.Namespace, result: dict[str, Any], line: str) -> None:
    """A command's result: `result` as one JSON object on stdout with --json, else `line`."""
    print(json.dumps(plain(result)) if args.json else line)


def plain(x: Any) -> Any:
    """`x` with numpy scalars as Python numbers and NaN as None, in dicts and lists too (for json.dumps)."""
    if isinstance(x, dict):
        return {k: plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [plain(v) for v in x]
    if hasattr(x, "item"):
        x = x.item()
    return None if isinstance(x, float) and math.isnan(x) else x
