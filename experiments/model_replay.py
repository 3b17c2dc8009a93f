"""Can plain RL's model represent walking?  The demonstrator's gait replayed through it.

Plain model-based RL only finds a gait the model predicts.  This fits the model plain RL has at
the start of iteration N + 1 (`--after N` finished iterations, then line 5: the data of lines 2
and 28-29 so far, nothing from a demonstrator), runs the design's hand-crafted demonstrator in
the simulator (demos.py, no execution noise), and replays its actions open-loop through the
model from the same starts.  Per starting point it prints the progress (m) the simulator gives
and the model predicts over the first T steps and over the whole episode.  A model that
predicts the gait's progress from RL's own data could guide a policy to it; one that predicts
much less cannot, whatever the policy optimisation does.

    python experiments/model_replay.py --design hexapod --after 0 4 --seeds 0 1 2
    python experiments/model_replay.py --design leg_none_wheel --after 0
    python experiments/model_replay.py --design hexapod --with-demos     # RL+IL's model, the clone's data in it
    python experiments/model_replay.py --design hexapod --set random_episodes=128   # 4x line 2's data
"""
from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import torch

if __package__ in (None, ""):              # run as a script: the stage files are one folder up
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import demos as demo_lib                                                                     # noqa: E402
import modular_rlil_minimal as rlil                                                          # noqa: E402
import sim2d                                                                                 # noqa: E402
from experiments.gradient_check import starting_point                                        # noqa: E402


@torch.no_grad()
def replay(model, demo: demo_lib.DemoData, horizon: int) -> dict:
    """Mean progress (m) of the demonstrations in the simulator and as the model predicts them
    from the same starts with the same actions, over `horizon` steps and over the whole episode."""
    states = torch.as_tensor(demo.states, dtype=torch.float32)                      # (E, T + 1, S)
    actions = torch.as_tensor(demo.actions, dtype=torch.float32)                    # (E, T, A)
    f, s = model.on_design(sim2d.design_graph(demo.design)), states[:, 0]
    x = [s[:, 0]]
    for t in range(actions.shape[1]):
        s = f(s, actions[:, t])
        x.append(s[:, 0])
    steps = actions.shape[1]
    true = states[:, :, 0] - states[:, :1, 0]
    return {"sim_T": float(true[:, horizon].mean()), "model_T": float((x[horizon] - x[0]).mean()),
            "sim_episode": float(true[:, steps].mean()), "model_episode": float((x[steps] - x[0]).mean())}


def with_settings(cfg: rlil.Config, settings: list[str]) -> rlil.Config:
    """cfg with FIELD=VALUE settings applied (numbers and on/off fields); a ValueError naming a
    setting that is not one."""
    kinds = {f.name: type(getattr(cfg, f.name)) for f in dataclasses.fields(cfg)}
    changes = {}
    for setting in settings:
        name, _, value = setting.partition("=")
        if kinds.get(name) not in (int, float, bool) or not value:
            raise ValueError(f"--set {setting}: expected FIELD=VALUE with a numeric or on/off Config field")
        try:
            changes[name] = (value in ("1", "on", "true")) if kinds[name] is bool else kinds[name](value)
        except ValueError:
            raise ValueError(f"--set {setting}: {name} takes a {kinds[name].__name__}") from None
    return dataclasses.replace(cfg, **changes)


def main(argv=None) -> int:
    parser = sim2d.CliParser(description=__doc__.split("\n")[0])
    parser.add_argument("--design", default="hexapod", help="a design with a demonstrator (default hexapod)")
    parser.add_argument("--after", nargs="+", type=int, default=[0], metavar="N",
                        help="plain RL's model after N finished iterations (default 0: the first fit)")
    parser.add_argument("--seeds", nargs="+", type=int, default=[0], metavar="S")
    parser.add_argument("--episodes", type=int, default=16, help="demonstrations replayed (default 16)")
    parser.add_argument("--preset", default="default", help="Algorithm 1's budget: default or tiny")
    parser.add_argument("--with-demos", action="store_true",
                        help="RL+IL's model instead, with the design's own demos: its data holds the clone's "
                             "roll-outs (--clone-data), so it has seen gait-like states")
    parser.add_argument("--set", nargs="+", default=[], metavar="FIELD=VALUE",
                        help="Config fields to change from the preset, e.g. random_episodes=128 random_action_std=0.5")
    args = parser.parse_args(argv)
    try:
        design = sim2d.parse_design(args.design)
        demo_lib.check_demonstrable(sim2d.design_graph(design))
        base = rlil.preset(args.preset)
        base = rlil.validate_config(with_settings(base, args.set))
    except ValueError as e:
        parser.error(str(e))
    if any(not 0 <= n <= 50 for n in args.after) or not 1 <= args.episodes <= 256:
        parser.error("--after takes 0 to 50 and --episodes 1 to 256")
    demo = demo_lib.collect_demos(design, args.episodes, base.episode_steps, seed=12345,   # starts of their own
                                  cfg=demo_lib.DemoConfig(execution_noise=0.0))         # actions as executed
    print(f"| seed | after iteration | T | sim, first T (m) | model, first T (m) | sim, {base.episode_steps} steps (m) "
          f"| model, {base.episode_steps} steps (m) |\n|---|---|---|---|---|---|---|")
    for seed in args.seeds:
        for after in args.after:
            cfg = dataclasses.replace(base, train=(design,), demos=(design,) if args.with_demos else (), seed=seed)
            _, model, _, _ = starting_point(cfg, after, rlil.load_demos(cfg) if args.with_demos else None)
            r = replay(model, demo, cfg.horizon)
            print(f"| {seed} | {after} | {cfg.horizon} | {r['sim_T']:.2f} | {r['model_T']:.2f} | "
                  f"{r['sim_episode']:.2f} | {r['model_episode']:.2f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
