"""Bruker NanoScope force curves: the header (`header.py`), the binary curve
(`nanoscope.py`) and NanoScope Analysis text exports (`text.py`)."""
