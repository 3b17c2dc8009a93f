"""Lets tests import the top-level stage files (sim2d.py, gnn.py, ...) from any directory."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
