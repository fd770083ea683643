"""Studies: code that benches and tests use and the `cortex` command does not.

Beside `bench/`, not installed with the product (pyproject.toml's packages), type-checked with
it (mypy). It imports the product; nothing in the product imports it (tests/test_architecture_map.py).
Each study's record is a page of docs/studies/.

Modules: `synthetic` (store tables generated from the calibration laws, for tests and
benchmarks of the analysis), `tension_synth` (force curves of known truth for `cortex afm
tension`), `viscous_time` (the viscous cell's linear response in time: the check of K*(ω)),
`prestressed_response` (complex moduli of a prestressed shell on the material stiffness only),
`waited_state` (the frequency-domain reading about the state after the wait) and
`shell_reading_bias` (power-law ramps read by `afm tension`'s shell: a campaign task kind).
"""
