"""Cortical tension and pressure without oscillation (`cortex afm tension`, SPEC 11):
approach ramps (`ramp.py`), pauses (`pause.py`), the command's read -> analyse
(`pipeline.py`) and what it writes (`report.py`); synthetic curves of known truth are a
study (`studies/tension_synth.py`)."""
