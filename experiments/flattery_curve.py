"""When does the model start to flatter the policy?  Flattery along one policy phase of plain RL.

The model flatters a policy when its T-step roll-out predicts more progress than the simulator
gives (`modular_rlil_minimal.model_bias`; issue #34 bounds it at 0.3 m).  Plain RL's first
policy at the walking budget is flattered by over 1 m.  Two readings lead to different fixes:
* the model is wrong from the start (already at the phase's first step, before the policy has
  moved), so better data is the answer;
* the policy walks into the model's errors as it climbs L_RL (flattery grows with the step k),
  so the fix is in the policy phase: fewer steps, or a check that sees the simulator.
This runs Algorithm 1 for `--after` iterations, fits line 5's model, then runs the policy phase
(lines 7-26) unchanged, and at each of its validation checks (step 0 and every `validate_every`
steps) measures, from the evaluation starts: the model's and the simulator's progress over the
first T steps of the noiseless policy.  The measurement draws no random numbers the phase uses,
so the phase takes the same steps as in a run.

    python experiments/flattery_curve.py --preset walk --design hexapod --seeds 0 1 2
    python experiments/flattery_curve.py --preset walk --design hexapod --set policy_steps=480
    python experiments/flattery_curve.py --design leg_leg_wheel --after 0 2 --out results/x.csv
"""
from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np
import torch

if __package__ in (None, ""):              # run as a script: the stage files are one folder up
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import modular_rlil_minimal as rlil                                                          # noqa: E402
import sim2d                                                                                 # noqa: E402
from experiments.gradient_check import starting_point                                        # noqa: E402
from experiments.model_replay import with_settings                                           # noqa: E402
from experiments.run_folders import UsageError, claim_output_file                            # noqa: E402
from experiments.sweeps import write_rows_csv                                                # noqa: E402

COLUMNS = ["design", "seed", "after", "step", "model_progress_m", "sim_progress_m", "flattery_m",
           "validation_reward", "lr"]


@torch.no_grad()
def flattery(policy, model, design: str, cfg: rlil.Config) -> dict:
    """`model_bias`'s two progress figures over the first T steps from the evaluation starts."""
    graph = sim2d.design_graph(design)
    run = sim2d.simulate(graph, rlil.PolicyActor(policy, design, cfg.eval_episodes), cfg.eval_episodes,
                         cfg.horizon, seed=rlil.eval_seed(cfg))
    bias = rlil.model_bias(policy, model, design, run, cfg)
    return {"model_progress_m": bias["model_progress_m"], "sim_progress_m": bias["sim_progress_m"],
            "flattery_m": bias["model_progress_m"] - bias["sim_progress_m"]}


def phase_rows(cfg: rlil.Config, after: int) -> list[dict]:
    """One row per validation check of iteration after + 1's policy phase (plain RL)."""
    policy, model, traj, rng = starting_point(cfg, after)
    design, rows = traj.design, []
    original = rlil.validation_reward

    def watched(policy_, model_, val_states, cfg_):
        value = original(policy_, model_, val_states, cfg_)
        with torch.random.fork_rng():                   # touches no generator the phase draws from
            row = flattery(policy_, model_, design, cfg_)
        rows.append({"design": sim2d.design_name(design), "seed": cfg.seed, "after": after,
                     "step": len(rows) * cfg.validate_every, **row, "validation_reward": value, "lr": None})
        return value

    rlil.validation_reward = watched
    try:
        phase = rlil.optimize_policy(policy, model, {design: traj}, {}, 0.0, cfg, rng)
    finally:
        rlil.validation_reward = original
    rows[-1]["lr"] = phase["lr"]
    return rows


def summary(rows: list[dict]) -> str:
    """Markdown: per design, starting point and step, the mean over seeds of each figure."""
    groups = {}
    for r in rows:
        groups.setdefault((r["design"], int(r["after"]), int(r["step"])), []).append(r)
    lines = ["| design | after iteration | policy step | seeds | model progress (m) | simulator progress (m) "
             "| flattery (m): mean, min - max |", "|---|---|---|---|---|---|---|"]
    for (design, after, step), g in groups.items():
        col = {k: np.array([float(r[k]) for r in g]) for k in ("model_progress_m", "sim_progress_m", "flattery_m")}
        lines.append(f"| {design} | {after} | {step} | {len(g)} | {col['model_progress_m'].mean():+.2f} | "
                     f"{col['sim_progress_m'].mean():+.2f} | {col['flattery_m'].mean():+.2f}, "
                     f"{col['flattery_m'].min():+.2f} - {col['flattery_m'].max():+.2f} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = sim2d.CliParser(description=__doc__.split("\n")[0])
    parser.add_argument("--preset", default="default", help="Algorithm 1's budget: default, walk or tiny")
    parser.add_argument("--design", default="hexapod")
    parser.add_argument("--after", nargs="+", type=int, default=[0], metavar="N",
                        help="starting points: after N finished iterations of plain RL (default 0: the first phase)")
    parser.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2], metavar="S")
    parser.add_argument("--set", nargs="+", default=[], metavar="FIELD=VALUE",
                        help="Config fields to change, e.g. policy_steps=480 horizon=10")
    parser.add_argument("--out", type=Path, help="also write every check's row to this CSV")
    parser.add_argument("--force", action="store_true", help="replace an existing --out file")
    args = parser.parse_args(argv)
    try:
        design = sim2d.parse_design(args.design)
        base = with_settings(dataclasses.replace(rlil.preset(args.preset), train=(design,), demos=()), args.set)
        rlil.validate_config(base)
        claim_output_file(args.out, ".csv", "--out", args.force)
    except (ValueError, UsageError) as e:
        parser.error(str(e))
    for name, values, lo, hi in (("--after", args.after, 0, 50), ("--seeds", args.seeds, 0, rlil.MAX_SEED)):
        if any(not lo <= v <= hi for v in values):
            parser.error(f"{name} takes {lo} to {hi}")
    rows = []
    for seed in args.seeds:
        for after in args.after:
            phase = phase_rows(dataclasses.replace(base, seed=seed), after)
            rows += phase
            print(f"{sim2d.design_name(design)} seed {seed} after {after}: flattery {phase[0]['flattery_m']:+.2f} m "
                  f"at step 0, {phase[-1]['flattery_m']:+.2f} m at step {phase[-1]['step']}", flush=True)
    print(summary(rows))
    if args.out:
        write_rows_csv(args.out, COLUMNS, rows)
        print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
