"""The names a user may choose from, in one home each, without numpy: the
command line offers them as argparse choices, and the modules that act on
them (`solver.model`, `solver.compression`, `solver.protocol`, `solver.protocol_simulation`,
`analysis.invert.table`, `analysis.afm.tension.ramp`) build their tables over them."""

BENDINGS = ("standard", "double", "none")             # bending variants of the shell (SPEC 2)
SOLVERS = ("fast", "explicit")                       # shell solvers (`--solver`, `[solver] method`)
INVERSION_METHODS = ("emulator", "law")              # forward models of the per-cell inversion
TENSION_ONLY_RAMP_MODELS = ("droplet", "small-deformation")       # ramp models of a tension-only cell
RAMP_MODELS = ("shell",) + TENSION_ONLY_RAMP_MODELS     # force-ramp models of the tension fit (shell: SPEC 2)
HOLD_KINDS = ("height", "force")                    # a protocol's hold: constant height or constant force
CORTEX_HISTORIES = ("carried", "relaxed")           # a time-domain cell's heights: one history, or each relaxed
