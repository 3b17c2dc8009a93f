"""Command line for Algorithm 1 and the PPO baseline: train, resume, evaluate, plot.

Paper: Whitman & Choset, "Learning Modular Robot Locomotion from
Demonstrations", Algorithm 1 (run by modular_rlil_minimal.py) and Sec. IV
(distance in 200 control steps); the model-free baseline PPO (ppo_minimal.py).
CPU, minutes (README, Quick start); Ctrl-C keeps what finished and prints the command that continues it:

    python train.py --train leg_none_wheel --demos hexapod car     # RL+IL
    python train.py --train leg_none_wheel                         # plain RL baseline
    python train.py --train car --preset tiny                      # class demo (README, Quick start)
    python train.py --train hexapod --method ppo                   # PPO, 2 M simulator steps
    python train.py --eval runs/leg_none_wheel-hexapod_car-seed0 --design hexapod --gif h.gif
    python train.py --transfer runs/leg_none_wheel-hexapod_car-seed0 runs/car-rl-seed0
    python train.py --compare runs/car-rl-seed0 runs/car-hexapod-seed0 --gif rl_vs_rlil.gif
    python train.py --figure3 --seeds 10                           # the paper's Figure 3
    python train.py --sample-efficiency                            # RL, RL+IL, PPO and PPO+IL per simulator step

A run directory holds metrics.json, metrics.csv, curve.png, policy.pt (config
inside), checkpoint.pt (everything a resume needs) and rollout.gif.  An existing
run is never overwritten: --resume continues it, --force starts afresh
(experiments/run_folders.py writes and reads these files).  The sweeps run by
experiments/sweeps.py, --transfer and --compare by experiments/transfer.py.
"""
from __future__ import annotations

import argparse
import ast
import dataclasses
import inspect
import os
import shlex
import shutil
import signal
import sys
import textwrap
import threading
import time
from pathlib import Path

import numpy as np
import torch

import modular_rlil_minimal as rlil
import ppo_minimal as ppo_lib
import sim2d
from experiments import sweeps, transfer
from experiments.run_folders import (Interrupted, UsageError, WriteError, all_flags, claim_output_file,
                                     claim_run_dir, config_flags, config_from_dict, is_ppo, load_checkpoint,
                                     load_policy, ppo_flags, prepare_run_dir, restore_run, run_name, save_checkpoint,
                                     save_curve, save_metrics, save_rollouts, write_or_say)
from gnn import GNNConfig


# ----------------------------------------------------------------------------
# Ctrl-C and SIGTERM
# ----------------------------------------------------------------------------
def on_signal(signum, frame) -> None:
    """SIGINT, SIGTERM: raise Interrupted, except where an exception would be swallowed: inside pymunk
    (its cffi callbacks, freeing bodies, print it and go on) and inside an import (a lazy one, such as
    numpy.random's, can lose it and the run ends as if no signal came).  There the same signal is sent
    again 50 ms later, until it lands in the run's own code."""
    if swallowed_there(frame):
        again = threading.Timer(0.05, os.kill, (os.getpid(), signum))
        again.daemon = True
        again.start()
        return
    raise Interrupted(signum)


def swallowed_there(frame) -> bool:
    """Whether `frame` or a caller of it is pymunk's code or the import machinery."""
    while frame is not None:
        name = frame.f_code.co_filename
        if "pymunk" in name or name.startswith("<frozen importlib"):
            return True
        frame = frame.f_back
    return False


# ----------------------------------------------------------------------------
# One run: train (or continue) it, writing every output after each iteration
# ----------------------------------------------------------------------------
def run(cfg, out: Path, resume: bool = False, force: bool = False, log=None,
        cache_dir=rlil.demo_lib.DEFAULT_CACHE_DIR) -> list[dict]:
    """Run (or continue) Algorithm 1 (a Config) or PPO (a PPOConfig) with every output written
    after each iteration (PPO: after each evaluation).

    Everything is checked before anything is written: a bad config or design is
    a UsageError, and a run that fails before its first checkpoint leaves no
    directory behind (one that existed before is left as it was).
    """
    say = log or rlil.ProgressLog()
    try:
        cfg = (ppo_lib if is_ppo(cfg) else rlil).validate_config(cfg)
    except ValueError as e:
        raise UsageError(str(e))
    lock, created = claim_run_dir(out)             # one writer per folder, from here to the end
    try:
        return train_in(cfg, out, resume, force, say, cache_dir)
    except BaseException:
        if created and not (out / "checkpoint.pt").exists():
            shutil.rmtree(out, ignore_errors=True)          # nothing half-made is left behind
        raise
    finally:
        lock.close()


def train_in(cfg, out: Path, resume: bool, force: bool, say, cache_dir) -> list[dict]:
    """`run` in the folder it has claimed."""
    budget = "env_steps" if is_ppo(cfg) else "iters"          # the one field a resume may change
    resuming = resume and (out / "checkpoint.pt").exists()
    run = None
    if resuming:
        path = out / "checkpoint.pt"
        ckpt = load_checkpoint(path)
        if not isinstance(ckpt, dict) or not isinstance(ckpt.get("config"), dict):
            raise UsageError(f"{path} holds no run config: it is not a training checkpoint; start a new --out")
        saved = config_from_dict(ckpt["config"])
        if type(saved) is not type(cfg) or dataclasses.replace(saved, **{budget: getattr(cfg, budget)}) != cfg:
            raise UsageError(f"--resume with a different configuration than {out}'s: only "
                             f"--{budget.replace('_', '-')} may change (start a new --out for other settings)")
        run = restore_run(ckpt, cfg, path)
        say(f"resuming {out} after iteration {run.iteration}")
    prepare_run_dir(out, resume, force and not resuming)
    total = ppo_lib.iterations(cfg) if is_ppo(cfg) else cfg.iters
    durations, last = [], {"t": time.perf_counter(), "iteration": run.iteration if run else 0}

    def on_iteration(run) -> None:          # after iteration 0 and every later one (PPO: every evaluation)
        write_or_say(out / "checkpoint.pt", lambda: save_checkpoint(out, run))
        write_or_say(out / "metrics.json", lambda: save_metrics(out, run.cfg, run.metrics))
        write_or_say(out / "curve.png", lambda: save_curve(out, run.cfg, run.metrics))
        if run.iteration > last["iteration"]:
            durations.append((time.perf_counter() - last["t"]) / (run.iteration - last["iteration"]))
            say(f"iteration {run.iteration}/{total} done; about "
                f"{(total - run.iteration) * np.mean(durations):.0f} s left")
        last.update(t=time.perf_counter(), iteration=run.iteration)

    demo_data = rlil.load_demos(cfg, cache_dir)
    if demo_data:
        say("demos: " + ", ".join(f"{sim2d.design_name(d)} {len(v.actions)} x {v.actions.shape[1]}"
                                  for d, v in demo_data.items()))
    if is_ppo(cfg):
        run = ppo_lib.ppo(cfg, run=run, log=say, on_evaluation=on_iteration, demo_data=demo_data)
    else:
        run = rlil.algorithm1(cfg, demo_data, run=run, log=say, on_iteration=on_iteration)
    write_or_say(out / "rollout.gif", lambda: save_rollouts(out, run))
    dist = " ".join(f"{m['distance_m']:.2f}" for m in run.metrics)
    say(f"done: distance per {'evaluation' if is_ppo(cfg) else 'iteration'} (m) {dist}; outputs in {out}")
    return run.metrics


def evaluate_run(run_dir: Path, design: str, gif: str | None = None, png: str | None = None,
                 force: bool = False) -> float:
    """Zero-shot or not: the saved policy on any design, distance in 200 steps from the run's
    evaluation starts."""
    claim_output_file(gif, ".gif", "--gif", force)
    claim_output_file(png, ".png", "--png", force)
    cfg, policy, iteration = load_policy(run_dir)
    torch.set_num_threads(cfg.threads)                  # as the run evaluated itself
    graph = sim2d.design_graph(design)
    result = rlil.evaluate_policy(policy, graph.code, cfg, rlil.eval_seed(cfg))
    d = result.distance_m
    print(f"policy {run_dir} (iteration {iteration}) on {graph.name} ({graph.code}): "
          f"{len(d)} starts, min {d.min():.2f} m, max {d.max():.2f} m, flipped {int(result.flipped.sum())}")
    title = f"{run_dir.name} on {graph.name}: {d[0]:.1f} m in {cfg.eval_steps} steps"
    if gif:
        sim2d.atomic_write(Path(gif), lambda p: sim2d.save_gif(graph, result.states[0], p, every=2, title=title))
        print(f"wrote {gif}")
    if png:
        sim2d.atomic_write(Path(png), lambda p: sim2d.save_png(graph, result.states[0], p, title=title))
        print(f"wrote {png}")
    print(f"design={graph.code} distance_m={d.mean():.4f}")
    return float(d.mean())


# ----------------------------------------------------------------------------
# Command line: every Config field is a flag, its docstring the help text
# ----------------------------------------------------------------------------
def field_help(cls) -> dict[str, str]:
    """{field: its help}: the string under each field of the dataclass `cls` (CleanRL's convention)."""
    body = ast.parse(textwrap.dedent(inspect.getsource(cls))).body[0].body
    return {field.target.id: " ".join(doc.value.value.split()) for field, doc in zip(body, body[1:])
            if isinstance(field, ast.AnnAssign) and isinstance(doc, ast.Expr) and isinstance(doc.value, ast.Constant)}


def parse_bool(text: str) -> bool:
    """on/off, true/false, yes/no, 1/0 (argparse's type=bool would take "False" as True)."""
    words = {"on": True, "true": True, "yes": True, "1": True, "off": False, "false": False, "no": False, "0": False}
    if text.lower() not in words:
        raise argparse.ArgumentTypeError(f"expected on/off (or true/false, yes/no, 1/0), got {text!r}")
    return words[text.lower()]


def build_parser() -> sim2d.CliParser:
    p = sim2d.CliParser(description="Modular RL+IL (Algorithm 1) and the PPO baseline on the planar world.")
    p.add_argument("--preset", default="default", help=f"named budget the flags below override: "
                   f"{', '.join(rlil.PRESETS)} (tiny: the tests' budget and the class demo; walk: Figure 3's "
                   "panel (a), where plain RL walks the hexapod)")
    p.add_argument("--out", help="run directory (default runs/<train>-<demos or rl>-seed<S>); with --transfer: "
                   "the folder of its outputs (default runs/transfer)")
    p.add_argument("--resume", action="store_true", help="continue an existing run after its last iteration")
    p.add_argument("--force", action="store_true", help="start afresh, replacing an existing run's outputs "
                   "(--eval, --transfer, --compare: replace existing outputs)")
    p.add_argument("--eval", metavar="RUN_DIR", help="evaluate a saved policy (with --design)")
    p.add_argument("--design", metavar="DESIGN", help="the one design of --eval or --compare (any of the 728, "
                   "trained on or not)")
    p.add_argument("--designs", nargs="+", metavar="DESIGN", help="with --transfer: the designs besides the "
                   "held-out ones (default Figure 3's four)")
    p.add_argument("--gif", help="with --eval or --compare: write an animation of the first start")
    p.add_argument("--png", help="with --eval or --compare: write six snapshots of the first start")
    p.add_argument("--transfer", nargs="+", metavar="RUN_DIR", help="zero-shot transfer table: each run's policy "
                   "on --designs and the 50 held-out designs, against their demonstrators (experiments/transfer.py)")
    p.add_argument("--compare", nargs=2, metavar=("RUN_A", "RUN_B"), help="draw two runs' policies on one "
                   "--design from the same start into --gif (and --png)")
    p.add_argument("--figure3", action="store_true",
                   help="run the paper's Figure 3 sweep: 4 panels x {RL, RL+IL} x seeds")
    p.add_argument("--seeds", type=int, default=3, help="with --figure3 or --sample-efficiency: seeds per condition (default 3)")
    p.add_argument("--jobs", type=int, default=2, help="with --figure3 or --sample-efficiency: runs in parallel processes (default 2)")
    p.add_argument("--panels", help="with --figure3: which panels, e.g. ad (default abcd)")
    p.add_argument("--launcher", choices=sweeps.LAUNCHERS, default="local",
                   help="with a sweep: local processes (--jobs at a time), or Ray tasks of one CPU each "
                        "(pip install -r requirements-ray.txt)")
    p.add_argument("--ray-address", metavar="ADDR", help="with --launcher ray: join this running Ray cluster "
                   "(default: start a local instance of --jobs CPUs)")
    p.add_argument("--plan", action="store_true", help="with a sweep: print one shell command per unfinished "
                   "run (for a SLURM job array, GNU parallel, ...) and run nothing")
    p.add_argument("--collect", metavar="DIR", help="with a sweep: run nothing; make the plot, CSV and summary "
                   "from the run directories in DIR (written to --out, default DIR), naming the missing ones")
    p.add_argument("--accept-other-configs", action="store_true", help="with a sweep: use run folders made with "
                   "other settings as they are (named in a warning) instead of refusing them")
    p.add_argument("--method", choices=("rlil", "ppo"), default="rlil",
                   help="rlil: Algorithm 1 (RL+IL with --demos, else RL); ppo: the model-free baseline "
                        "(ppo_minimal.py) on the same modular policy")
    p.add_argument("--sample-efficiency", action="store_true",
                   help="run RL, RL+IL, PPO and PPO+IL (Figure 3's demos) on hexapod and leg_none_wheel x seeds and plot "
                        "distance against simulator steps and seconds")
    group = p.add_argument_group("Algorithm 1 (modular_rlil_minimal.Config; defaults: the README's main command)")
    default, helps = rlil.Config(), {**field_help(rlil.Config), **field_help(GNNConfig)}
    for flag, dest, f in config_flags():
        value = getattr(default.gnn, f.name) if dest.startswith("gnn_") else getattr(default, f.name)
        if isinstance(value, tuple):
            kind = dict(nargs="+" if f.name == "train" else "*", metavar="DESIGN")
        else:
            kind = dict(type=parse_bool if isinstance(value, bool) else type(value))
        group.add_argument(flag, dest=dest, default=None, help=f"{helps[f.name]} (default {value})", **kind)
    ppo_default, ppo_helps = ppo_lib.PPOConfig(), field_help(ppo_lib.PPOConfig)
    told = {"train", "seed", "threads", "episode_steps", "eval_episodes", "eval_steps", "gnn"}
    shared = [f.name for f in dataclasses.fields(ppo_lib.PPOConfig)
              if f.name in {g.name for g in dataclasses.fields(rlil.Config)} - told]   # demos, bc_steps, il_*, ...
    differ = [n for n in shared if ppo_helps[n] != helps[n] or getattr(ppo_default, n) != getattr(default, n)]
    group = p.add_argument_group(
        "PPO, with --method ppo (ppo_minimal.PPOConfig)",
        "PPO also takes --train (one design), --seed, --threads (default 1), --episode-steps (T, default 200), "
        "--eval-episodes, --eval-steps and the --gnn-* flags above; --preset tiny is its tests' budget. "
        f"With --demos it is PPO+IL (after DAPG) and takes {', '.join('--' + n.replace('_', '-') for n in shared)} "
        "above, with these meanings or defaults for PPO: "
        + "; ".join(f"--{n.replace('_', '-')}: {ppo_helps[n]} (default {getattr(ppo_default, n)})"
                    for n in differ) + ".")
    for flag, dest, f in ppo_flags():
        value = getattr(ppo_default, f.name)
        group.add_argument(flag, dest=dest, default=None, help=f"{ppo_helps[f.name]} (default {value})",
                           type=parse_bool if isinstance(value, bool) else type(value))
    return p


def config_from_args(args, method: str | None = None, strict: bool = True):
    """The preset of `method` (default args.method: a Config, or a PPOConfig for "ppo"), overridden
    by every flag given; checked (UsageError names the bad field).  With `strict`, a flag the
    method does not use is a UsageError; without it (--sample-efficiency builds both) it is ignored."""
    method = method or args.method
    lib = ppo_lib if method == "ppo" else rlil
    own = {dest for _, dest, _ in (all_flags(ppo_lib.PPOConfig()) if method == "ppo" else config_flags())}
    every = {dest for _, dest, _ in config_flags() + ppo_flags()}
    given = {dest: getattr(args, dest) for dest in every if getattr(args, dest) is not None}
    foreign = sorted(set(given) - own)
    if strict and foreign:
        name = "--" + foreign[0].replace("_", "-")
        raise UsageError(f"{name} is not a setting of {'PPO' if method == 'ppo' else 'Algorithm 1'}"
                         + ("" if method == "ppo" else " (PPO's flags need --method ppo)"))
    given = {k: v for k, v in given.items() if k in own}
    try:
        cfg = lib.preset(args.preset)
        gnn = dataclasses.replace(cfg.gnn, **{k[4:]: v for k, v in given.items() if k.startswith("gnn_")})
        cfg = dataclasses.replace(cfg, gnn=gnn, **{k: tuple(v) if isinstance(v, list) else v
                                                   for k, v in given.items() if not k.startswith("gnn_")})
        cfg = lib.validate_config(cfg)
    except ValueError as e:
        raise UsageError(str(e))
    return cfg


def sweep(args) -> int:
    """--figure3 or --sample-efficiency: run, plan or collect the sweep (experiments/sweeps.py); exit
    status 1 when a run is missing or failed, 128 + the signal's number when SIGTERM or Ctrl-C stopped
    it (its runs keep their finished iterations; the same command continues it).  A flag the sweep
    would not use is a UsageError."""
    name = "--figure3" if args.figure3 else "--sample-efficiency"
    if args.figure3 and args.sample_efficiency:
        raise UsageError("--figure3 and --sample-efficiency are two sweeps: run one at a time")
    if not 1 <= args.seeds <= sweeps.MAX_SEEDS or not 1 <= args.jobs <= sweeps.MAX_JOBS:
        raise UsageError(f"--seeds takes 1 to {sweeps.MAX_SEEDS} and --jobs 1 to {sweeps.MAX_JOBS}, "
                         f"got {args.seeds} and {args.jobs}")
    for flag, value in (("--train", args.train), ("--demos", args.demos), ("--seed", args.seed)):
        if value is not None:
            raise UsageError(f"{flag} does nothing with {name}: a sweep sets each run's designs, demos and seed "
                             "itself (--seeds N: seeds 0 to N-1)")
    if args.resume or args.force:
        raise UsageError(f"--resume and --force do nothing with {name}: a sweep continues its unfinished runs "
                         "itself and never replaces finished ones (move a run folder away to run it again)")
    for flag, value in (("--eval", args.eval), ("--design", args.design), ("--designs", args.designs),
                        ("--gif", args.gif), ("--png", args.png), ("--transfer", args.transfer),
                        ("--compare", args.compare)):
        if value is not None:
            raise UsageError(f"{flag} does not go with {name} (it belongs to --eval, --transfer or --compare)")
    if args.method == "ppo":
        raise UsageError(f"--method ppo does nothing with {name}: " + (
            "Figure 3 compares Algorithm 1's RL+IL and RL (--sample-efficiency runs PPO beside them)"
            if args.figure3 else "it runs RL, RL+IL, PPO and PPO+IL, PPO's flags setting its PPO runs"))
    if args.sample_efficiency and args.panels is not None:
        raise UsageError("--panels goes with --figure3 (--sample-efficiency runs hexapod and leg_none_wheel)")
    if args.threads is not None and args.jobs > 1:
        raise UsageError("--threads applies to a sweep only with --jobs 1: runs in parallel get one torch thread each")
    if args.ray_address and args.launcher != "ray":
        raise UsageError("--ray-address goes with --launcher ray")
    if (args.plan or args.collect) and args.launcher != "local":
        raise UsageError("--plan and --collect launch nothing: leave out --launcher")
    if args.plan and args.collect:
        raise UsageError("--plan and --collect exclude each other")
    if args.collect and not Path(args.collect).is_dir():
        raise UsageError(f"--collect {args.collect}: no such folder of run directories")
    collect = Path(args.collect) if args.collect else None
    out = Path(args.out) if args.out else collect or Path("runs/figure3" if args.figure3 else "runs/sample_efficiency")
    warn = lambda line: print(line, file=sys.stderr)          # noqa: E731  (--plan's stdout is the plan)
    if args.figure3:
        args.panels = "abcd" if args.panels is None else args.panels
        if not args.panels or set(args.panels) - set(sweeps.PANELS):
            raise UsageError(f"--panels takes letters from abcd, got {args.panels!r}")
        ppo_only = [flag for flag, dest, _ in ppo_flags() if getattr(args, dest) is not None]
        if ppo_only:
            raise UsageError(f"{ppo_only[0]} is PPO's: --figure3 runs Algorithm 1 only (--sample-efficiency "
                             "runs PPO too)")
        base = config_from_args(args)
        runs, last = sweeps.figure3_runs(out, base, args.seeds, args.jobs, args.panels), base.iters
    else:
        base, base_ppo = config_from_args(args, "rlil", strict=False), config_from_args(args, "ppo", strict=False)
        runs, last = sweeps.sample_efficiency_runs(out, base, base_ppo, args.seeds, args.jobs), 0
    if args.plan:
        sweeps.check_reuse(runs, args.accept_other_configs, log=warn)
        return print_plan(sweeps.plan_lines(runs, last))
    command = ("python train.py " + shlex.join(sys.argv[1:]) if Path(sys.argv[0]).name == "train.py"
               else "the same command")
    try:
        if args.figure3:
            problems = sweeps.figure3(out, base, args.seeds, args.jobs, panels=args.panels, launcher=args.launcher,
                                      ray_address=args.ray_address, collect=collect,
                                      accept_other_configs=args.accept_other_configs)
        else:
            problems = sweeps.sample_efficiency(out, base, base_ppo, args.seeds, args.jobs, launcher=args.launcher,
                                                ray_address=args.ray_address, collect=collect,
                                                accept_other_configs=args.accept_other_configs)
    except KeyboardInterrupt as e:                # SIGTERM or Ctrl-C (main's on_signal, launch_runs)
        e = e if isinstance(e, Interrupted) else Interrupted(getattr(e, "signum", signal.SIGINT))
        print(sweeps.interrupted_line(e, out, command), file=sys.stderr)
        return 128 + e.signum
    return 1 if problems else 0


def print_plan(lines: list[str]) -> int:
    """The plan on stdout, one command per line (nothing else there); a count on stderr."""
    for line in lines:
        print(line)
    print(f"{len(lines)} runs to do", file=sys.stderr)
    return 0


def what_was_kept(out: Path, argv: list[str]) -> str:
    """What `out` keeps and the command that continues the run (the end of an interrupted run's line)."""
    try:
        done = torch.load(out / "checkpoint.pt", weights_only=False)["iteration"]
    except Exception:                             # none yet, or cut short while being written
        return f"nothing was kept in {out}; run the same command again"
    args = [a for a in argv if a not in ("--resume", "--force")]
    args += [] if "--out" in args else ["--out", str(out)]
    kept = f"iterations 0-{done}" if done else "iteration 0"
    return f"{out} keeps {kept}; continue with: python train.py {' '.join(args)} --resume"


def main(argv=None) -> int:
    parser = build_parser()
    argv = sys.argv[1:] if argv is None else list(argv)
    args = parser.parse_args(argv)
    out = None                                    # the run directory an interruption reports on
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:     # not when Ctrl-C is ignored (a background job)
        signal.signal(signal.SIGINT, on_signal)
    if signal.getsignal(signal.SIGTERM) in (signal.SIG_DFL, signal.SIG_IGN):  # a time limit always stops a run cleanly
        signal.signal(signal.SIGTERM, on_signal)
    try:
        if args.sample_efficiency or args.figure3:
            return sweep(args)
        if (args.launcher != "local" or args.ray_address or args.plan or args.collect or args.accept_other_configs
                or args.panels is not None):
            raise UsageError("--launcher, --ray-address, --plan, --collect, --accept-other-configs and --panels go "
                             "with --figure3 or --sample-efficiency")
        if args.transfer or args.compare:
            return transfer.main(args)
        if args.designs:
            raise UsageError("--designs goes with --transfer (--eval and --compare take one --design)")
        if args.eval:
            given = [flag for flag, dest, _ in config_flags() + ppo_flags() if getattr(args, dest) is not None]
            if given or args.resume or args.out or args.method != "rlil" or args.preset != "default":
                raise UsageError(f"--eval evaluates a saved run with its own settings: leave out "
                                 f"{(given or ['--resume, --out, --method and --preset'])[0]}")
            if not args.design:
                raise UsageError("--eval needs --design DESIGN")
            try:
                sim2d.design_graph(args.design)
            except ValueError as e:
                raise UsageError(str(e))
            evaluate_run(Path(args.eval), args.design, args.gif, args.png, args.force)
            return 0
        if args.design or args.gif or args.png:
            raise UsageError("--design, --gif and --png go with --eval or --compare")
        if not args.train:
            raise UsageError("say what to train with --train DESIGN [DESIGN ...] (or --eval RUN_DIR)")
        if args.resume and args.force:
            raise UsageError("--resume and --force exclude each other")
        cfg = config_from_args(args)
        out = Path(args.out) if args.out else Path("runs") / run_name(cfg)
        if args.resume and not (out / "checkpoint.pt").exists():
            raise UsageError(f"nothing to resume: {out} has no checkpoint.pt")
        run(cfg, out, resume=args.resume, force=args.force)
        return 0
    except UsageError as e:
        parser.error(str(e))
    except WriteError as e:
        print(f"{parser.prog}: error: {e}; {what_was_kept(out, argv)}", file=sys.stderr)
        return 1
    except KeyboardInterrupt as e:
        signum = getattr(e, "signum", signal.SIGINT)
        if out is None:                           # a sweep: every run is a run directory of its own
            print(f"interrupted ({signal.Signals(signum).name}): finished runs are kept, interrupted ones "
                  "continue from their last checkpoint: run the same command again", file=sys.stderr)
        else:
            print(f"interrupted ({signal.Signals(signum).name}): {what_was_kept(out, argv)}", file=sys.stderr)
        return 128 + signum


if __name__ == "__main__":
    sys.exit(main())
