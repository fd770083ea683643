"""Measured cells (SPEC 6): AFM recording formats, synthetic recordings,
per-cell inversion and population statistics."""
