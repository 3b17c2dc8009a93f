"""Tooling beside the lesson: speed (bench.py), the physics check (check_physics.py) and the
mutation table (mutations.py).  Run each as a script: python tools/bench.py --help."""
