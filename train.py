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
    python train.py --transfer runs/leg_none_wheel-hexapod_car-seed0 runs/car-rl-seed0   # transfer.py
    python train.py --compare runs/car-rl-seed0 runs/car-hexapod-seed0 --gif rl_vs_rlil.gif
    python train.py --sample-efficiency                            # RL, RL+IL, PPO and PPO+IL per simulator step

A run directory holds metrics.json, metrics.csv, curve.png, policy.pt (config
inside), checkpoint.pt (everything a resume needs) and rollout.gif.  An existing
run is never overwritten: --resume continues it, --force starts afresh.
The sweeps (--figure3, --sample-efficiency) and the results tables are in sweeps.py.
"""
from __future__ import annotations

import argparse
import csv
import dataclasses
import inspect
import json
import os
import re
import shutil
import signal
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

import modular_rlil_minimal as rlil
import ppo_minimal as ppo_lib
import sim2d
from gnn import GNNConfig, ModularModel, ModularPolicy

LAUNCHERS = ("local", "ray")      # how a sweep runs its runs (sweeps.launch_runs)
OUTPUTS = ("metrics.json", "metrics.csv", "curve.png", "policy.pt", "checkpoint.pt", "rollout.gif")


class UsageError(Exception):
    """Bad input: reported as one line with exit status 2."""


# ----------------------------------------------------------------------------
# Small helpers: run names, atomic writes, config round trip
# ----------------------------------------------------------------------------
def is_ppo(cfg) -> bool:
    """A PPO baseline config (ppo_minimal.PPOConfig) rather than Algorithm 1's (Config)."""
    return isinstance(cfg, ppo_lib.PPOConfig)


def run_name(cfg) -> str:
    """<train>-<demos or rl>-seed<S>; PPO: <train>-ppo-seed<S>, with demos <train>-ppo_<demos>-seed<S>."""
    train = "+".join(sim2d.design_name(sim2d.parse_design(d)) for d in cfg.train)
    demos = "_".join(sim2d.design_name(sim2d.parse_design(d)) for d in cfg.demos)
    if is_ppo(cfg):
        return f"{train}-ppo{'_' + demos if demos else ''}-seed{cfg.seed}"
    return f"{train}-{demos or 'rl'}-seed{cfg.seed}"


def atomic_write(path: Path, write) -> None:
    """write(tmp_path) then rename over `path`: a crash never leaves half a file."""
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.stem}.", suffix=path.suffix)
    os.close(fd)
    try:
        write(tmp)
        os.chmod(tmp, 0o644)                     # mkstemp makes 0600 files
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)


def versions() -> dict:
    """What a run's digits depend on besides its config (Config.threads among them): the library
    versions and the CPU's vector instructions torch uses (AVX2, AVX512, ...)."""
    import pymunk
    return {"torch": torch.__version__, "numpy": np.__version__, "pymunk": pymunk.version,
            "python": sys.version.split()[0], "cpu_capability": torch.backends.cpu.get_cpu_capability()}


def config_to_dict(cfg) -> dict:
    """The config as JSON-able dict, with the library versions under "versions" and
    "method": "ppo" for a PPO run (Algorithm 1's runs have no "method")."""
    return {**dataclasses.asdict(cfg), **({"method": "ppo"} if is_ppo(cfg) else {}), "versions": versions()}


# Settings that left the code (docs/ablations.md, Removed mechanisms) and the value at which the
# code they switched on did nothing: a run written with that value is today's algorithm.
REMOVED_AT_OFF = {"ensemble": 1, "held_out_models": 0, "trust_region": 0.0, "gnn.contact_features": False,
                  "critic": False}
REMOVED_WITH_THEIR_SWITCH = ("critic_gamma", "critic_lambda", "critic_steps")   # acted only with it on


def config_from_dict(d: dict):
    """The config `config_to_dict` wrote; a UsageError naming settings this version lacks (a
    removed setting at its off value, REMOVED_AT_OFF, is dropped: the run did not use it; so are
    the parameters of a removed switch, REMOVED_WITH_THEIR_SWITCH, whatever their value)."""
    def kept(settings: dict, prefix: str = "") -> dict:
        return {k: v for k, v in settings.items() if prefix + k not in REMOVED_WITH_THEIR_SWITCH
                and not (prefix + k in REMOVED_AT_OFF and v == REMOVED_AT_OFF[prefix + k])}
    d = {k: v for k, v in kept(d).items() if k not in ("versions", "method")}
    d["gnn"] = kept(d["gnn"], "gnn.")
    cls = ppo_lib.PPOConfig if "env_steps" in d else rlil.Config       # PPO's are written with "method": "ppo"
    unknown = sorted(set(d) - {f.name for f in dataclasses.fields(cls)})
    unknown += sorted(f"gnn.{k}" for k in set(d["gnn"]) - {f.name for f in dataclasses.fields(GNNConfig)})
    if unknown:
        raise UsageError(f"this run was written by another version of the code: settings {', '.join(unknown)} "
                         "no longer exist (docs/ablations.md, Removed mechanisms); start a new run")
    d["gnn"] = GNNConfig(**d["gnn"])
    d["train"], d["demos"] = tuple(d["train"]), tuple(d.get("demos", ()))   # PPO runs before PPO+IL had none
    return cls(**d)


def method_of(cfg) -> str:
    if is_ppo(cfg):
        return "PPO+IL" if cfg.demos else "PPO"
    return "RL+IL" if cfg.demos else "RL"


def policy_to_evaluate(cfg, policy: ModularPolicy):
    """The policy as it acts in its run: PPO trains it without its memory (ppo_minimal.Memoryless)."""
    return ppo_lib.Memoryless(policy) if is_ppo(cfg) else policy


# ----------------------------------------------------------------------------
# Outputs
# ----------------------------------------------------------------------------
def save_metrics(out: Path, cfg: rlil.Config, metrics: list[dict]) -> None:
    atomic_write(out / "metrics.json", lambda p: Path(p).write_text(
        json.dumps({"config": config_to_dict(cfg), "iterations": metrics}, indent=1)))
    columns = list(dict.fromkeys(k for row in metrics for k in row))

    def write_csv(p):
        with open(p, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=columns)
            w.writeheader()
            w.writerows(metrics)
    atomic_write(out / "metrics.csv", write_csv)


COLOURS = {"RL+IL": "tab:blue", "RL": "tab:red", "PPO": "tab:green", "PPO+IL": "tab:purple"}


def save_curve(out: Path, cfg, metrics: list[dict]) -> None:
    """curve.png: distance per iteration (Algorithm 1) or per simulator step (PPO)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    x_key = "sim_steps" if is_ppo(cfg) else "iteration"
    it = [m[x_key] for m in metrics]
    fig, ax = plt.subplots(figsize=(6, 4), dpi=100)
    colour = COLOURS[method_of(cfg)]
    ax.plot(it, [m["distance_m"] for m in metrics], "o-", color=colour, label=f"{method_of(cfg)} (seed {cfg.seed})")
    ax.fill_between(it, [m["distance_min_m"] for m in metrics], [m["distance_max_m"] for m in metrics],
                    color=colour, alpha=0.2, label="min-max over starts")
    ax.set_xlabel("simulator steps (evaluation excluded)" if is_ppo(cfg) else "iteration")
    ax.set_ylabel(f"distance in {cfg.eval_steps} steps (m)")
    ax.set_title(run_name(cfg))
    if not is_ppo(cfg):
        ax.set_xticks(it)
    ax.legend()
    ax.grid(alpha=0.3)
    fig.tight_layout()
    atomic_write(out / "curve.png", lambda p: fig.savefig(p, format="png"))
    plt.close(fig)


def save_checkpoint(out: Path, run) -> None:
    """policy.pt (policy + config, for --eval) and checkpoint.pt (everything, for --resume)."""
    cfg = config_to_dict(run.cfg)
    atomic_write(out / "policy.pt", lambda p: torch.save(
        {"config": cfg, "policy": run.policy.state_dict(), "iteration": run.iteration}, p))
    if is_ppo(run.cfg):
        atomic_write(out / "checkpoint.pt", lambda p: torch.save({
            "config": cfg, "policy": run.policy.state_dict(), "value": run.value.state_dict(),
            "opt": run.opt.state_dict(), "iteration": run.iteration, "sim_steps": run.sim_steps,
            "return_scale": dataclasses.asdict(run.return_scale), "metrics": run.metrics,
            "rng": run.rng_state()}, p))
        return
    atomic_write(out / "checkpoint.pt", lambda p: torch.save({
        "config": cfg, "policy": run.policy.state_dict(), "model": run.model.state_dict(),
        "data": {d: {"states": t.states, "actions": t.actions} for d, t in run.data.items()},
        "il_weight": run.il_weight, "iteration": run.iteration, "kept_return": run.kept_return,
        "metrics": run.metrics, "rng": run.rng_state()}, p))


def load_checkpoint(path: Path) -> dict:
    if not path.is_file():
        raise UsageError(f"no checkpoint at {path}: give a run directory written by train.py")
    try:
        return torch.load(path, weights_only=False)
    except Exception as e:   # any unreadable file: truncated, not a torch file, ...
        raise UsageError(f"cannot read checkpoint {path} ({type(e).__name__}): the file is corrupt or not from train.py")


def restore_run(ckpt: dict, cfg):
    if is_ppo(cfg):
        run = ppo_lib.new_run(cfg)
        run.policy.load_state_dict(ckpt["policy"])
        run.value.load_state_dict(ckpt["value"])
        run.opt.load_state_dict(ckpt["opt"])
        run.iteration, run.sim_steps, run.metrics = ckpt["iteration"], ckpt["sim_steps"], ckpt["metrics"]
        run.return_scale = ppo_lib.ReturnScale(**ckpt["return_scale"])
        run.rng = rlil.Run.rng_from_state(ckpt["rng"])
        return run
    policy, model = ModularPolicy(cfg.gnn), ModularModel(cfg.gnn)
    policy.load_state_dict(ckpt["policy"])
    model.load_state_dict(ckpt["model"])
    data = {d: rlil.Trajectories(d, v["states"], v["actions"]) for d, v in ckpt["data"].items()}
    return rlil.Run(cfg, policy, model, data, ckpt["il_weight"], rlil.Run.rng_from_state(ckpt["rng"]),
                    ckpt["iteration"], ckpt["metrics"], ckpt.get("kept_return"))


def save_rollouts(out: Path, run) -> None:
    """rollout.gif: the final policy on each training design (one file per extra design)."""
    for k, design in enumerate(run.cfg.train):
        result = rlil.evaluate_policy(policy_to_evaluate(run.cfg, run.policy), design, run.cfg,
                                      rlil.eval_seed(run.cfg))
        name = "rollout.gif" if k == 0 else f"rollout_{sim2d.design_name(design)}.gif"
        atomic_write(out / name, lambda p: sim2d.save_gif(design, result.states[0], p, every=2))


# ----------------------------------------------------------------------------
# Commands
# ----------------------------------------------------------------------------
def prepare_run_dir(out: Path, resume: bool, force: bool) -> None:
    if out.exists() and not out.is_dir():
        raise UsageError(f"--out {out} is a file, not a directory: name a new or existing run directory")
    existing = [f for f in OUTPUTS if (out / f).exists()]
    if existing and not (resume or force):
        raise UsageError(f"{out} already holds a run ({', '.join(existing)}): "
                         "use --resume to continue it or --force to start afresh")
    created = not out.exists()
    try:
        out.mkdir(parents=True, exist_ok=True)
        tempfile.TemporaryFile(dir=out).close()                  # can files be written there?
    except OSError as e:
        if created and out.is_dir():
            shutil.rmtree(out, ignore_errors=True)
        raise UsageError(f"cannot write the run directory {out} ({e.strerror or type(e).__name__}): "
                         "name a directory you can write with --out")
    if force:
        for f in existing:
            (out / f).unlink()


PENDING_CTRL_C = []   # a Ctrl-C that arrived inside pymunk, raised at the next log line or checkpoint


def on_ctrl_c(signum, frame) -> None:
    """SIGINT: KeyboardInterrupt, except inside pymunk, whose cffi callbacks (freeing bodies) would
    print the exception and swallow it; there it waits in PENDING_CTRL_C for `raise_pending_ctrl_c`."""
    if frame is not None and "pymunk" in frame.f_code.co_filename:
        PENDING_CTRL_C.append(signum)
        return
    raise KeyboardInterrupt


def raise_pending_ctrl_c() -> None:
    if PENDING_CTRL_C:
        PENDING_CTRL_C.clear()
        raise KeyboardInterrupt


def train(cfg, out: Path, resume: bool = False, force: bool = False, log=None,
          cache_dir=rlil.demo_lib.DEFAULT_CACHE_DIR) -> list[dict]:
    """Run (or continue) Algorithm 1 (a Config) or PPO (a PPOConfig) with every output written
    after each iteration (PPO: after each evaluation).

    Everything is checked before anything is written: a bad config or design is
    a UsageError, and a run that fails before its first checkpoint leaves no
    directory behind (one that existed before is left as it was).
    """
    log_line = log or rlil.ProgressLog()

    def log(message: str) -> None:
        raise_pending_ctrl_c()
        log_line(message)
    try:
        cfg = (ppo_lib if is_ppo(cfg) else rlil).validate_config(cfg)
    except ValueError as e:
        raise UsageError(str(e))
    budget = "env_steps" if is_ppo(cfg) else "iters"          # the one field a resume may change
    resuming = resume and (out / "checkpoint.pt").exists()
    run = None
    if resuming:
        ckpt = load_checkpoint(out / "checkpoint.pt")
        saved = config_from_dict(ckpt["config"])
        if type(saved) is not type(cfg) or dataclasses.replace(saved, **{budget: getattr(cfg, budget)}) != cfg:
            raise UsageError(f"--resume with a different configuration than {out}'s: only "
                             f"--{budget.replace('_', '-')} may change (start a new --out for other settings)")
        run = restore_run(ckpt, cfg)
        log(f"resuming {out} after iteration {run.iteration}")
    created = not out.exists()
    prepare_run_dir(out, resume, force and not resuming)
    total = ppo_lib.iterations(cfg) if is_ppo(cfg) else cfg.iters
    durations, last = [], {"t": time.perf_counter(), "iteration": run.iteration if run else 0}

    def on_iteration(run) -> None:          # after iteration 0 and every later one (PPO: every evaluation)
        raise_pending_ctrl_c()
        save_checkpoint(out, run)
        save_metrics(out, run.cfg, run.metrics)
        save_curve(out, run.cfg, run.metrics)
        if run.iteration > last["iteration"]:
            durations.append((time.perf_counter() - last["t"]) / (run.iteration - last["iteration"]))
            log(f"iteration {run.iteration}/{total} done; about "
                f"{(total - run.iteration) * np.mean(durations):.0f} s left")
        last.update(t=time.perf_counter(), iteration=run.iteration)

    try:
        demo_data = rlil.load_demos(cfg, cache_dir)
        if demo_data:
            log("demos: " + ", ".join(f"{sim2d.design_name(d)} {len(v.actions)} x {v.actions.shape[1]}"
                                       for d, v in demo_data.items()))
        if is_ppo(cfg):
            run = ppo_lib.ppo(cfg, run=run, log=log, on_evaluation=on_iteration, demo_data=demo_data)
        else:
            run = rlil.algorithm1(cfg, demo_data, run=run, log=log, on_iteration=on_iteration)
    except BaseException:
        if created and not (out / "checkpoint.pt").exists():
            shutil.rmtree(out, ignore_errors=True)          # nothing half-made is left behind
        raise
    save_rollouts(out, run)
    dist = " ".join(f"{m['distance_m']:.2f}" for m in run.metrics)
    log(f"done: distance per {'evaluation' if is_ppo(cfg) else 'iteration'} (m) {dist}; outputs in {out}")
    return run.metrics


def load_policy(run_dir: Path):
    """A run directory's policy.pt: (its config, the policy as it is evaluated, its iteration)."""
    ckpt = load_checkpoint(Path(run_dir) / "policy.pt")
    cfg = config_from_dict(ckpt["config"])
    policy = ModularPolicy(cfg.gnn)
    policy.load_state_dict(ckpt["policy"])
    return cfg, policy_to_evaluate(cfg, policy), ckpt["iteration"]


def check_new(paths, force: bool) -> None:
    """A UsageError naming the existing files among `paths` (None skipped) unless `force`."""
    existing = [str(p) for p in paths if p is not None and Path(p).exists()]
    if existing and not force:
        raise UsageError(f"{', '.join(existing)} already exist{'s' if len(existing) == 1 else ''}: "
                         "use --force to replace, or name another output")


def evaluate_run(run_dir: Path, design: str, gif: str | None = None, png: str | None = None,
                 force: bool = False) -> float:
    """Zero-shot or not: the saved policy on any design, distance in 200 steps from the run's
    evaluation starts."""
    check_new([gif, png], force)
    cfg, policy, iteration = load_policy(run_dir)
    torch.set_num_threads(cfg.threads)                  # as the run evaluated itself
    graph = sim2d.design_graph(design)
    result = rlil.evaluate_policy(policy, graph.code, cfg, rlil.eval_seed(cfg))
    d = result.distance_m
    print(f"policy {run_dir} (iteration {iteration}) on {graph.name} ({graph.code}): "
          f"{len(d)} starts, min {d.min():.2f} m, max {d.max():.2f} m, flipped {int(result.flipped.sum())}")
    title = f"{run_dir.name} on {graph.name}: {d[0]:.1f} m in {cfg.eval_steps} steps"
    if gif:
        sim2d.save_gif(graph, result.states[0], gif, every=2, title=title)
        print(f"wrote {gif}")
    if png:
        sim2d.save_png(graph, result.states[0], png, title=title)
        print(f"wrote {png}")
    print(f"design={graph.code} distance_m={d.mean():.4f}")
    return float(d.mean())


# ----------------------------------------------------------------------------
# Command line: every Config field is a flag, its comment the help text
# ----------------------------------------------------------------------------
def field_help(cls) -> dict[str, str]:
    """{field: the comment after it in `cls`'s source}, comment-only lines aligned under it included."""
    helps, last, column = {}, None, None
    for line in inspect.getsource(cls).splitlines():
        m = re.match(r"\s+(\w+): [^#]+#\s?(.*)", line)
        if m:
            helps[m[1]], last, column = m[2].strip(), m[1], line.index("#")
        elif last and line.strip().startswith("#") and line.index("#") == column:
            helps[last] += " " + line.strip("# \n")
        else:
            last = None
    return helps


def parse_bool(text: str) -> bool:
    """on/off, true/false, yes/no, 1/0 (argparse's type=bool would take "False" as True)."""
    words = {"on": True, "true": True, "yes": True, "1": True, "off": False, "false": False, "no": False, "0": False}
    if text.lower() not in words:
        raise argparse.ArgumentTypeError(f"expected on/off (or true/false, yes/no, 1/0), got {text!r}")
    return words[text.lower()]


def config_flags() -> list[tuple[str, str, dataclasses.Field]]:
    """(flag, dest, field) for every Config field; GNNConfig's fields as --gnn-<name>."""
    flags = [("--" + f.name.replace("_", "-"), f.name, f) for f in dataclasses.fields(rlil.Config) if f.name != "gnn"]
    flags += [("--gnn-" + f.name.replace("_", "-"), "gnn_" + f.name, f) for f in dataclasses.fields(GNNConfig)]
    return flags


def ppo_flags() -> list[tuple[str, str, dataclasses.Field]]:
    """(flag, dest, field) for the PPOConfig fields Config lacks; the shared ones (--train, --seed,
    --threads, --episode-steps, --eval-episodes, --eval-steps, --gnn-*) use Config's flags."""
    shared = {f.name for f in dataclasses.fields(rlil.Config)}
    return [("--" + f.name.replace("_", "-"), f.name, f) for f in dataclasses.fields(ppo_lib.PPOConfig)
            if f.name not in shared]


def all_flags(cfg) -> list[tuple[str, str, dataclasses.Field]]:
    """The flags of `cfg`'s fields: every Config field, or every PPOConfig field."""
    if not is_ppo(cfg):
        return config_flags()
    names = {f.name for f in dataclasses.fields(ppo_lib.PPOConfig)}
    return [x for x in config_flags() if x[1].startswith("gnn_") or x[1] in names] + ppo_flags()


def config_args(cfg) -> list[str]:
    """The train.py arguments that rebuild `cfg`: --method ppo for PPO, --train, --demos, and every
    field that differs from the default."""
    default = type(cfg)()
    args = (["--method", "ppo"] if is_ppo(cfg) else []) + ["--train", *cfg.train]
    args += ["--demos", *cfg.demos] if cfg.demos else []
    for flag, dest, f in all_flags(cfg):
        value = getattr(cfg.gnn, f.name) if dest.startswith("gnn_") else getattr(cfg, f.name)
        base = getattr(default.gnn, f.name) if dest.startswith("gnn_") else getattr(default, f.name)
        if f.name not in ("train", "demos") and value != base:
            args += [flag, str(value)]
    return args


def build_parser() -> sim2d.CliParser:
    p = sim2d.CliParser(description="Modular RL+IL (Algorithm 1) and the PPO baseline on the planar world.")
    p.add_argument("--preset", default="default", help=f"named budget the flags below override: "
                   f"{', '.join(rlil.PRESETS)} (tiny: the tests' budget and the class demo)")
    p.add_argument("--out", help="run directory (default runs/<train>-<demos or rl>-seed<S>); with --transfer: "
                   "the folder of its outputs (default runs/transfer)")
    p.add_argument("--resume", action="store_true", help="continue an existing run after its last iteration")
    p.add_argument("--force", action="store_true", help="start afresh, replacing an existing run's outputs "
                   "(--eval, --transfer, --compare: replace existing outputs)")
    p.add_argument("--eval", metavar="RUN_DIR", help="evaluate a saved policy (with --design)")
    p.add_argument("--design", nargs="+", metavar="DESIGN", help="design for --eval or --compare (any of the 728, "
                   "trained on or not); with --transfer: the designs besides the held-out ones (default Figure 3's)")
    p.add_argument("--gif", help="with --eval or --compare: write an animation of the first start")
    p.add_argument("--png", help="with --eval or --compare: write six snapshots of the first start")
    p.add_argument("--transfer", nargs="+", metavar="RUN_DIR", help="zero-shot transfer table: each run's policy "
                   "on --design and the 50 held-out designs, against their demonstrators (transfer.py)")
    p.add_argument("--compare", nargs=2, metavar=("RUN_A", "RUN_B"), help="draw two runs' policies on one "
                   "--design from the same start into --gif (and --png)")
    p.add_argument("--figure3", action="store_true",
                   help="run the paper's Figure 3 sweep: 4 panels x {RL, RL+IL} x seeds")
    p.add_argument("--seeds", type=int, default=3, help="with --figure3 or --sample-efficiency: seeds per condition (default 3)")
    p.add_argument("--jobs", type=int, default=2, help="with --figure3 or --sample-efficiency: runs in parallel processes (default 2)")
    p.add_argument("--panels", default="abcd", help="with --figure3: which panels, e.g. ad (default abcd)")
    p.add_argument("--launcher", choices=LAUNCHERS, default="local",
                   help="with a sweep: local processes (--jobs at a time), or Ray tasks of one CPU each "
                        "(pip install -r requirements-ray.txt)")
    p.add_argument("--ray-address", metavar="ADDR", help="with --launcher ray: join this running Ray cluster "
                   "(default: start a local instance of --jobs CPUs)")
    p.add_argument("--plan", action="store_true", help="with a sweep: print one shell command per unfinished "
                   "run (for a SLURM job array, GNU parallel, ...) and run nothing")
    p.add_argument("--collect", metavar="DIR", help="with a sweep: run nothing; make the plot, CSV and summary "
                   "from the run directories in DIR (written to --out, default DIR), naming the missing ones")
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
    """--figure3 or --sample-efficiency: run, plan or collect the sweep (sweeps.py); exit status 1 when
    a run is missing or failed."""
    sys.modules.setdefault("train", sys.modules[__name__])   # run as a script: sweeps gets this module
    import sweeps                                             # sweeps imports train: not at the top
    if args.seeds < 1 or args.jobs < 1:
        raise UsageError(f"--seeds and --jobs must be positive integers, got {args.seeds} and {args.jobs}")
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
    if args.figure3:
        if not args.panels or set(args.panels) - set(sweeps.PANELS):
            raise UsageError(f"--panels takes letters from abcd, got {args.panels!r}")
        base = config_from_args(args)
        if args.plan:
            return print_plan(sweeps.plan_lines(sweeps.figure3_runs(out, base, args.seeds, args.jobs, args.panels),
                                                base.iters))
        problems = sweeps.figure3(out, base, args.seeds, args.jobs, panels=args.panels, launcher=args.launcher,
                                  ray_address=args.ray_address, collect=collect)
    else:
        base, base_ppo = config_from_args(args, "rlil", strict=False), config_from_args(args, "ppo", strict=False)
        if args.plan:
            return print_plan(sweeps.plan_lines(sweeps.sample_efficiency_runs(out, base, base_ppo, args.seeds,
                                                                              args.jobs), 0))
        problems = sweeps.sample_efficiency(out, base, base_ppo, args.seeds, args.jobs, launcher=args.launcher,
                                            ray_address=args.ray_address, collect=collect)
    return 1 if problems else 0


def print_plan(lines: list[str]) -> int:
    """The plan on stdout, one command per line (nothing else there); a count on stderr."""
    for line in lines:
        print(line)
    print(f"{len(lines)} runs to do", file=sys.stderr)
    return 0


def resume_hint(out: Path, argv: list[str]) -> str:
    """The one line Ctrl-C prints: what `out` keeps and the command that continues the run."""
    try:
        done = torch.load(out / "checkpoint.pt", weights_only=False)["iteration"]
    except Exception:                             # none yet, or cut short while being written
        return f"interrupted before the first checkpoint: nothing was kept in {out}; run the same command again"
    args = [a for a in argv if a not in ("--resume", "--force")]
    args += [] if "--out" in args else ["--out", str(out)]
    kept = f"iterations 0-{done}" if done else "iteration 0"
    return (f"interrupted: {out} keeps {kept}; continue with: "
            f"python train.py {' '.join(args)} --resume")


def main(argv=None) -> int:
    parser = build_parser()
    argv = sys.argv[1:] if argv is None else list(argv)
    args = parser.parse_args(argv)
    out = None                                    # the run directory a Ctrl-C reports on
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        signal.signal(signal.SIGINT, on_ctrl_c)
    try:
        if args.sample_efficiency or args.figure3:
            return sweep(args)
        if args.launcher != "local" or args.ray_address or args.plan or args.collect:
            raise UsageError("--launcher, --ray-address, --plan and --collect go with --figure3 or --sample-efficiency")
        if args.transfer or args.compare:
            sys.modules.setdefault("train", sys.modules[__name__])   # run as a script: transfer gets this module
            import transfer                                           # transfer imports train: not at the top
            return transfer.main(args)
        if args.eval:
            if not args.design or len(args.design) > 1:
                raise UsageError("--eval needs one --design DESIGN")
            args.design = args.design[0]
            try:
                sim2d.design_graph(args.design)
            except ValueError as e:
                raise UsageError(str(e))
            evaluate_run(Path(args.eval), args.design, args.gif, args.png, args.force)
            return 0
        if not args.train:
            raise UsageError("say what to train with --train DESIGN [DESIGN ...] (or --eval RUN_DIR)")
        if args.resume and args.force:
            raise UsageError("--resume and --force exclude each other")
        cfg = config_from_args(args)
        out = Path(args.out) if args.out else Path("runs") / run_name(cfg)
        if args.resume and not (out / "checkpoint.pt").exists():
            raise UsageError(f"nothing to resume: {out} has no checkpoint.pt")
        train(cfg, out, resume=args.resume, force=args.force)
        return 0
    except UsageError as e:
        parser.error(str(e))
    except KeyboardInterrupt:
        if out is None:                           # a sweep: every run is a run directory of its own
            print("interrupted: finished runs are kept, interrupted ones continue from their last "
                  "checkpoint: run the same command again", file=sys.stderr)
        else:
            print(resume_hint(out, argv), file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
