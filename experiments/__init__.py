"""The experiments built on the stage files: sweeps over seeds (sweeps.py), transfer to other designs
(transfer.py), the statistics (stats.py), the committed results tables (tables.py), and the run
folders train.py writes (run_folders.py)."""
