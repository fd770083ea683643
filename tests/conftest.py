"""Paths the tests share: ROOT, the project checkout (commands run there), and
BIN, the virtual environment's bin directory (`cortex`, `mpiexec`)."""

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent
