"""A campaign's points for a task kind with parameters of its own (`campaign.kinds.Kind.params`,
other than the protocol's, `campaign.protocol_grid`): each shell of the grid under each point of
the `[params]` section's product.

The `[params]` section names every one of the kind's parameters, and only those, each a number or
a non-empty list of finite numbers (the kind's compute function checks what values it takes).
The points are the product of the lists in the kind's order (m of them, the last fastest); point
i is shell i // m under parameter point i % m. A point's store columns are the shell's and the
kind's parameters; its id and the campaign's fingerprint are made from `ParamPoint.to_dict`, the
shell's fields and the parameters'.
"""

import itertools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from campaign.grid import Grid
from campaign.shell_product import ShellProduct, numbers
from common.errors import InputError
from solver.model import Shell


@dataclass(frozen=True)
class ParamPoint:
    """One point: the shell and the kind's parameters' values (column -> value)."""

    shell: Shell
    values: Mapping[str, float]

    def to_dict(self) -> dict[str, object]:
        """The shell's fields and the parameters' values."""
        return {**self.shell.to_dict(), **self.values}


def params_axes(path: Any, section: Any, names: Sequence[str]) -> dict[str, list[float]]:
    """The `[params]` section's axes, in the order of `names` (the kind's parameters); InputError
    naming what is wrong if a name is missing or unknown, or a value is not a finite number."""
    if not isinstance(section, dict):
        raise InputError(f"{path}: [params] must be a table")
    missing = [k for k in names if k not in section]
    unknown = sorted(set(section) - set(names))
    if missing or unknown:
        raise InputError(f"{path}: [params] names the task kind's parameters, {', '.join(names)}"
                         + (f" (missing: {', '.join(missing)})" if missing else "")
                         + (f" (unknown: {', '.join(unknown)})" if unknown else ""))
    axes = {}
    for key in names:
        values = numbers(section[key])
        if values is None:
            raise InputError(f"{path}: [params] {key} must be a finite number or a non-empty list of them "
                             f"(got {section[key]!r})")
        axes[key] = values
    return axes


class ParamGrid(ShellProduct):
    """The points of `shells` × the product of the `[params]` `axes` (`params_axes`)."""

    noun = "parameter point"

    def __init__(self, shells: Grid, axes: Mapping[str, list[float]]):
        super().__init__(shells, list(itertools.product(*axes.values())), tuple(axes))

    def point(self, shell: Shell, values: tuple[Any, ...]) -> ParamPoint:
        return ParamPoint(shell, dict(zip(self.names, values)))
