"""Does line 1's clone flip?  Behavioural cloning, then Sec. IV's evaluation, per seed.

A run's iteration 0 is the clone of Algorithm 1's line 1, evaluated from Sec. IV's starts.  Its
distance counts a robot that flips (|pitch| > sim2d.FLIP_PITCH) and drives on its back, which the
reward penalises, so the first RL policy may turn it upright and slower: a "fall" of the metric
(docs/history/2026-12-plain-rl-diagnosis.md, part 16).  This runs line 1 exactly as a run does (the
same seeding, so the distance is the run's iteration-0 distance) and writes, per seed, the
distance and how many of the starts flipped; no RL, so about 40 s a seed.

    python experiments/clone_flips.py --train leg_none_wheel --demos hexapod car --seeds 0 1 2 \\
        --out results/clone_flips/leg_none_wheel-seeds0-2.csv
"""
from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np
import torch

if __package__ in (None, ""):              # run as a script: the stage files are one folder up
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import demos as demo_lib                                                                      # noqa: E402
import modular_rlil_minimal as rlil                                                          # noqa: E402
import sim2d                                                                                 # noqa: E402
from experiments.run_folders import UsageError, claim_output_file                            # noqa: E402
from experiments.sweeps import write_rows_csv                                                # noqa: E402

COLUMNS = ["train", "demos", "seed", "distance_m", "flipped", "starts"]


def clone_row(cfg: rlil.Config, cache_dir=demo_lib.DEFAULT_CACHE_DIR) -> dict:
    """Line 1 as `algorithm1` runs it for cfg's seed (its demos, seeding and cloning), then
    `evaluate_iteration`'s figures at iteration 0."""
    demo_data = rlil.load_demos(cfg, cache_dir)
    torch.set_num_threads(cfg.threads)
    rng = rlil.seed_everything(cfg.seed)
    policy = rlil.ModularPolicy(cfg.gnn)
    rlil.pretrain_bc(policy, demo_data, cfg, rng)                                            # line 1
    row = rlil.evaluate_iteration(policy, None, list(cfg.train), cfg, 0)
    return {"train": " ".join(cfg.train), "demos": " ".join(cfg.demos), "seed": cfg.seed,
            "distance_m": row["distance_m"], "flipped": row["flipped"],
            "starts": cfg.eval_episodes * len(cfg.train)}


def main(argv=None) -> int:
    parser = sim2d.CliParser(description=__doc__.split("\n")[0])
    parser.add_argument("--train", nargs="+", default=["leg_none_wheel"], metavar="DESIGN")
    parser.add_argument("--demos", nargs="+", default=["hexapod", "car"], metavar="DESIGN")
    parser.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2], metavar="S")
    parser.add_argument("--out", type=Path, help="also write one row per seed to this CSV")
    parser.add_argument("--force", action="store_true", help="replace an existing --out file")
    args = parser.parse_args(argv)
    try:
        cfg = dataclasses.replace(rlil.Config(), train=tuple(map(sim2d.parse_design, args.train)),
                                  demos=tuple(map(sim2d.parse_design, args.demos)))
        rlil.validate_config(cfg)
        claim_output_file(args.out, ".csv", "--out", args.force)
    except (ValueError, UsageError) as e:
        parser.error(str(e))
    if any(not 0 <= s <= rlil.MAX_SEED for s in args.seeds):
        parser.error(f"--seeds takes 0 to {rlil.MAX_SEED}")
    rows = []
    for seed in args.seeds:
        r = clone_row(dataclasses.replace(cfg, seed=seed))
        rows.append(r)
        print(f"seed {seed}: the clone covers {r['distance_m']:.2f} m, {r['flipped']} of {r['starts']} starts flipped",
              flush=True)
    print(f"{sum(r['flipped'] > 0 for r in rows)} of {len(rows)} clones flip from some start; "
          f"mean distance {np.mean([r['distance_m'] for r in rows]):.2f} m")
    if args.out:
        write_rows_csv(args.out, COLUMNS, rows)
        print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
