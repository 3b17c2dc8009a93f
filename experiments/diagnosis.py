"""Why plain model-based RL does not walk the hexapod: measurements read from committed runs.

The improvement check (`--keep-better`, modular_rlil_minimal.improvement_check) keeps the previous
policy when the new one's noiseless roll-outs of line 28 return less than the kept one's.  This
reads each run's metrics.json and prints, per iteration, the new policy's return, whether it was
kept, and by how much a rejected one fell short of the kept one: a check that rejects policies by
less than the spread of one policy's return between two sets of roll-outs freezes learning on noise.

    python experiments/diagnosis.py results/hexapod_rl_15_iterations_runs/*
    python experiments/diagnosis.py results/figure3_runs/leg_none_wheel-rl-seed*
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

if __package__ in (None, ""):              # run as a script: the stage files are one folder up
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import sim2d                                                                                 # noqa: E402
from experiments.run_folders import UsageError                                               # noqa: E402


def rejections(run_dir: Path) -> list[dict]:
    """One row per iteration from 1 on: the new policy's return, whether it was kept, the kept
    policy's return it was held against (the last kept one's, or the clone's / none at iteration 1)."""
    try:
        rows = json.loads((Path(run_dir) / "metrics.json").read_text())["iterations"]
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise UsageError(f"{run_dir}: no readable metrics.json ({type(e).__name__})")
    out, kept = [], None
    for r in rows[1:]:
        if r.get("kept_new") is None or r.get("policy_return") is None:
            raise UsageError(f"{run_dir}: iteration {r.get('iteration')} has no improvement check (--keep-better off?)")
        out.append({"iteration": r["iteration"], "return": r["policy_return"], "kept": r["kept_new"],
                    "against": kept, "distance_m": r["distance_m"]})
        if r["kept_new"]:
            kept = r["policy_return"]
    return out


def summary(runs: dict[str, list[dict]]) -> str:
    """Markdown: per run, the iterations rejected, and over all runs the shortfalls of the rejected."""
    lines = ["| run | iterations | rejected | shortfall of the rejected: median, max | kept returns, first → last |",
             "|---|---|---|---|---|"]
    short = []
    for name, rows in runs.items():
        gaps = [r["against"] - r["return"] for r in rows if not r["kept"] and r["against"] is not None]
        short += gaps
        kept = [r["return"] for r in rows if r["kept"]]
        lines.append(f"| {name} | {len(rows)} | {sum(not r['kept'] for r in rows)} | "
                     + (f"{np.median(gaps):.2f}, {max(gaps):.2f}" if gaps else "-") + " | "
                     + (f"{kept[0]:.2f} → {kept[-1]:.2f}" if kept else "-") + " |")
    if short:
        lines += ["", f"{len(short)} rejected policies in all: {np.mean(np.array(short) < 0.1) * 100:.0f} % of them "
                      f"fell short of the kept policy's return by less than 0.1 (median {np.median(short):.2f})."]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = sim2d.CliParser(description=__doc__.split("\n")[0])
    parser.add_argument("runs", nargs="+", metavar="RUN_DIR", help="run folders with a metrics.json each")
    args = parser.parse_args(argv)
    try:
        runs = {Path(d).name: rejections(Path(d)) for d in args.runs}
    except UsageError as e:
        parser.error(str(e))
    for name, rows in runs.items():
        print(f"{name}: " + " ".join(f"{r['iteration']}:{r['return']:.2f}"
                                     + ("" if r["kept"] else f"(rejected < {r['against']:.2f})") for r in rows))
    print(summary(runs))
    return 0


if __name__ == "__main__":
    sys.exit(main())
