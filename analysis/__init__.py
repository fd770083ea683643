"""Analysis of campaign stores: calibration laws (SPEC 4), the per-cell
inversion (SPEC 6) shared with the measured cells, the reconstruction check,
the Monte-Carlo error study (SPEC 5), figures and reports.

Modules: `laws` (the law and its fits), `calibration` (steps 1-4, the
`Calibration` file), `inversion` (one cell, or many at once), `reconstruction`,
`montecarlo`, `figures`, `report` (the whole run), `cli`, `synthetic` (store
tables generated from the laws, for tests and benchmarks)."""
