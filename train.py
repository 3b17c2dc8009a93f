"""Command line for Algorithm 1 and the PPO baseline: train, resume, evaluate, plot.

Paper: Whitman & Choset, "Learning Modular Robot Locomotion from
Demonstrations", Algorithm 1 (run by modular_rlil_minimal.py) and Sec. IV
(distance in 200 control steps); the model-free baseline PPO (ppo_minimal.py).
CPU, about 5 minutes:

    python train.py --train leg_none_wheel --demos hexapod car     # RL+IL
    python train.py --train leg_none_wheel                         # plain RL baseline
    python train.py --train car --preset tiny                      # class demo, about 12 s
    python train.py --train hexapod --method ppo                   # PPO, 2 M simulator steps
    python train.py --eval runs/leg_none_wheel-hexapod_car-seed0 --design hexapod --gif h.gif
    python train.py --sample-efficiency                            # RL, RL+IL and PPO per simulator step

A run directory holds metrics.json, metrics.csv, curve.png, policy.pt (config
inside), checkpoint.pt (everything a resume needs) and rollout.gif.  An existing
run is never overwritten: --resume continues it, --force starts afresh.
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
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

import modular_rlil_minimal as rlil
import ppo_minimal as ppo_lib
import sim2d
from gnn import GNNConfig, ModularPolicy

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
    train = "+".join(sim2d.design_name(sim2d.parse_design(d)) for d in cfg.train)
    if is_ppo(cfg):
        return f"{train}-ppo-seed{cfg.seed}"
    demos = "_".join(sim2d.design_name(sim2d.parse_design(d)) for d in cfg.demos) or "rl"
    return f"{train}-{demos}-seed{cfg.seed}"


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
    """The library versions a run's numbers depend on (with Config.threads)."""
    import pymunk
    return {"torch": torch.__version__, "numpy": np.__version__, "pymunk": pymunk.version,
            "python": sys.version.split()[0]}


def config_to_dict(cfg) -> dict:
    """The config as JSON-able dict, with the library versions under "versions" and
    "method": "ppo" for a PPO run (Algorithm 1's runs have no "method")."""
    return {**dataclasses.asdict(cfg), **({"method": "ppo"} if is_ppo(cfg) else {}), "versions": versions()}


def config_from_dict(d: dict):
    d = {k: v for k, v in d.items() if k not in ("versions", "method")}
    d["gnn"] = GNNConfig(**d["gnn"])
    d["train"] = tuple(d["train"])
    if "env_steps" in d:                                  # written with "method": "ppo"
        return ppo_lib.PPOConfig(**d)
    d["demos"] = tuple(d["demos"])
    return rlil.Config(**d)


def method_of(cfg) -> str:
    return "PPO" if is_ppo(cfg) else "RL+IL" if cfg.demos else "RL"


def eval_policy(cfg, policy: ModularPolicy):
    """The policy as evaluated: PPO trained it without its memory (ppo_minimal.Memoryless)."""
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


COLOURS = {"RL+IL": "tab:blue", "RL": "tab:red", "PPO": "tab:green"}


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
        "il_weight": run.il_weight, "iteration": run.iteration,
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
    policy, model = ModularPolicy(cfg.gnn), rlil.Ensemble(cfg)
    policy.load_state_dict(ckpt["policy"])
    model.load_state_dict(ckpt["model"])
    data = {d: rlil.Trajectories(d, v["states"], v["actions"]) for d, v in ckpt["data"].items()}
    return rlil.Run(cfg, policy, model, data, ckpt["il_weight"], rlil.Run.rng_from_state(ckpt["rng"]),
                    ckpt["iteration"], ckpt["metrics"])


def save_rollouts(out: Path, run) -> None:
    """rollout.gif: the final policy on each training design (one file per extra design)."""
    for k, design in enumerate(run.cfg.train):
        result = rlil.evaluate_policy(eval_policy(run.cfg, run.policy), design, run.cfg, rlil.eval_seed(run.cfg))
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
    if force:
        for f in existing:
            (out / f).unlink()
    out.mkdir(parents=True, exist_ok=True)


def train(cfg, out: Path, resume: bool = False, force: bool = False, log=None,
          cache_dir=rlil.demo_lib.DEFAULT_CACHE_DIR) -> list[dict]:
    """Run (or continue) Algorithm 1 (a Config) or PPO (a PPOConfig) with every output written
    after each iteration (PPO: after each evaluation).

    Everything is checked before anything is written: a bad config or design is
    a UsageError, and a run that fails before its first checkpoint leaves no
    directory behind (one that existed before is left as it was).
    """
    log = log or rlil.ProgressLog()
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
        save_checkpoint(out, run)
        save_metrics(out, run.cfg, run.metrics)
        save_curve(out, run.cfg, run.metrics)
        if run.iteration > last["iteration"]:
            durations.append((time.perf_counter() - last["t"]) / (run.iteration - last["iteration"]))
            log(f"iteration {run.iteration}/{total} done; about "
                f"{(total - run.iteration) * np.mean(durations):.0f} s left")
        last.update(t=time.perf_counter(), iteration=run.iteration)

    try:
        if is_ppo(cfg):
            run = ppo_lib.ppo(cfg, run=run, log=log, on_evaluation=on_iteration)
        else:
            demo_data = rlil.load_demos(cfg, cache_dir)
            if demo_data:
                log("demos: " + ", ".join(f"{sim2d.design_name(d)} {len(v.actions)} x {v.actions.shape[1]}"
                                           for d, v in demo_data.items()))
            run = rlil.algorithm1(cfg, demo_data, run=run, log=log, on_iteration=on_iteration)
    except BaseException:
        if created and not (out / "checkpoint.pt").exists():
            shutil.rmtree(out, ignore_errors=True)          # nothing half-made is left behind
        raise
    save_rollouts(out, run)
    dist = " ".join(f"{m['distance_m']:.2f}" for m in run.metrics)
    log(f"done: distance per {'evaluation' if is_ppo(cfg) else 'iteration'} (m) {dist}; outputs in {out}")
    return run.metrics


def evaluate_run(run_dir: Path, design: str, gif: str | None = None) -> float:
    """Zero-shot or not: the saved policy on any design, distance in 200 steps from the run's
    evaluation starts."""
    ckpt = load_checkpoint(run_dir / "policy.pt")
    cfg = config_from_dict(ckpt["config"])
    policy = ModularPolicy(cfg.gnn)
    policy.load_state_dict(ckpt["policy"])
    graph = sim2d.design_graph(design)
    result = rlil.evaluate_policy(eval_policy(cfg, policy), graph.code, cfg, rlil.eval_seed(cfg))
    d = result.distance_m
    print(f"policy {run_dir} (iteration {ckpt['iteration']}) on {graph.name} ({graph.code}): "
          f"{len(d)} starts, min {d.min():.2f} m, max {d.max():.2f} m, flipped {int(result.flipped.sum())}")
    if gif:
        sim2d.save_gif(graph, result.states[0], gif, every=2)
        print(f"wrote {gif}")
    print(f"design={graph.code} distance_m={d.mean():.4f}")
    return float(d.mean())


# ----------------------------------------------------------------------------
# Figure 3 of the paper: four conditions, RL vs RL+IL, over seeds
# ----------------------------------------------------------------------------
PANELS = {   # panel: (trained design, demo designs), the paper's Fig. 3 (a)-(d)
    "a": ("hexapod", ("hexapod",)),
    "b": ("car", ("car",)),
    "c": ("leg_leg_wheel", ("hexapod", "car")),
    "d": ("leg_none_wheel", ("hexapod", "car")),
}


def figure3_runs(out: Path, base: rlil.Config, seeds: int, jobs: int, panels: str = "abcd") -> list[dict]:
    """One entry per run of the sweep: its panel, method, seed, directory and train.py arguments.

    Every run has `base`'s budget; design, demos and seed are the panel's, and a
    run gets one torch thread when several run at once.
    """
    runs = []
    for panel, (design, demos) in PANELS.items():
        if panel not in panels:
            continue
        for method, demo_list in (("RL+IL", demos), ("RL", ())):
            for seed in range(seeds):
                cfg = dataclasses.replace(base, train=(sim2d.parse_design(design),), seed=seed,
                                          demos=tuple(sim2d.parse_design(d) for d in demo_list),
                                          threads=1 if jobs > 1 else base.threads)
                runs.append({"panel": panel, "train": design, "demos": "+".join(demos), "method": method,
                             "seed": seed, "dir": out / run_name(cfg), "args": config_args(cfg)})
    return runs


def launch_runs(runs: list[dict], last: int, jobs: int, log, what: str) -> None:
    """Run every run of a sweep whose metrics.json has not reached iteration `last` (a run's own
    "last" if it has one) as its own train.py process, `jobs` at a time, continuing interrupted
    ones with --resume; each run's output goes to its train.log, its exit status to r["returncode"]."""
    import subprocess
    from concurrent.futures import ThreadPoolExecutor, as_completed

    t0 = time.perf_counter()
    todo = [r for r in runs if last_iteration(r["dir"]) < r.get("last", last)]
    log(f"{what}: {len(runs)} runs, {len(runs) - len(todo)} already finished, {jobs} at a time")

    def launch(run):
        cmd = [sys.executable, str(Path(__file__).resolve()), *run["args"], "--out", str(run["dir"])]
        if (run["dir"] / "checkpoint.pt").exists():
            cmd.append("--resume")
        run["dir"].mkdir(parents=True, exist_ok=True)
        with open(run["dir"] / "train.log", "a") as f:
            return subprocess.run(cmd, stdout=f, stderr=subprocess.STDOUT).returncode

    with ThreadPoolExecutor(max_workers=jobs) as pool:
        futures = {pool.submit(launch, r): r for r in todo}
        for done, future in enumerate(as_completed(futures), 1):
            r = futures[future]
            r["returncode"] = future.result()
            status = "ok" if r["returncode"] == 0 else f"FAILED (see {r['dir'] / 'train.log'})"
            elapsed = time.perf_counter() - t0
            log(f"run {done}/{len(todo)} {r['dir'].name}: {status}; about "
                f"{elapsed / done * (len(todo) - done):.0f} s left")


def last_iteration(run_dir: Path) -> int:
    """The iteration of the last row of a run's metrics.json; -1 when it has none."""
    try:
        return json.loads((run_dir / "metrics.json").read_text())["iterations"][-1]["iteration"]
    except (OSError, ValueError, KeyError, IndexError):
        return -1


def finished_iterations(run_dir: Path) -> int:
    """Iterations after iteration 0 in a run's metrics.json; -1 when it has none."""
    try:
        return len(json.loads((run_dir / "metrics.json").read_text())["iterations"]) - 1
    except (OSError, ValueError, KeyError):
        return -1


def figure3(out: Path, base: rlil.Config, seeds: int, jobs: int, log=None, panels: str = "abcd") -> list[str]:
    """Run (or reuse) every run of the sweep as its own train.py process, then plot and tabulate.

    Each run is a normal run directory under `out`, so a sweep resumes (finished
    runs are reused, interrupted ones continue) and its runs can be spread over
    machines by any scheduler and merged into one `out` before plotting.
    Returns the runs that failed or did not finish all `base.iters` iterations,
    one line each; they are named in the summary and on the plot too.
    """
    log = log or rlil.ProgressLog()
    out.mkdir(parents=True, exist_ok=True)
    runs = figure3_runs(out, base, seeds, jobs, panels)
    launch_runs(runs, base.iters, jobs, log, "figure 3")
    problems = []
    for r in runs:
        n = finished_iterations(r["dir"])
        if n < base.iters or r.get("returncode", 0) != 0:
            why = f"exit status {r['returncode']}, " if r.get("returncode", 0) != 0 else ""
            problems.append(f"({r['panel']}) {r['method']} seed {r['seed']}: {why}{max(n, 0)} of {base.iters} "
                            f"iterations ({r['dir']})")
    rows = figure3_rows(runs)
    write_figure3(out, rows, base.iters, problems, panels)
    summary = summarize_figure3(rows, base.iters, seeds, problems, panels)
    atomic_write(out / "figure3.md", lambda p: Path(p).write_text(summary))
    print(summary)
    log(f"wrote {out / 'figure3.png'}, {out / 'figure3.csv'} and {out / 'figure3.md'}"
        + (f"; {len(problems)} runs missing or failed" if problems else ""))
    return problems


FIGURE3_COLUMNS = ["panel", "train", "demos", "method", "seed", "iteration", "distance_m",
                   "model_progress_m", "sim_progress_m"]


def figure3_rows(runs: list[dict]) -> list[dict]:
    """The CSV rows (FIGURE3_COLUMNS) of every finished iteration; the model's and the simulator's
    progress over the first T steps are empty at iteration 0 (no model yet)."""
    rows = []
    for r in runs:
        try:
            metrics = json.loads((r["dir"] / "metrics.json").read_text())["iterations"]
        except (OSError, ValueError, KeyError):
            continue
        rows += [{"panel": r["panel"], "train": r["train"], "demos": r["demos"], "method": r["method"],
                  "seed": r["seed"], "iteration": m["iteration"], "distance_m": m["distance_m"],
                  "model_progress_m": m.get("model_progress_m"), "sim_progress_m": m.get("sim_progress_m")}
                 for m in metrics]
    return rows


def converged_at(curve: dict, threshold: float):
    """First iteration whose distance reaches `threshold`, or None."""
    return next((i for i in sorted(curve) if curve[i] >= threshold), None)


def summarize_figure3(rows: list[dict], iters: int, seeds: int, problems: list[str] = (), panels: str = "abcd") -> str:
    """Markdown table per panel and method: iterations to converge, final distance, spread,
    the largest drop of a seed between consecutive iterations, and model exploitation.

    Converged = the first iteration whose mean over seeds reaches 90 % of the
    best mean at iteration `iters` of either method in that panel (per seed: of
    that seed's curve).  Means are over the seeds that reached an iteration;
    the "seeds" column says how many reached the last one.  Spread = max - min
    over seeds, averaged over iterations 1..iters.  Largest drop = the largest
    fall of one seed from one iteration to the next after iteration 1.
    Exploitation = the largest, over iterations >= 1, of the mean over seeds of
    |model_progress_m - sim_progress_m| (the first T steps).
    """
    lines = ["| panel | method | seeds | converged at (mean curve) | per seed | final mean (m) | final min-max (m) "
             "| spread (m) | largest drop after it. 1 (m) | exploitation (m) |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for panel, (design, demos) in PANELS.items():
        if panel not in panels:
            continue
        runs, gaps = {}, {}                       # method -> seed -> iteration -> distance / |model - sim|
        for r in rows:
            if r["panel"] == panel:
                runs.setdefault(r["method"], {}).setdefault(r["seed"], {})[r["iteration"]] = r["distance_m"]
                if r.get("model_progress_m") is not None and r.get("sim_progress_m") is not None:
                    gaps.setdefault(r["method"], {}).setdefault(r["iteration"], []).append(
                        abs(r["model_progress_m"] - r["sim_progress_m"]))
        mean = {m: {i: np.mean([c[i] for c in curves.values() if i in c])
                    for i in range(iters + 1) if any(i in c for c in curves.values())}
                for m, curves in runs.items()}
        finals = [curve[iters] for curve in mean.values() if iters in curve]
        threshold = 0.9 * max(finals) if finals else float("inf")
        fmt = lambda i: "not converged" if i is None else str(i)          # noqa: E731
        for method in ("RL+IL", "RL"):
            curves = runs.get(method, {})
            final = [c[iters] for c in curves.values() if iters in c]
            head = f"| ({panel}) {design} ({' + '.join(demos)} demos) | {method} | {len(final)} of {seeds} |"
            if not final:
                lines.append(head + " no run finished | | | | | | |")
                continue
            per_seed = [converged_at(c, threshold) for c in curves.values()]
            spread = np.mean([np.ptp([c[i] for c in curves.values() if i in c]) for i in range(1, iters + 1)])
            drops = [c[i] - c[i + 1] for c in curves.values() for i in range(1, iters) if i + 1 in c]
            gap = max((np.mean(v) for v in gaps.get(method, {}).values()), default=float("nan"))
            lines.append(f"{head} {fmt(converged_at(mean[method], threshold))} | {', '.join(map(fmt, per_seed))} | "
                         f"{np.mean(final):.2f} | {min(final):.2f} - {max(final):.2f} | {spread:.2f} | "
                         f"{max(drops, default=0.0):.2f} | {gap:.2f} |")
    if problems:
        lines += ["", "Missing or failed runs (left out of the means above):"] + [f"- {p}" for p in problems]
    return "\n".join(lines) + "\n"


def write_rows_csv(path: Path, columns: list[str], rows: list[dict]) -> None:
    """A CSV with a header row of `columns` and one line per dict, written atomically."""
    def write(p):
        with open(p, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=columns)
            w.writeheader()
            w.writerows(rows)
    atomic_write(path, write)


def save_sweep_plot(fig, path: Path, problems: list[str]) -> None:
    """Save a sweep's figure atomically (missing or failed runs named along its foot) and close it."""
    import matplotlib.pyplot as plt
    if problems:
        fig.text(0.01, 0.01, "missing or failed: " + "; ".join(p.split(" (")[0] for p in problems),
                 fontsize=8, color="tab:red", wrap=True)
    fig.tight_layout(rect=(0, 0.04 * bool(problems), 1, 1))
    atomic_write(path, lambda p: fig.savefig(p, format="png"))
    plt.close(fig)


def write_figure3(out: Path, rows: list[dict], iters: int, problems: list[str] = (), panels: str = "abcd") -> None:
    """figure3.csv and figure3.png: mean over seeds as a line, min-max as a band."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    write_rows_csv(out / "figure3.csv", FIGURE3_COLUMNS, rows)
    shown = [(p, v) for p, v in PANELS.items() if p in panels]
    fig, axes = plt.subplots(1, len(shown), figsize=(4 * len(shown), 3.8 + 0.18 * len(problems)), dpi=100,
                             sharey=True, squeeze=False)
    axes = axes[0]
    for ax, (panel, (design, demos)) in zip(axes, shown):
        for method, colour in (("RL+IL", "tab:blue"), ("RL", "tab:red")):
            table = {}
            for row in rows:
                if row["panel"] == panel and row["method"] == method:
                    table.setdefault(row["iteration"], []).append(row["distance_m"])
            if not table:
                continue
            it = sorted(table)
            counts = sorted({len(table[i]) for i in it})
            seeds = f"{counts[0]}" if len(counts) == 1 else f"{counts[0]}-{counts[-1]}"
            ax.plot(it, [np.mean(table[i]) for i in it], "o-", color=colour, label=f"{method} ({seeds} seeds)")
            ax.fill_between(it, [min(table[i]) for i in it], [max(table[i]) for i in it], color=colour, alpha=0.2)
        ax.set_title(f"({panel}) {design}, demos: {' + '.join(demos)}", fontsize=10)
        ax.set_xlabel("iteration")
        ax.set_xticks(range(iters + 1))
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="lower right")
    axes[0].set_ylabel("distance in 200 steps (m)")
    save_sweep_plot(fig, out / "figure3.png", problems)


# ----------------------------------------------------------------------------
# Sample efficiency (not in the paper): Algorithm 1 against PPO per simulator step and per second
# ----------------------------------------------------------------------------
SAMPLE_EFFICIENCY = {"hexapod": PANELS["a"][1], "leg_none_wheel": PANELS["d"][1]}   # design: Figure 3's demos
THRESHOLDS_M = (5.0, 10.0)
SAMPLE_COLUMNS = ["train", "method", "seed", "iteration", "sim_steps", "seconds", "distance_m"]


def sample_efficiency_runs(out: Path, base: rlil.Config, base_ppo: ppo_lib.PPOConfig, seeds: int,
                           jobs: int) -> list[dict]:
    """One entry per run: hexapod and leg_none_wheel x {RL+IL, RL, PPO} x seeds, with `base`'s and
    `base_ppo`'s budgets; one torch thread per run when several run at once."""
    runs = []
    for design, demos in SAMPLE_EFFICIENCY.items():
        code = (sim2d.parse_design(design),)
        for method in ("RL+IL", "RL", "PPO"):
            for seed in range(seeds):
                if method == "PPO":
                    cfg = dataclasses.replace(base_ppo, train=code, seed=seed,
                                              threads=1 if jobs > 1 else base_ppo.threads)
                else:
                    cfg = dataclasses.replace(base, train=code, seed=seed, threads=1 if jobs > 1 else base.threads,
                                              demos=tuple(sim2d.parse_design(d) for d in demos) if method == "RL+IL" else ())
                last = ppo_lib.iterations(cfg) if method == "PPO" else cfg.iters
                runs.append({"train": design, "method": method, "seed": seed, "dir": out / run_name(cfg),
                             "args": config_args(cfg), "last": last})
    return runs


def sample_efficiency_rows(runs: list[dict]) -> list[dict]:
    """The CSV rows (SAMPLE_COLUMNS) of every recorded evaluation; seconds are cumulative."""
    rows = []
    for r in runs:
        try:
            saved = json.loads((r["dir"] / "metrics.json").read_text())
        except (OSError, ValueError):
            continue
        cfg, seconds = config_from_dict(saved["config"]), 0.0
        for m in saved["iterations"]:
            seconds += m["seconds"]
            steps = m["sim_steps"] if "sim_steps" in m else rlil.sim_steps(cfg, m["iteration"])   # runs before sim_steps
            rows.append({"train": r["train"], "method": r["method"], "seed": r["seed"], "iteration": m["iteration"],
                         "sim_steps": steps, "seconds": seconds, "distance_m": m["distance_m"]})
    return rows


def mean_curve(rows: list[dict], design: str, method: str) -> list[tuple]:
    """[(sim_steps, mean seconds, [distance per seed]) per iteration] of one design and method;
    every seed evaluates at the same iterations and simulator steps."""
    table = {}
    for row in rows:
        if row["train"] == design and row["method"] == method:
            table.setdefault(row["iteration"], []).append(row)
    return [(np.mean([r["sim_steps"] for r in table[i]]), np.mean([r["seconds"] for r in table[i]]),
             [r["distance_m"] for r in table[i]]) for i in sorted(table)]


def summarize_sample_efficiency(rows: list[dict], seeds: int, problems: list[str] = ()) -> str:
    """Markdown: per design and method, the simulator steps and seconds at which the mean over seeds
    first reaches 5 m and 10 m in 200 steps, and where each ends."""
    head = " | ".join(f"{t:g} m: steps | {t:g} m: seconds" for t in THRESHOLDS_M)
    lines = [f"| design | method | seeds | {head} | final steps | final seconds | final mean (m) | final min-max (m) |",
             "|---|---|---|" + "---|" * (2 * len(THRESHOLDS_M) + 4)]
    for design in SAMPLE_EFFICIENCY:
        for method in ("RL+IL", "RL", "PPO"):
            curve = mean_curve(rows, design, method)
            if not curve:
                lines.append(f"| {design} | {method} | 0 of {seeds} |" + " |" * (2 * len(THRESHOLDS_M) + 4))
                continue
            cells = []
            for t in THRESHOLDS_M:
                hit = next(((s, sec) for s, sec, d in curve if np.mean(d) >= t), None)
                cells += [f"{hit[0]:,.0f}", f"{hit[1]:.0f}"] if hit else ["not reached", ""]
            steps, seconds, final = curve[-1]
            lines.append(f"| {design} | {method} | {len(final)} of {seeds} | {' | '.join(cells)} | {steps:,.0f} | "
                         f"{seconds:.0f} | {np.mean(final):.2f} | {min(final):.2f} - {max(final):.2f} |")
    if problems:
        lines += ["", "Missing or failed runs (left out of the means above):"] + [f"- {p}" for p in problems]
    return "\n".join(lines) + "\n"


def write_sample_efficiency(out: Path, rows: list[dict], problems: list[str] = ()) -> None:
    """sample_efficiency.csv and .png: per design, distance against simulator steps and against
    seconds (both log axes; the untrained PPO policy at 0 steps is left off), mean over seeds as a
    line, min-max as a band, the summary's thresholds as dotted lines."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib import ticker

    write_rows_csv(out / "sample_efficiency.csv", SAMPLE_COLUMNS, rows)
    fig, axes = plt.subplots(len(SAMPLE_EFFICIENCY), 2, figsize=(13, 3.8 * len(SAMPLE_EFFICIENCY)), dpi=100,
                             sharey="row", squeeze=False)
    for row_axes, (design, demos) in zip(axes, SAMPLE_EFFICIENCY.items()):
        for method, colour in COLOURS.items():
            curve = [c for c in mean_curve(rows, design, method) if c[0] > 0]
            if not curve:
                continue
            n = len(curve[-1][2])
            label = (f"{method}" + (f" ({' + '.join(demos)} demos)" if method == "RL+IL" else "")
                     + f", {n} seed{'s' * (n > 1)}")
            for ax, k in zip(row_axes, (0, 1)):
                x = [c[k] for c in curve]
                ax.plot(x, [np.mean(c[2]) for c in curve], "o-", ms=3, color=colour, label=label)
                ax.fill_between(x, [min(c[2]) for c in curve], [max(c[2]) for c in curve], color=colour, alpha=0.2)
        for ax, xlabel, unit in zip(row_axes, ("simulator steps (evaluation excluded)",
                                               "wall-clock seconds (one thread, evaluation included)"), ("", " s")):
            ax.set_xscale("log")
            ax.xaxis.set_major_formatter(ticker.FuncFormatter(                 # 1,000 and 100 s, not 10^3
                lambda v, _, u=unit: f"{v:,.0f}{u}" if v >= 1 else f"{v:g}{u}"))
            ax.xaxis.set_minor_formatter(ticker.NullFormatter())
            for t in THRESHOLDS_M:                # the summary table's thresholds
                ax.axhline(t, color="grey", lw=0.8, ls=":")
            ax.set_xlabel(xlabel)
            ax.set_title(design, fontsize=10)
            ax.grid(alpha=0.3, which="both")
        row_axes[0].set_ylabel("distance in 200 steps (m)")
        row_axes[1].legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.02, 1))    # beside the row
    save_sweep_plot(fig, out / "sample_efficiency.png", problems)


def sample_efficiency(out: Path, base: rlil.Config, base_ppo: ppo_lib.PPOConfig, seeds: int, jobs: int,
                      log=None) -> list[str]:
    """Run (or reuse) every run as its own train.py process, then plot, tabulate and summarise
    (sample_efficiency.png, .csv, .md in `out`).  Returns the runs that failed or did not finish."""
    log = log or rlil.ProgressLog()
    out.mkdir(parents=True, exist_ok=True)
    runs = sample_efficiency_runs(out, base, base_ppo, seeds, jobs)
    launch_runs(runs, 0, jobs, log, "sample efficiency")
    problems = [f"{r['train']} {r['method']} seed {r['seed']}: "
                + (f"exit status {r['returncode']}, " if r.get("returncode", 0) != 0 else "")
                + f"{max(last_iteration(r['dir']), 0)} of {r['last']} iterations ({r['dir']})"
                for r in runs if last_iteration(r["dir"]) < r["last"] or r.get("returncode", 0) != 0]
    rows = sample_efficiency_rows(runs)
    write_sample_efficiency(out, rows, problems)
    summary = summarize_sample_efficiency(rows, seeds, problems)
    atomic_write(out / "sample_efficiency.md", lambda p: Path(p).write_text(summary))
    print(summary)
    log(f"wrote {out / 'sample_efficiency.png'}, .csv and .md" + (f"; {len(problems)} runs missing or failed"
                                                                   if problems else ""))
    return problems


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
    args += ["--demos", *cfg.demos] if not is_ppo(cfg) and cfg.demos else []
    for flag, dest, f in all_flags(cfg):
        value = getattr(cfg.gnn, f.name) if dest.startswith("gnn_") else getattr(cfg, f.name)
        base = getattr(default.gnn, f.name) if dest.startswith("gnn_") else getattr(default, f.name)
        if f.name not in ("train", "demos") and value != base:
            args += [flag, str(value)]
    return args


def build_parser() -> sim2d.CliParser:
    p = sim2d.CliParser(description="Modular RL+IL (Algorithm 1) and the PPO baseline on the planar world.")
    p.add_argument("--preset", default="default", help=f"named budget the flags below override: "
                   f"{', '.join(rlil.PRESETS)} (tiny: the tests' budget, a class demo of about 12 s)")
    p.add_argument("--out", help="run directory (default runs/<train>-<demos or rl>-seed<S>)")
    p.add_argument("--resume", action="store_true", help="continue an existing run after its last iteration")
    p.add_argument("--force", action="store_true", help="start afresh, replacing an existing run's outputs")
    p.add_argument("--eval", metavar="RUN_DIR", help="evaluate a saved policy (with --design)")
    p.add_argument("--design", help="design for --eval (any of the 728, trained on or not)")
    p.add_argument("--gif", help="with --eval: write an animation of the first start")
    p.add_argument("--figure3", action="store_true",
                   help="run the paper's Figure 3 sweep: 4 panels x {RL, RL+IL} x seeds")
    p.add_argument("--seeds", type=int, default=3, help="with --figure3 or --sample-efficiency: seeds per condition (default 3)")
    p.add_argument("--jobs", type=int, default=2, help="with --figure3 or --sample-efficiency: runs in parallel processes (default 2)")
    p.add_argument("--panels", default="abcd", help="with --figure3: which panels, e.g. ad (default abcd)")
    p.add_argument("--method", choices=("rlil", "ppo"), default="rlil",
                   help="rlil: Algorithm 1 (RL+IL with --demos, else RL); ppo: the model-free baseline "
                        "(ppo_minimal.py) on the same modular policy")
    p.add_argument("--sample-efficiency", action="store_true",
                   help="run RL, RL+IL (Figure 3's demos) and PPO on hexapod and leg_none_wheel x seeds and plot "
                        "distance against simulator steps and seconds")
    group = p.add_argument_group("Algorithm 1 (modular_rlil_minimal.Config; defaults: the 5-minute CPU run)")
    default, helps = rlil.Config(), {**field_help(rlil.Config), **field_help(GNNConfig)}
    for flag, dest, f in config_flags():
        value = getattr(default.gnn, f.name) if dest.startswith("gnn_") else getattr(default, f.name)
        if isinstance(value, tuple):
            kind = dict(nargs="+" if f.name == "train" else "*", metavar="DESIGN")
        else:
            kind = dict(type=parse_bool if isinstance(value, bool) else type(value))
        group.add_argument(flag, dest=dest, default=None, help=f"{helps[f.name]} (default {value})", **kind)
    ppo_default, ppo_helps = ppo_lib.PPOConfig(), field_help(ppo_lib.PPOConfig)
    group = p.add_argument_group(
        "PPO, with --method ppo (ppo_minimal.PPOConfig)",
        "PPO also takes --train (one design), --seed, --threads (default 1), --episode-steps (T, default 200), "
        "--eval-episodes, --eval-steps and the --gnn-* flags above; --preset tiny is its tests' budget.")
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


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        if args.sample_efficiency:
            if args.seeds < 1 or args.jobs < 1:
                raise UsageError(f"--seeds and --jobs must be positive integers, got {args.seeds} and {args.jobs}")
            problems = sample_efficiency(Path(args.out or "runs/sample_efficiency"),
                                         config_from_args(args, "rlil", strict=False),
                                         config_from_args(args, "ppo", strict=False), args.seeds, args.jobs)
            return 1 if problems else 0
        if args.figure3:
            if args.seeds < 1 or args.jobs < 1:
                raise UsageError(f"--seeds and --jobs must be positive integers, got {args.seeds} and {args.jobs}")
            if not args.panels or set(args.panels) - set(PANELS):
                raise UsageError(f"--panels takes letters from abcd, got {args.panels!r}")
            problems = figure3(Path(args.out or "runs/figure3"), config_from_args(args), args.seeds, args.jobs,
                               panels=args.panels)
            return 1 if problems else 0
        if args.eval:
            if not args.design:
                raise UsageError("--eval needs --design DESIGN")
            try:
                sim2d.design_graph(args.design)
            except ValueError as e:
                raise UsageError(str(e))
            evaluate_run(Path(args.eval), args.design, args.gif)
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


if __name__ == "__main__":
    sys.exit(main())
