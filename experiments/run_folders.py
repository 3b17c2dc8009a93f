"""What train.py and the experiments share: run folders, their config, and their outputs.

A run folder (runs/<design>-<demos or rl>-seed<S>/) holds metrics.json,
metrics.csv, curve.png, policy.pt (the policy and its config, for --eval),
checkpoint.pt (everything --resume needs) and rollout.gif.  This module names
runs, writes and reads those files, turns a run's config into JSON and into the
train.py flags that rebuild it, and loads a saved policy.  It sits below
train.py, experiments/sweeps.py and experiments/transfer.py, and imports only
the stage files.
"""
from __future__ import annotations

import csv
import dataclasses
import fcntl
import hashlib
import json
import os
import shutil
import signal
import sys
import tempfile
from pathlib import Path

import numpy as np
import torch

import modular_rlil_minimal as rlil
import ppo_minimal as ppo_lib
import sim2d
from gnn import GNNConfig, ModularModel, ModularPolicy
from sim2d import atomic_write

OUTPUTS = ("metrics.json", "metrics.csv", "curve.png", "policy.pt", "checkpoint.pt", "rollout.gif")


class UsageError(Exception):
    """Bad input: reported as one line with exit status 2."""


class Interrupted(KeyboardInterrupt):
    """Ctrl-C (SIGINT) or SIGTERM (what a cluster scheduler sends at a time limit), handled alike: a
    run keeps its finished iterations; a sweep's runs stopped with `finished` of `total` finished."""

    def __init__(self, signum: int = signal.SIGINT, finished: int | None = None, total: int | None = None):
        super().__init__(signal.Signals(signum).name)
        self.signum, self.finished, self.total = signum, finished, total


# ----------------------------------------------------------------------------
# Run names and the config round trip
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


# Settings that left the code (docs/history/2026-11-ablations.md, "Removed mechanisms", and
# docs/history/2026-12-plain-rl-diagnosis.md for recent_data and improvement_tries,
# docs/history/2026-12-class-run-budgets.md for bc_lr) and the value at which the
# code they switched on did nothing: a run written with that value is today's algorithm.
REMOVED_AT_OFF = {"ensemble": 1, "held_out_models": 0, "trust_region": 0.0, "gnn.contact_features": False,
                  "critic": False, "random_knots": 10, "recent_data": 0.0,
                  "random_wave_share": 1.0, "wheel_splines": False, "random_wave_offset": 0.0,
                  "bc_lr": 1e-3, "improvement_tries": 1}
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
                         "no longer exist (docs/results.md lists the removed mechanisms); start a new run")
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


COLOURS = {"RL+IL": "tab:blue", "RL": "tab:red", "PPO": "tab:green", "PPO+IL": "tab:purple",
           "SB3 PPO": "tab:olive"}   # SB3 PPO: interfaces/sb3_ppo.py, only collected (its CSVs in sb3_ppo_runs/)


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


def restore_run(ckpt: dict, cfg, path: Path):
    """The run a checkpoint.pt holds, to continue it; a UsageError for a file that is not one."""
    needs = {"policy", "iteration", "metrics", "rng"} | ({"value", "opt", "sim_steps", "return_scale"} if is_ppo(cfg)
                                                         else {"model", "data", "il_weight"})
    if not isinstance(ckpt, dict) or needs - set(ckpt):
        raise UsageError(f"{path} is not a training checkpoint (it lacks "
                         f"{', '.join(sorted(needs - set(ckpt if isinstance(ckpt, dict) else ())))}; a policy.pt?): "
                         "it cannot be resumed; start a new --out")
    if is_ppo(cfg):
        run = ppo_lib.new_run(cfg)
        run.policy.load_state_dict(ckpt["policy"])
        run.value.load_state_dict(ckpt["value"])
        run.opt.load_state_dict(ckpt["opt"])
        run.iteration, run.sim_steps, run.metrics = ckpt["iteration"], ckpt["sim_steps"], ckpt["metrics"]
        run.return_scale = ppo_lib.ReturnScale(**ckpt["return_scale"])
        run.rng = rlil.Run.restore_rngs(ckpt["rng"])
        return run
    policy, model = ModularPolicy(cfg.gnn), ModularModel(cfg.gnn)
    policy.load_state_dict(ckpt["policy"])
    model.load_state_dict(ckpt["model"])
    data = {d: rlil.Trajectories(d, v["states"], v["actions"]) for d, v in ckpt["data"].items()}
    return rlil.Run(cfg, policy, model, data, ckpt["il_weight"], rlil.Run.restore_rngs(ckpt["rng"]),
                    ckpt["iteration"], ckpt["metrics"], ckpt.get("kept_return"))


def save_rollouts(out: Path, run) -> None:
    """rollout.gif: the final policy on each training design (one file per extra design)."""
    for k, design in enumerate(run.cfg.train):
        result = rlil.evaluate_policy(policy_to_evaluate(run.cfg, run.policy), design, run.cfg,
                                      rlil.eval_seed(run.cfg))
        name = "rollout.gif" if k == 0 else f"rollout_{sim2d.design_name(design)}.gif"
        atomic_write(out / name, lambda p: sim2d.save_gif(design, result.states[0], p, every=2))


# ----------------------------------------------------------------------------
# The run folder, a saved policy
# ----------------------------------------------------------------------------
LOCK = ".lock"          # in a run folder: locked (fcntl.flock) by the one process writing it


def hold(lock, what, holder: str, elsewhere: str) -> None:
    """Take the exclusive flock on the open file `lock` without waiting and write "holder (pid N)"
    into it; if another process has it, close `lock` and raise a UsageError naming that process."""
    try:
        fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        lock.seek(0)
        other = lock.read().strip() or "another process"
        lock.close()
        raise UsageError(f"{what} is being written by {other}: wait for it to end, or {elsewhere}")
    lock.truncate(0)
    lock.write(f"{holder} (pid {os.getpid()})\n")
    lock.flush()


def claim_run_dir(out: Path):
    """Hold the run folder `out` (made if missing) for this process alone: an exclusive lock on
    out/.lock, taken atomically and let go when the file is closed or the process ends, however it
    ends.  A second writer, at whatever moment it starts, gets a UsageError naming the holder.
    Returns (the open lock file: close it to let go, whether this call made the folder)."""
    if out.exists() and not out.is_dir():
        raise UsageError(f"--out {out} is a file, not a directory: name a new or existing run directory")
    created = not out.exists()
    try:
        out.mkdir(parents=True, exist_ok=True)
        lock = open(out / LOCK, "a+")
    except BaseException as e:               # OSError, or a signal while making it
        if created and out.is_dir():
            shutil.rmtree(out, ignore_errors=True)
        if not isinstance(e, OSError):
            raise
        raise UsageError(f"cannot write the run directory {out} ({e.strerror or type(e).__name__}): "
                         "name a directory you can write with --out")
    try:
        hold(lock, out, "train.py", "name another --out")
    except BaseException:                 # a signal (or a full disk) while claiming: no folder made here is left
        if created and not lock.closed:   # ... unless another process holds it by now
            try:
                fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
                shutil.rmtree(out, ignore_errors=True)
            except OSError:
                pass
        lock.close()
        raise
    return lock, created


def prepare_run_dir(out: Path, resume: bool, force: bool) -> None:
    """Refuse a claimed folder that already holds a run unless `resume` or `force`; `force`
    removes its outputs."""
    existing = [f for f in OUTPUTS if (out / f).exists()]
    if existing and not (resume or force):
        raise UsageError(f"{out} already holds a run ({', '.join(existing)}): "
                         "use --resume to continue it or --force to start afresh")
    if force:
        for f in existing:
            (out / f).unlink()


class WriteError(Exception):
    """A run's file could not be written (a full disk, an I/O error): one line, then how to resume."""


def write_or_say(path: Path, write) -> None:
    """write(), any OSError (or torch's RuntimeError from a failed write) as a WriteError naming `path`."""
    try:
        write()
    except (OSError, RuntimeError) as e:
        reason = e.strerror if isinstance(e, OSError) and e.strerror else str(e).splitlines()[0][:120]
        raise WriteError(f"cannot write {path} ({reason})") from e


OUTPUT_LOCKS = Path(tempfile.gettempdir()) / f"modular-rlil-locks-{os.getuid()}"
_claimed: dict[str, object] = {}    # the output files this process holds: resolved path -> open lock file


def claim_output_file(path, suffix: str, flag: str, force: bool) -> None:
    """Before any work: `path` (None: nothing asked) must end in `suffix`, sit in an existing folder
    this process can write, and not be a folder or (without `force`) an existing file.  Then the
    file is this process's until it ends, as claim_run_dir holds a run folder: a second process
    naming it, at whatever moment it starts, gets a UsageError naming the holder.  The lock is an
    flock on a file in OUTPUT_LOCKS named after the path, so nothing is left beside the output."""
    if path is None:
        return
    path = Path(path)
    if path.suffix.lower() != suffix:
        raise UsageError(f"{flag} {path}: name a {suffix} file")
    if path.is_dir():
        raise UsageError(f"{flag} {path} is a folder: name a {suffix} file in it")
    if not path.parent.resolve().is_dir():
        raise UsageError(f"{flag} {path}: no folder {path.parent}")
    try:
        tempfile.TemporaryFile(dir=path.parent).close()
    except OSError as e:
        raise UsageError(f"{flag} {path}: cannot write in {path.parent} ({e.strerror or type(e).__name__})")
    key = str(path.resolve())
    if key not in _claimed:
        try:
            OUTPUT_LOCKS.mkdir(exist_ok=True)
            lock = open(OUTPUT_LOCKS / (hashlib.sha1(key.encode()).hexdigest()[:20] + ".lock"), "a+")
        except OSError as e:
            raise UsageError(f"{flag} {path}: cannot hold it, no lock in {OUTPUT_LOCKS} "
                             f"({e.strerror or type(e).__name__}): set TMPDIR to a folder you can write")
        hold(lock, path, Path(sys.argv[0]).name, "name another file")
        _claimed[key] = lock
    if path.exists() and not force:          # read under the lock: a holder that just finished wrote it
        raise UsageError(f"{path} already exists: use --force to replace it, or name another file")


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


# ----------------------------------------------------------------------------
# A config as train.py flags: every Config field is --<name>, GNNConfig's --gnn-<name>
# ----------------------------------------------------------------------------
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


