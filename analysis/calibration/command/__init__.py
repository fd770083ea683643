"""`cortex analysis calibrate`'s work beyond the law itself (`analysis.calibration.law`):
the pipeline (`pipeline`: read -> fit -> write), the reconstruction check
(`reconstruction`), the Monte-Carlo error study (`montecarlo`, SPEC 5), the
figures (`figures`) and report.md (`report`).

Public API (imported on first use): `run(store, out)` (the whole command), `reconstruct`.
"""

from common.lazy_exports import lazy_exports

__all__, __getattr__, __dir__ = lazy_exports(__name__, {
    "run": "analysis.calibration.command.pipeline", "reconstruct": "analysis.calibration.command.reconstruction",
})
