"""Lets tests import the top-level stage files (sim2d.py, gnn.py, ...) from any directory.

Tests run torch on one thread: their tensors are tiny, and two threads on a
busy 2-core machine made a small GRU step 1000x slower (35 ms instead of 26 us).
"""
import sys
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).parent))
torch.set_num_threads(1)
