"""Stable-Baselines3 PPO on ModularRobot-v0, evaluated with the project's own metric.

    python interfaces/sb3_ppo.py --design leg_none_wheel --steps 1000000 --seed 0 \\
        --eval-every 50000 --out runs/sb3_ppo-leg_none_wheel-seed0.csv

Trains PPO("MlpPolicy") with SB3's defaults, as a new user runs it, on one robot of the design
(interfaces/gymnasium_env.py: training's observation, reward, flip and 100-step episodes), and
at step 0, every --eval-every steps and at the end measures Sec. IV's metric the way
modular_rlil_minimal.evaluate_policy does: sim2d.simulate from the same 8 perturbed starts
(seed eval_seed, so the same starts as Algorithm 1's and ppo_minimal's runs of that --seed),
200 control steps, the policy's deterministic (mean) action.  Each evaluation is printed and,
with --out, appended to that CSV (steps, seconds, distance_m) as soon as it is measured; an
existing file is never overwritten.  steps: the environment steps the evaluated policy was
trained on; seconds: training's wall-clock seconds so far, evaluations excluded.  PPO updates
its policy after every 2048 steps, so an evaluation falls on the first update at or past each
multiple of --eval-every, and training runs on to the next multiple of 2048 at or past --steps.
"""
from __future__ import annotations

import csv
import sys
import time
from pathlib import Path

if __package__ in (None, ""):              # run as a script: the stage files are one folder up
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import gymnasium                                                                  # noqa: E402
import torch                                                                      # noqa: E402
from stable_baselines3 import PPO                                                 # noqa: E402
from stable_baselines3.common.callbacks import BaseCallback                       # noqa: E402
from stable_baselines3.common.logger import Logger                                # noqa: E402

import modular_rlil_minimal as rlil                                               # noqa: E402
import sim2d                                                                      # noqa: E402
from interfaces.gymnasium_env import ID, flat_observation                         # noqa: E402

COLUMNS = ("steps", "seconds", "distance_m")
MAX_SEED = 2 ** 32 - 1                     # SB3 seeds numpy's global generator, which takes 32 bits


def sb3_actor(model, graph: sim2d.DesignGraph):
    """The SB3 policy as a simulator controller act(obs, state, t) -> (n, A): its deterministic action."""
    def act(obs, state, t):
        return model.predict(flat_observation(obs, graph), deterministic=True)[0]
    return act


def evaluate(model, design: str, seed: int) -> sim2d.Episodes:
    """Sec. IV's metric as modular_rlil_minimal.evaluate_policy measures it for a run of `seed`:
    eval_episodes (8) starts of eval_seed, eval_steps (200) control steps."""
    cfg = rlil.Config(seed=seed)
    return sim2d.simulate(design, sb3_actor(model, sim2d.design_graph(design)), n=cfg.eval_episodes,
                          steps=cfg.eval_steps, seed=rlil.eval_seed(cfg))


class _Checkpoints(BaseCallback):
    """Calls record(steps) at the first policy update at or past each multiple of `every` steps.

    The policy changes only in PPO's update, after each rollout of n_steps (2048 by default), so it is
    evaluated where the next rollout starts: a check inside a rollout would measure the policy
    of the last update under a later step count."""

    def __init__(self, every: int, record):
        super().__init__()
        self.every, self.record, self.next = every, record, every

    def _on_rollout_start(self) -> None:
        if self.num_timesteps >= self.next:
            self.record(self.num_timesteps)
            self.next = (self.num_timesteps // self.every + 1) * self.every

    def _on_step(self) -> bool:
        return True


def train(design: str, steps: int, seed: int = 0, eval_every: int | None = None, out=None, log=print,
          **ppo_kwargs):
    """PPO("MlpPolicy", ModularRobot-v0 of `design`, seed=seed) for `steps` environment steps, evaluated
    at 0, after the first update past each multiple of `eval_every` steps (None: none) and at the end.

    Returns (the SB3 model, the rows {steps, seconds, distance_m}); with `out`, each row is also
    appended to that new CSV as it is measured (an existing file raises FileExistsError).
    ppo_kwargs go to PPO (none: SB3's defaults).
    """
    graph = sim2d.design_graph(design)
    model = PPO("MlpPolicy", gymnasium.make(ID, design=graph.code), seed=seed, **ppo_kwargs)
    model.set_logger(Logger(folder=None, output_formats=[]))   # SB3's own would leave an empty /tmp/SB3-<date>
    rows, spent = [], {"eval": 0.0}
    f = open(out, "x", newline="") if out is not None else None       # "x": never over an existing file
    try:
        writer = csv.writer(f) if f else None
        if writer:
            writer.writerow(COLUMNS)
            f.flush()
        t0 = time.perf_counter()

        def record(at: int):
            t = time.perf_counter()
            row = {"steps": at, "seconds": t - t0 - spent["eval"]}
            d = evaluate(model, graph.code, seed).distance_m
            spent["eval"] += time.perf_counter() - t
            row["distance_m"] = float(d.mean())
            rows.append(row)
            if writer:
                writer.writerow([row[c] for c in COLUMNS])
                f.flush()
            log(f"{at} steps, {row['seconds']:.1f} s: {row['distance_m']:.2f} m (min {d.min():.2f}, "
                f"max {d.max():.2f}) in {rlil.Config.eval_steps} steps")

        record(0)
        model.learn(total_timesteps=steps, callback=_Checkpoints(eval_every, record) if eval_every else None)
        if rows[-1]["steps"] != model.num_timesteps:
            record(model.num_timesteps)
    finally:
        if f:
            f.close()
    return model, rows


def check_out(path: str) -> None:
    """Before any work: --out must name a new .csv file in an existing folder (a one-line ValueError)."""
    p = Path(path)
    if p.suffix.lower() != ".csv":
        raise ValueError(f"--out {path}: name a .csv file")
    if p.is_dir():
        raise ValueError(f"--out {path} is a folder: name a .csv file in it")
    if not p.parent.resolve().is_dir():
        raise ValueError(f"--out {path}: no folder {p.parent}")
    if p.exists():
        raise ValueError(f"{path} already exists: name another file (it is never overwritten)")


def main(argv=None) -> int:
    parser = sim2d.CliParser(description="Stable-Baselines3 PPO (MlpPolicy, SB3's defaults) on one design, "
                             "evaluated as the project evaluates: distance in 200 control steps from 8 starts.")
    parser.add_argument("--design", default="leg_none_wheel",
                        help="a name (%s) or a 6-letter code of l/w/n" % ", ".join(sim2d.NAMED_DESIGNS))
    parser.add_argument("--steps", type=int, default=1_000_000, help="environment (control) steps of training")
    parser.add_argument("--seed", type=int, default=0, help="PPO's seed and the evaluation's starts (eval_seed)")
    parser.add_argument("--eval-every", type=int, default=50_000, help="environment steps between evaluations")
    parser.add_argument("--threads", type=int, default=1, help="torch CPU threads (the project's default: 1)")
    parser.add_argument("--out", help="a new CSV: one row (steps, seconds, distance_m) per evaluation")
    args = parser.parse_args(argv)
    try:
        design = sim2d.design_graph(args.design).code
        for flag, value in (("--steps", args.steps), ("--eval-every", args.eval_every), ("--threads", args.threads)):
            if value < 1:
                raise ValueError(f"{flag} must be a positive whole number, got {value}")
        if not 0 <= args.seed <= MAX_SEED:
            raise ValueError(f"--seed must be from 0 to {MAX_SEED} (2^32 - 1), got {args.seed}")
        if args.out is not None:
            check_out(args.out)
    except ValueError as e:
        parser.error(str(e))
    torch.set_num_threads(args.threads)
    try:
        _, rows = train(design, args.steps, args.seed, args.eval_every, args.out)
    except FileExistsError:
        parser.error(f"{args.out} already exists: name another file (it is never overwritten)")
    print(f"design={sim2d.design_name(design)} steps={rows[-1]['steps']} seed={args.seed} "
          f"distance_m={rows[-1]['distance_m']:.4f}" + (f" out={args.out}" if args.out else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
