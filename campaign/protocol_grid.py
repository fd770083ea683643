"""A protocol-bias campaign's nodes (`[campaign] task = "analysis.afm.synth.protocol_bias:protocol_bias"`, SPEC 12): each shell
of the grid (`campaign.grid.Grid`) under each point of the `[protocol]` section's product.

The `[protocol]` axes (PROTOCOL_KEYS):

    exponents      a list of pairs [β_B, β_S] of K(t) = K(1 s) (t/1 s)^-β (K(1 s): the grid's
                   moduli): pairs, not a product, so a campaign picks the ones it needs
    wait_s         T_w, the wait at the mean height before the oscillation (a number or a list)
    frequency_hz   f, the oscillation's frequency (a number or a list)

The protocol points are the product exponents × wait_s × frequency_hz (m of them, the last
fastest); node i is shell i // m under point i % m, so the protocol varies fastest. A node's
protocol (`bias_protocol`, a `solver.protocol.Protocol`): from the shell's h0 a ramp of Δh/2 to
the mean height h_m = h0 - Δh/2 at 0.2 µm/s, a hold of T_w there, 5 periods of 0.25 µm at f. A node's store columns are the shell's parameters and PROTOCOL_PARAMS
(a task kind with these parameters takes a `[protocol]` section, `campaign.kinds`; the frequency as `protocol_frequency_hz`, apart from the viscous
interior's `frequency_hz`); its id and the campaign's fingerprint are made from `to_dict`, the
shell's fields and the protocol's.
"""

import itertools
import math
from dataclasses import dataclass
from typing import Any

from campaign.grid import Grid
from campaign.shell_product import ShellProduct, numbers
from common.errors import InputError
from solver.model import Shell
from solver.protocol import Hold, Oscillate, Protocol, Ramp

PROTOCOL_KEYS = ("exponents", "wait_s", "frequency_hz")
NODE_KEYS = ("bulk_exponent", "shear_exponent", "wait_s", "frequency_hz")   # a node's protocol
COLUMN = {"bulk_exponent": "bulk_exponent", "shear_exponent": "shear_exponent", "wait_s": "wait_s",
          "frequency_hz": "protocol_frequency_hz"}      # a [protocol] key's store column
PROTOCOL_PARAMS = tuple(COLUMN[k] for k in NODE_KEYS)   # a node's protocol columns (with the shell's)


def bias_protocol(shell: Shell, wait_s: float, frequency_hz: float) -> Protocol:
    """A node's protocol (module docstring)."""
    h_m = shell.h0_um - 0.5 * shell.dh_um
    return Protocol(shell.h0_um, (Ramp(to_um=h_m), Hold(wait_s), Oscillate(frequency_hz)))


@dataclass(frozen=True)
class BiasNode:
    """One node: the shell (K(1 s) its moduli, h0 = h_m + Δh/2), the exponents and the protocol."""

    shell: Shell
    bulk_exponent: float
    shear_exponent: float
    protocol: Protocol

    @property
    def wait_s(self) -> float:
        hold = self.protocol.steps[1]
        assert isinstance(hold, Hold)
        return hold.duration_s

    @property
    def frequency_hz(self) -> float:
        osc = self.protocol.steps[2]
        assert isinstance(osc, Oscillate)
        return osc.frequency_hz

    def to_dict(self) -> dict[str, object]:
        """The shell's fields and the protocol point (as their store columns)."""
        return {**self.shell.to_dict(), **{COLUMN[k]: getattr(self, k) for k in NODE_KEYS}}


def _is_number(v: Any) -> bool:
    return not isinstance(v, bool) and isinstance(v, (int, float)) and math.isfinite(v)


def protocol_axes(path: Any, section: dict[str, Any]) -> dict[str, list[Any]]:
    """The `[protocol]` section's axes (`exponents` as (β_B, β_S) tuples, each β in [0, 1); T_w >= 0 s;
    f > 0 Hz), each non-empty; InputError naming what is wrong if not."""
    missing = [k for k in PROTOCOL_KEYS if k not in section]
    if missing:
        raise InputError(f"{path}: [protocol] needs {', '.join(missing)}")
    pairs = section["exponents"]
    if not isinstance(pairs, list) or not pairs or not all(
            isinstance(p, list) and len(p) == 2 and all(_is_number(b) and 0.0 <= b < 1.0 for b in p) for p in pairs):
        raise InputError(f"{path}: [protocol] exponents must be a list of pairs [beta_B, beta_S], each in [0, 1) "
                         f"(got {pairs!r})")
    axes: dict[str, list[Any]] = {"exponents": [(float(b), float(s)) for b, s in pairs]}
    for key, least, strict in (("wait_s", 0.0, False), ("frequency_hz", 0.0, True)):
        values = numbers(section[key])
        if values is None or not all(v > least if strict else v >= least for v in values):
            raise InputError(f"{path}: [protocol] {key} must be a number {'>' if strict else '>='} 0 or a "
                             f"non-empty list of them (got {section[key]!r})")
        axes[key] = values
    return axes


class BiasGrid(ShellProduct):
    """The nodes of `shells` × the product of the protocol `axes` (`protocol_axes`)."""

    noun = "node"

    def __init__(self, shells: Grid, axes: dict[str, list[Any]]):
        points = [(b, s, w, f) for (b, s), w, f in
                  itertools.product(axes["exponents"], axes["wait_s"], axes["frequency_hz"])]
        super().__init__(shells, points, PROTOCOL_PARAMS)

    def point(self, shell: Shell, values: tuple[Any, ...]) -> BiasNode:
        b, sh, w, f = values
        return BiasNode(shell, b, sh, bias_protocol(shell, w, f))
