"""A task kind that lives outside the product (`campaign.kinds`): what a user's own kind looks like.

`made_up_kinds:squares` computes at once, per grid point (a `solver.model.Shell`), numbers that
are easy to check: the square of its height and its K_S/K_B. Its version is 1, or what the
environment variable MADE_UP_KIND_VERSION says (how a test plays "the kind's code changed").
`made_up_kinds:shifted` has parameters of its own, given by a campaign's `[params]` section
(`campaign.params_grid`): (h0 + offset_um) · scale.
"""

import os

from campaign.kinds import Kind, register


def squares(shell):
    """The kind's compute function: {column: value} of one grid point."""
    return {"h0_squared_um2": shell.h0_um ** 2, "shear_over_bulk": shell.shear_mN_per_m / shell.bulk_mN_per_m}


KIND = register(Kind("squares", int(os.environ.get("MADE_UP_KIND_VERSION", "1")),
                     {"h0_squared_um2": "µm²", "shear_over_bulk": "1"}, squares,
                     doc="h0² and K_S/K_B of a shell (a test's kind)"))


def shifted(point):
    """A kind with parameters of its own (`[params]`): h0 plus `offset_um`, times `scale`."""
    return {"shifted_um": (point.shell.h0_um + point.values["offset_um"]) * point.values["scale"]}


SHIFTED = register(Kind("shifted", 1, {"shifted_um": "µm"}, shifted, params={"offset_um": "µm", "scale": "1"},
                        doc="(h0 + offset) scale of a shell (a test's kind with parameters of its own)"))
