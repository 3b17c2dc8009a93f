"""Speed of the world, of the networks' training steps and of one PPO iteration, on this CPU.

Three groups of measurements (none of them is ever asserted by a test):

  world     robot control steps per second: sim2d.World.step against bare pymunk
            driving the same robots (16 robots per named design, 100 steps, best of 5)
  networks  a hexapod policy update through model roll-outs (Algorithm 1 lines 10-15,
            T = 20, 256 robots) and a model update (512 transitions), best of 5; then
            the default run's policy, BC and model steps (train.py's defaults), best of 3
  ppo       one PPO iteration's collection and update at the default config, and one
            minibatch step with the policy's memory and without (ppo_minimal.py)

CPU commands (one torch thread unless --threads):

    python tools/bench.py                      # all three groups, ~1 min
    python tools/bench.py --world              # the world only, ~10 s
    python tools/bench.py --networks           # the networks only, ~30 s
    python tools/bench.py --ppo --design car   # one PPO iteration on the car (default hexapod)
    python tools/bench.py --profile policy     # torch.profiler: operators of 3 default policy steps, by self CPU time
    python tools/bench.py --profile bc         # ... of behavioural-cloning steps (also: model)
    python tools/bench.py --networks --threads 2

The first line printed says what ran the numbers: torch's version, its CPU
capability (the vector instructions its kernels use) and the thread count.
Each group ends with one line of key=value figures, for scripts.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
import torch

if __package__ in (None, ""):              # run as a script: the stage files are one folder up
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import demos as demo_lib                                                                    # noqa: E402
import modular_rlil_minimal as rlil                                                          # noqa: E402
import sim2d                                                                                 # noqa: E402
from gnn import GNNConfig, ModularModel, ModularPolicy                                       # noqa: E402
from ppo_minimal import (Memoryless, PPOConfig, collect_episodes, gae, new_run, ppo_update,  # noqa: E402
                         validate_config)
from experiments import run_folders                                                          # noqa: E402
from sim2d import (NAMED_DESIGNS, PHYSICS_SUBSTEPS, STEPS_PER_ACTION, SUBSTEP_DT, World,     # noqa: E402
                   atomic_write, design_graph, joint_speed_scale, random_spline_actions)

PROFILE_STEPS = ("policy", "bc", "model")


def provenance(threads: int) -> str:
    """One line: torch's version, its CPU capability and the number of torch threads."""
    return (f"torch {torch.__version__}, CPU capability {torch.backends.cpu.get_cpu_capability()}, "
            f"{threads} thread(s)")


# ----------------------------------------------------------------------------
# World: the world's overhead over bare pymunk stepping of the same robots
# ----------------------------------------------------------------------------
def bench_world(designs=tuple(NAMED_DESIGNS), n: int = 16, steps: int = 100, repeats: int = 5) -> dict:
    """Robot control steps per second: World.step vs bare pymunk driving the same robots.

    Bare pymunk = what a user of pymunk alone must do for the same motion: set
    every motor's rate (`motor.rate = r`) and call `space.step(SUBSTEP_DT)` 5 x
    PHYSICS_SUBSTEPS times, with the same Spaces (same solver settings) and no
    state read, observation or reward.  Both replay the same actions from the
    same start, alternating, in one process; best of `repeats` each.
    """
    results = {}
    for design in designs:
        world = World(design, n=n)
        actions = random_spline_actions(np.random.default_rng(0), n, design_graph(design).action_dim, steps)
        rates = np.clip(actions, -1, 1) * joint_speed_scale(world.graph)
        best_world = best_bare = float("inf")
        for _ in range(repeats):
            world.reset(seed=0)
            t0 = time.perf_counter()
            for t in range(steps):
                world.step(actions[:, t])
            best_world = min(best_world, time.perf_counter() - t0)
            world.reset(seed=0)
            t0 = time.perf_counter()
            for t in range(steps):
                for space, motors, rate in zip(world.spaces, world.motors, rates[:, t].tolist()):
                    for motor, r in zip(motors, rate):
                        motor.rate = r
                    for _ in range(STEPS_PER_ACTION * PHYSICS_SUBSTEPS):
                        space.step(SUBSTEP_DT)
            best_bare = min(best_bare, time.perf_counter() - t0)
        results[design] = {"world": n * steps / best_world, "bare": n * steps / best_bare}
    return results


def print_world() -> None:
    results = bench_world()
    for design, r in results.items():
        print(f"{design:15s} world {r['world']:8.0f} steps/s   bare pymunk {r['bare']:8.0f} steps/s"
              f"   ratio {r['world'] / r['bare']:.2f}")
    hexa = results["hexapod"]
    print(f"hexapod_steps_per_s={hexa['world']:.1f} hexapod_ratio={hexa['world'] / hexa['bare']:.3f}")


# ----------------------------------------------------------------------------
# Networks: policy updates through model roll-outs, model fitting, and the
# default run's three kinds of step
# ----------------------------------------------------------------------------
def random_transitions(design: str, n_robots: int, steps: int, seed: int, episodes: bool = False):
    """Sim transitions (s, a, s_next), (n_robots * steps, .) float32, random spline actions (Sec. III-B);
    with `episodes`, the episodes instead: states (n_robots, steps + 1, S), actions (n_robots, steps, A).
    (tests/test_gnn.py fits its models on these too.)"""
    graph = sim2d.design_graph(design)
    actions = sim2d.random_spline_actions(np.random.default_rng(seed), n_robots, graph.action_dim, steps)
    run = sim2d.simulate(graph, lambda obs, s, t: actions[:, t], n=n_robots, steps=steps, seed=seed)
    states = torch.as_tensor(run.states, dtype=torch.float32)                            # (n, T + 1, S)
    if episodes:
        return states, torch.as_tensor(run.actions, dtype=torch.float32)
    return (states[:, :-1].flatten(0, 1), torch.as_tensor(run.actions, dtype=torch.float32).flatten(0, 1),
            states[:, 1:].flatten(0, 1))


def best_seconds_per_call(fn, calls: int, repeats: int) -> float:
    """Seconds per call of fn(): one warm-up call, then the best of `repeats` timings of `calls` calls."""
    fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(calls):
            fn()
        times.append((time.perf_counter() - t0) / calls)
    return min(times)


def bench_networks(design: str = "hexapod", batch: int = 256, horizon: int = 20, model_batch: int = 512,
                   repeats: int = 5, cfg: GNNConfig = GNNConfig()) -> dict:
    """Best-of-`repeats` speed of a policy update through model roll-outs, and of a model update."""
    rollout = rlil.rollout                      # Algorithm 1 lines 10-15, the code the training runs
    torch.manual_seed(0)
    graph = sim2d.design_graph(design)
    states, actions, next_states = random_transitions(design, n_robots=32, steps=100, seed=0)
    policy, model = ModularPolicy(cfg), ModularModel(cfg)
    model.fit_normalization([(graph, states, actions, next_states)])
    policy_opt = torch.optim.Adam(policy.parameters(), lr=1e-3, foreach=True)
    model_opt = torch.optim.Adam(model.parameters(), lr=1e-3, foreach=True)

    def policy_update():                        # eqn. (RL_loss) through the frozen model, Sec. III-F
        s0 = states[torch.randint(len(states), (batch,))]
        R, _, _ = rollout(policy, model, s0, policy.initial_hidden(batch, graph), graph, horizon)
        loss = -R.mean()
        policy_opt.zero_grad()
        loss.backward()
        policy_opt.step()

    def model_update():
        i = torch.randint(len(states), (model_batch,))
        loss = model.loss(states[i], actions[i], next_states[i], graph)
        model_opt.zero_grad()
        loss.backward()
        model_opt.step()

    def seconds_per_call(fn, calls):
        return best_seconds_per_call(fn, calls, repeats)

    model.requires_grad_(False)                 # frozen while the policy trains; gradients flow through it
    t_rollout = seconds_per_call(policy_update, 2)
    model.requires_grad_(True)
    t_fit = seconds_per_call(model_update, 20)
    return {"rollout_s": t_rollout, "rollout_robot_steps_per_s": batch * horizon / t_rollout,
            "model_fit_s": t_fit, "model_fit_transitions_per_s": model_batch / t_fit}


def default_run_steps(cfg=None) -> dict:
    """The default run's three kinds of step as functions (train.py's defaults):

    policy step: L_RL over 64 leg_none_wheel robots x T = 20 steps through the frozen
      model, plus lambda L_IL over 2 demo designs (hexapod, car) x 32 windows x 8 steps,
      backward, clipped Adam step (Algorithm 1 lines 9-21; 120 per iteration);
    BC step: L_IL alone, backward, Adam (line 1; 1000 before the loop);
    model step: one-step loss on 512 leg_none_wheel transitions, backward, Adam (line 5).
    Demonstrations are random observations and actions of the demo designs' shapes:
    the cost does not depend on the values.
    """
    cfg = cfg or rlil.Config(train=("lnwwnl",), demos=("llllll", "wnwwnw"))
    rng, graph = np.random.default_rng(0), sim2d.design_graph(cfg.train[0])
    torch.manual_seed(0)
    data = rlil.Trajectories(graph.code, *random_transitions(graph.code, 16, 50, seed=0, episodes=True))
    policy, model = ModularPolicy(cfg.gnn), ModularModel(cfg.gnn)
    flat = data.transitions()
    model.fit_normalization([(graph, *flat)])

    def random_demo(design):                   # (E, T, ...) random obs and actions of the design's shapes
        g, (E, T) = sim2d.design_graph(design), (cfg.demo_episodes, cfg.demo_steps)
        s = rng.standard_normal((E, T, g.state_dim)).astype(np.float32)
        a = rng.uniform(-1, 1, (E, T, g.action_dim)).astype(np.float32)
        return demo_lib.DemoData(g.code, sim2d.observe(s, g), a, s, np.zeros(E), np.zeros(E, bool))

    demo_data = {d: random_demo(d) for d in cfg.demos}
    buffers = {graph.code: rlil.init_buffer(policy, data, cfg, rng)}
    policy_opt = torch.optim.Adam(policy.parameters(), lr=1e-4, foreach=True)
    model_opt = torch.optim.Adam(model.parameters(), lr=1e-4, foreach=True)

    def policy_step():
        model.requires_grad_(False)
        loss_rl = rlil.rl_loss(policy, model, buffers, cfg, rng)
        loss_il, entropy = rlil.il_loss(policy, demo_data, cfg, rng)
        loss = rlil.rlil_loss(loss_rl, loss_il + cfg.entropy_weight * entropy, cfg.il_weight)
        rlil.gradient_step(policy_opt, loss, policy, cfg.grad_clip)
        model.requires_grad_(True)

    def bc_step():
        loss, _ = rlil.il_loss(policy, demo_data, cfg, rng)
        policy_opt.zero_grad()
        loss.backward()
        policy_opt.step()

    def model_step():
        loss = rlil.model_loss(model, graph.code, flat, cfg.model_batch, rng)
        model_opt.zero_grad()
        loss.backward()
        model_opt.step()

    return {"policy": policy_step, "bc": bc_step, "model": model_step}


def bench_default_run(repeats: int = 3) -> dict:
    """Best-of-`repeats` seconds per call of `default_run_steps`, and the policy step's robot-steps/s."""
    cfg, steps = rlil.Config(), default_run_steps()

    def seconds_per_call(fn, calls):
        return best_seconds_per_call(fn, calls, repeats)

    t_policy = seconds_per_call(steps["policy"], 3)
    return {"policy_step_s": t_policy, "policy_robot_steps_per_s": cfg.batch * cfg.horizon / t_policy,
            "bc_step_s": seconds_per_call(steps["bc"], 10), "model_step_s": seconds_per_call(steps["model"], 20)}


def profile_default_run(step: str = "policy", calls: int = 3, rows: int = 25) -> str:
    """torch.profiler's table of the operators of `calls` default-run steps, by self CPU time."""
    from torch.profiler import ProfilerActivity, profile
    fn = default_run_steps()[step]
    fn()                                                                                    # warm-up
    with profile(activities=[ProfilerActivity.CPU]) as prof:
        for _ in range(calls):
            fn()
    return prof.key_averages().table(sort_by="self_cpu_time_total", row_limit=rows)


def print_networks(threads: int) -> None:
    r = bench_networks()
    print(f"hexapod, best of 5, {threads} threads: policy update (T=20 roll-out of 256 robots, "
          f"backward, Adam) {1e3 * r['rollout_s']:.0f} ms; model update (512 transitions) "
          f"{1e3 * r['model_fit_s']:.1f} ms")
    print(f"rollout_robot_steps_per_s={r['rollout_robot_steps_per_s']:.1f} "
          f"model_fit_transitions_per_s={r['model_fit_transitions_per_s']:.1f}")
    d = bench_default_run()
    print(f"default run (train.py's defaults), best of 3, {threads} threads: policy step "
          f"(64 leg_none_wheel robots x T=20 through the model + IL on 2 x 32 windows x 8 steps) "
          f"{1e3 * d['policy_step_s']:.0f} ms; BC step {1e3 * d['bc_step_s']:.1f} ms; "
          f"model step {1e3 * d['model_step_s']:.1f} ms")
    print(f"default_policy_robot_steps_per_s={d['policy_robot_steps_per_s']:.1f}")


# ----------------------------------------------------------------------------
# PPO: one iteration (kept out of ppo_minimal's loop)
# ----------------------------------------------------------------------------
def bench_ppo(design: str = "hexapod", threads: int = 1) -> dict:
    """Seconds of one PPO iteration's collection and update at the default config, and the cost of
    one minibatch step with the memory (sequences re-run in order, as CleanRL's LSTM PPO) and without."""
    torch.set_num_threads(threads)
    cfg = validate_config(PPOConfig(train=(design,), threads=threads))
    run, graph = new_run(cfg), sim2d.design_graph(design)
    policy = Memoryless(run.policy)
    t0 = time.perf_counter()
    batch = collect_episodes(policy, run.value, cfg, run.rng)
    t_collect = time.perf_counter() - t0
    t0 = time.perf_counter()
    advantages, returns = gae(batch.rewards, batch.values, batch.last_value, batch.terminal, cfg.gamma, cfg.gae_lambda)
    ppo_update(policy, run.value, run.opt, batch, advantages, returns, cfg, run.rng)
    t_update = time.perf_counter() - t0
    # one minibatch (N T / minibatches samples) forward + backward, without and with the recurrence
    per_mb = cfg.robots * cfg.episode_steps // cfg.minibatches
    flat = {k: v.flatten(0, 1)[:per_mb] for k, v in batch.obs.items()}
    t0 = time.perf_counter()
    policy.distribution(flat, graph)[0].sum().backward()
    t_flat = time.perf_counter() - t0
    robots = max(1, cfg.robots // cfg.minibatches)          # CleanRL's LSTM PPO: minibatches of whole robots
    t0 = time.perf_counter()
    h, total = run.policy.initial_hidden(robots, graph), 0.0
    for t in range(cfg.episode_steps):
        mean, _, h = run.policy({k: v[:robots, t] for k, v in batch.obs.items()}, graph, h)
        total = total + mean.sum()
    total.backward()
    t_seq = time.perf_counter() - t0
    return {"collect_s": t_collect, "update_s": t_update, "steps": cfg.robots * cfg.episode_steps,
            "minibatch_memoryless_s": t_flat, "minibatch_recurrent_s": t_seq}


def print_ppo(design: str, threads: int) -> None:
    r = bench_ppo(design, threads)
    total = r["collect_s"] + r["update_s"]
    print(f"{design}, {threads} thread(s), one iteration of {r['steps']} steps: collection "
          f"{r['collect_s']:.2f} s ({r['steps'] / r['collect_s']:.0f} steps/s), update {r['update_s']:.2f} s; "
          f"{1e5 / r['steps'] * total / 60:.1f} min per 100 k simulator steps")
    print(f"one minibatch forward+backward: memoryless {1e3 * r['minibatch_memoryless_s']:.0f} ms, "
          f"recurrent (sequences in order) {1e3 * r['minibatch_recurrent_s']:.0f} ms")


# ----------------------------------------------------------------------------
# Phases: where the main command's time goes, phase by phase
# ----------------------------------------------------------------------------
PHASES = [   # (module, function, phase, part): every call of the function is timed under its label
    (rlil, "load_demos", "demonstrations (made, not cached)", ""),
    (rlil, "pretrain_bc", "line 1: behavioural cloning", ""),
    (rlil, "collect_random_rollouts", "line 2: random spline data", ""),
    (rlil, "add_clone_rollouts", "the clone's roll-outs (--clone-data)", ""),
    (rlil, "train_model", "line 5: model fit", ""),
    (rlil, "optimize_policy", "lines 7-26: policy phase", ""),
    (rlil, "rl_loss", "lines 7-26: policy phase", "L_RL: the T-step model roll-out (forward)"),
    (rlil, "il_loss", "lines 7-26: policy phase", "L_IL and the entropy penalty (forward)"),
    (rlil, "gradient_step", "lines 7-26: policy phase", "line 21: backward pass and Adam step"),
    (rlil, "refresh_buffer", "lines 7-26: policy phase", "lines 22-25: buffer refresh"),
    (rlil, "validation_reward", "lines 7-26: policy phase", "validation checks (Sec. III-J)"),
    (rlil, "add_policy_rollouts", "lines 28-29: policy data", ""),
    (rlil, "improvement_check", "the improvement check (--keep-better)", ""),
    (rlil, "evaluate_iteration", "evaluation (Sec. IV, 8 starts x 200 steps)", ""),
]
PHASE_COLUMNS = ["threads", "phase", "part", "calls", "seconds", "cpu_capability"]


class PhaseTimer:
    """Inclusive seconds and calls per label; a part is timed only inside its phase (il_loss in
    line 1 belongs to line 1, in the policy phase to its L_IL part)."""

    def __init__(self):
        self.seconds, self.calls, self.open = {}, {}, []

    def timed(self, fn, phase: str, part: str):
        def wrapper(*args, **kwargs):
            inside = bool(self.open) and self.open[-1] == phase
            if part and not inside or not part and self.open:
                return fn(*args, **kwargs)                  # a part outside its phase, or a phase in another
            label = (phase, part)
            self.open.append(phase if not part else label)
            t0 = time.perf_counter()
            try:
                return fn(*args, **kwargs)
            finally:
                self.open.pop()
                self.seconds[label] = self.seconds.get(label, 0.0) + time.perf_counter() - t0
                self.calls[label] = self.calls.get(label, 0) + 1
        return wrapper

    def add(self, phase: str, seconds: float) -> None:
        self.seconds[(phase, "")] = self.seconds.get((phase, ""), 0.0) + seconds
        self.calls[(phase, "")] = self.calls.get((phase, ""), 0) + 1


def profile_phases(cfg, workdir: Path) -> tuple[dict, dict, float]:
    """Run `cfg` as train.py runs it (demonstrations made afresh in `workdir`, every output written
    after every iteration) with PhaseTimer around PHASES and the outputs: (seconds, calls, total)."""
    timer, saved = PhaseTimer(), [(m, name, getattr(m, name)) for m, name, _, _ in PHASES]
    for m, name, phase, part in PHASES:
        setattr(m, name, timer.timed(getattr(m, name), phase, part))
    out = workdir / "run"
    out.mkdir()

    def write(phase, fn, *args):
        t0 = time.perf_counter()
        fn(*args)
        timer.add(phase, time.perf_counter() - t0)

    def on_iteration(run):
        write("outputs: checkpoint.pt and policy.pt", run_folders.save_checkpoint, out, run)
        write("outputs: metrics.json and .csv, curve.png", run_folders.save_metrics, out, run.cfg, run.metrics)
        write("outputs: metrics.json and .csv, curve.png", run_folders.save_curve, out, run.cfg, run.metrics)
    try:
        t0 = time.perf_counter()
        demo_data = rlil.load_demos(cfg, workdir / "cache")
        run = rlil.algorithm1(cfg, demo_data, log=lambda message: None, on_iteration=on_iteration)
        write("outputs: rollout.gif (its evaluation included)", run_folders.save_rollouts, out, run)
        total = time.perf_counter() - t0
    finally:
        for m, name, fn in saved:
            setattr(m, name, fn)
    return timer.seconds, timer.calls, total


def phase_rows(threads: int) -> list[dict]:
    """PHASE_COLUMNS rows of the main command (train.py's defaults, seed 0) at `threads` torch threads;
    the last row, "the whole run", is its wall time, "other" what no phase covers."""
    import tempfile
    cfg = rlil.validate_config(rlil.Config(train=("leg_none_wheel",), demos=("hexapod", "car"), threads=threads))
    with tempfile.TemporaryDirectory(prefix="phases-") as tmp:
        seconds, calls, total = profile_phases(cfg, Path(tmp))
    cpu = torch.backends.cpu.get_cpu_capability()
    order = [(phase, part) for _, _, phase, part in PHASES] + [k for k in seconds if k[0].startswith("outputs")]
    rows = [{"threads": threads, "phase": phase, "part": part, "calls": calls[phase, part],
             "seconds": seconds[phase, part], "cpu_capability": cpu}
            for phase, part in dict.fromkeys(order) if (phase, part) in seconds]
    covered = sum(r["seconds"] for r in rows if not r["part"])
    rows.append({"threads": threads, "phase": "other (between phases)", "part": "", "calls": 1,
                 "seconds": total - covered, "cpu_capability": cpu})
    rows.append({"threads": threads, "phase": "the whole run", "part": "", "calls": 1, "seconds": total,
                 "cpu_capability": cpu})
    return rows


def print_phases(threads: int, csv_path: Path) -> None:
    """Profile the main command and write its rows into `csv_path` (rows of other thread counts kept)."""
    import csv
    rows = phase_rows(threads)
    kept = []
    if csv_path.exists():
        with open(csv_path, newline="") as f:
            kept = [r for r in csv.DictReader(f) if int(r["threads"]) != threads]

    def write(p):
        with open(p, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=PHASE_COLUMNS)
            w.writeheader()
            w.writerows(kept + rows)
    atomic_write(csv_path, write)
    total = rows[-1]["seconds"]
    for r in rows:
        print(f"{r['seconds']:8.1f} s {100 * r['seconds'] / total:5.1f} %  {r['phase']}"
              + (f": {r['part']}" if r["part"] else "") + f" ({r['calls']} calls)")
    print(f"wrote {csv_path} (python experiments/tables.py makes results/phase_profile.md from it)")


# ----------------------------------------------------------------------------
# Entry point
# ----------------------------------------------------------------------------
def main(argv=None) -> int:
    parser = sim2d.CliParser(prog="tools/bench.py", description=__doc__.split("\n")[0])
    parser.add_argument("--world", action="store_true", help="time the world against bare pymunk")
    parser.add_argument("--networks", action="store_true", help="time hexapod roll-outs and model fitting, "
                        "and the default run's policy, BC and model steps")
    parser.add_argument("--ppo", action="store_true", help="time one PPO iteration (on --design)")
    parser.add_argument("--profile", choices=PROFILE_STEPS,
                        help="print torch.profiler's operator table of 3 default-run steps of this kind")
    parser.add_argument("--phases", action="store_true", help="profile the main command phase by phase (a whole "
                        "run, about 3 minutes) into results/phase_profile.csv, rows of other --threads kept")
    parser.add_argument("--threads", type=int, default=1, help="torch CPU threads (default 1)")
    parser.add_argument("--design", default="hexapod", help="the design of the PPO bench (default hexapod)")
    args = parser.parse_args(argv)
    if args.threads < 1:
        parser.error(f"--threads must be at least 1, got {args.threads}")
    try:
        sim2d.parse_design(args.design)
    except ValueError as e:
        parser.error(str(e))
    if args.phases:
        torch.set_num_threads(args.threads)
        print(provenance(args.threads))
        print_phases(args.threads, Path(__file__).resolve().parents[1] / "results" / "phase_profile.csv")
        return 0
    everything = not (args.world or args.networks or args.ppo or args.profile)
    torch.set_num_threads(args.threads)
    print(provenance(args.threads))
    if args.world or everything:
        print_world()
    if args.networks or everything:
        print_networks(args.threads)
    if args.ppo or everything:
        print_ppo(args.design, args.threads)
    if args.profile:
        print(profile_default_run(args.profile))
    return 0


if __name__ == "__main__":
    sys.exit(main())
