"""Does the model's gradient point uphill in the real world?  A probe of plain model-based RL.

Algorithm 1 improves the policy by descending L_RL, the negative T-step return through the
learned model (lines 9-21).  That only helps if a step that raises the model's return also raises
the simulator's.  This takes a fixed policy and model, the ones plain RL has at the start of a
policy phase (`--after` finished iterations of Algorithm 1, then line 5's model fit), takes one
policy step along the gradient of L_RL at horizon T (Adam at policy_lr from a fresh state: the
phase's first step, line 21), and measures the change of the real return in the simulator, from
the same starts with the same sensor noise as before the step (paired, so an unchanged policy
changes by exactly 0).  Each probe draws a new batch of initial states and action noise.

Per probe it records the change of
  real_T        the simulator's return over the first T steps (what L_RL optimises),
  real_episode  the simulator's return over the whole episode (what line 28's data and the
                improvement check see),
  model_T       the model's deterministic T-step return from the same starts (what the model says).

    python experiments/gradient_check.py                                  # hexapod and leg_none_wheel, T = 10, 20, 40
    python experiments/gradient_check.py --designs hexapod --horizons 20 --probes 8 --seeds 0 --after 0 2
    python experiments/gradient_check.py --out results/gradient_check.csv     # also write every probe's row

The summary gives, per design, --after and T, the share of probes that raise each return, and the
median change.  A gradient that points uphill in the model but not in the simulator (model_T
above 0, real_T at or below 0) is the model's error steering the policy.
"""
from __future__ import annotations

import copy
import dataclasses
import sys
from pathlib import Path

import numpy as np
import torch

if __package__ in (None, ""):              # run as a script: the stage files are one folder up
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import modular_rlil_minimal as rlil                                                          # noqa: E402
import sim2d                                                                                 # noqa: E402
from experiments.run_folders import UsageError, claim_output_file                            # noqa: E402
from experiments.sweeps import write_rows_csv                                                # noqa: E402

COLUMNS = ["design", "seed", "after", "horizon", "probe", "real_T", "real_episode", "model_T"]


def starting_point(cfg: rlil.Config, after: int, demo_data: dict | None = None):
    """Plain RL's policy, model and T_train at the start of iteration after + 1's policy phase:
    Algorithm 1 run for `after` iterations (0: line 2 only), then line 5 on all the data so far
    (with `demo_data`, RL+IL's: line 1 first, and the clone's roll-outs in T_train)."""
    run = rlil.algorithm1(dataclasses.replace(cfg, iters=after), demo_data or {}, log=lambda m: None)
    rlil.train_model(run.model, run.data, cfg, run.rng, first=(after == 0))
    return run.policy, run.model, run.data[sim2d.parse_design(cfg.train[0])], run.rng


def real_returns(policy, design: str, n: int, steps: int, seed: int, horizon: int):
    """The simulator's returns of the noiseless policy from n starts (seeded): over the first
    `horizon` steps and over `steps` steps, (n,) each, and the starts (n, S) as a tensor."""
    run = sim2d.simulate(design, rlil.PolicyActor(policy, design, n), n, steps, seed=seed)
    r = sim2d.reward(run.states[:, :-1], run.actions, run.states[:, 1:], sim2d.design_graph(design))   # (n, steps)
    return r[:, :horizon].sum(1), r.sum(1), torch.as_tensor(run.states[:, 0], dtype=torch.float32)


@torch.no_grad()
def model_return(policy, model, s0, design: str, horizon: int) -> np.ndarray:
    """The model's deterministic `horizon`-step return of the policy from states s0: (n,)."""
    graph = sim2d.design_graph(design)
    R, _, _ = rlil.rollout(policy, model, s0, policy.initial_hidden(len(s0), graph), graph, horizon,
                           deterministic=True)
    return R.numpy()


def policy_step(policy, model, traj, cfg: rlil.Config, rng: np.random.Generator):
    """A copy of the policy after one step of line 21 on L_RL alone (a fresh batch of line 9)."""
    new = copy.deepcopy(policy)
    opt = torch.optim.Adam(new.parameters(), lr=cfg.policy_lr, foreach=True)
    model.requires_grad_(False)
    buffers = {traj.design: rlil.init_buffer(new, traj, cfg, rng)}
    rlil.gradient_step(opt, rlil.rl_loss(new, model, buffers, cfg, rng), new, cfg.grad_clip)
    model.requires_grad_(True)
    return new


def probe_rows(design: str, seed: int, after: int, horizons, probes: int, starts: int,
               base: rlil.Config | None = None) -> list[dict]:
    """Every probe's row (COLUMNS) for one design, seed and starting point."""
    cfg = dataclasses.replace(base or rlil.Config(), train=(sim2d.parse_design(design),), demos=(), seed=seed)
    policy, model, traj, rng = starting_point(cfg, after)
    eval_seed = rlil.eval_seed(cfg) + 7                      # starts of their own, the same before and after
    rows = []
    for T in horizons:
        cfg_T = dataclasses.replace(cfg, horizon=T)
        before_T, before_ep, s0 = real_returns(policy, design, starts, cfg.episode_steps, eval_seed, T)
        model_before = model_return(policy, model, s0, design, T)
        for p in range(probes):
            new = policy_step(policy, model, traj, cfg_T, rng)
            after_T, after_ep, _ = real_returns(new, design, starts, cfg.episode_steps, eval_seed, T)
            rows.append({"design": design, "seed": seed, "after": after, "horizon": T, "probe": p,
                         "real_T": float(np.mean(after_T - before_T)),
                         "real_episode": float(np.mean(after_ep - before_ep)),
                         "model_T": float(np.mean(model_return(new, model, s0, design, T) - model_before))})
    return rows


def summary(rows: list[dict]) -> str:
    """Markdown: per design, starting point and T, the share of probes raising each return."""
    groups = {}
    for r in rows:
        name = sim2d.design_name(sim2d.parse_design(r["design"]))
        groups.setdefault((name, int(r["after"]), int(r["horizon"])), []).append(r)
    lines = ["| design | after iteration | T | probes | real_T up | real_episode up | model_T up "
             "| model up, real_T not | median change: real_T, real_episode, model_T |",
             "|---|---|---|---|---|---|---|---|---|"]
    for (design, after, T), g in groups.items():
        col = {k: np.array([float(r[k]) for r in g]) for k in ("real_T", "real_episode", "model_T")}
        share = {k: f"{np.mean(v > 0) * 100:.0f} %" for k, v in col.items()}
        fooled = np.mean((col["model_T"] > 0) & (col["real_T"] <= 0)) * 100
        lines.append(f"| {design} | {after} | {T} | {len(g)} | {share['real_T']} | {share['real_episode']} | "
                     f"{share['model_T']} | {fooled:.0f} % | " + ", ".join(f"{np.median(v):+.4f}" for v in col.values())
                     + " |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = sim2d.CliParser(description=__doc__.split("\n")[0])
    parser.add_argument("--preset", default="default", help="Algorithm 1's budget: default or tiny (a quick look)")
    parser.add_argument("--designs", nargs="+", default=["hexapod", "leg_none_wheel"], metavar="DESIGN")
    parser.add_argument("--horizons", nargs="+", type=int, default=[10, 20, 40], metavar="T",
                        help="model roll-out lengths of L_RL, 1 to 100 (default 10 20 40)")
    parser.add_argument("--after", nargs="+", type=int, default=[0], metavar="N",
                        help="starting points: after N finished iterations of plain RL (default 0: the "
                             "first policy phase)")
    parser.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2], metavar="S")
    parser.add_argument("--probes", type=int, default=16, help="policy steps per starting point and T (default 16)")
    parser.add_argument("--starts", type=int, default=32, help="simulator starts per evaluation (default 32)")
    parser.add_argument("--out", type=Path, help="also write every probe's row to this CSV")
    parser.add_argument("--force", action="store_true", help="replace an existing --out file")
    args = parser.parse_args(argv)
    try:
        designs = [sim2d.design_name(sim2d.parse_design(d)) for d in args.designs]
    except ValueError as e:
        parser.error(str(e))
    for name, values, lo, hi in (("--horizons", args.horizons, 1, 100), ("--after", args.after, 0, 50),
                                 ("--seeds", args.seeds, 0, rlil.MAX_SEED), ("--probes", [args.probes], 1, 1000),
                                 ("--starts", [args.starts], 1, 1024)):
        if any(not lo <= v <= hi for v in values):
            parser.error(f"{name} takes {lo} to {hi}")
    try:
        claim_output_file(args.out, ".csv", "--out", args.force)
    except UsageError as e:
        parser.error(str(e))
    try:
        base = rlil.preset(args.preset)
    except ValueError as e:
        parser.error(str(e))
    rows = []
    for design in designs:
        for seed in args.seeds:
            for after in args.after:
                rows += probe_rows(design, seed, after, args.horizons, args.probes, args.starts, base)
                print(f"{design} seed {seed} after {after}: done", flush=True)
    print(summary(rows))
    if args.out:
        write_rows_csv(args.out, COLUMNS, rows)
        print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
