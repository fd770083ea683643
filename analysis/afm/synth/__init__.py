"""Synthetic experiments with known truth: elastic cells (`cells.py`) and
viscoelastic cells (`rheology.py`)."""
