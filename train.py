"""Command line for Algorithm 1: train, resume, evaluate, plot.

Paper: Whitman & Choset, "Learning Modular Robot Locomotion from
Demonstrations", Algorithm 1 (run by modular_rlil_minimal.py) and Sec. IV
(distance in 200 control steps).  CPU, about 5 minutes:

    python train.py --train leg_none_wheel --demos hexapod car     # RL+IL
    python train.py --train leg_none_wheel                         # plain RL baseline
    python train.py --eval runs/leg_none_wheel-hexapod_car-seed0 --design hexapod --gif h.gif

A run directory holds metrics.json, metrics.csv, curve.png, policy.pt (config
inside), checkpoint.pt (everything a resume needs) and rollout.gif.  An existing
run is never overwritten: --resume continues it, --force starts afresh.
"""
from __future__ import annotations

import csv
import dataclasses
import json
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

import modular_rlil_minimal as rlil
import sim2d
from gnn import GNNConfig, ModularModel, ModularPolicy

OUTPUTS = ("metrics.json", "metrics.csv", "curve.png", "policy.pt", "checkpoint.pt", "rollout.gif")
THREADS = 2   # torch threads: the 2-core machine the budget is measured on


class UsageError(Exception):
    """Bad input: reported as one line with exit status 2."""


# ----------------------------------------------------------------------------
# Small helpers: run names, atomic writes, config round trip
# ----------------------------------------------------------------------------
def run_name(cfg: rlil.Config) -> str:
    train = "+".join(sim2d.design_name(sim2d.parse_design(d)) for d in cfg.train)
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


def config_to_dict(cfg: rlil.Config) -> dict:
    return dataclasses.asdict(cfg)


def config_from_dict(d: dict) -> rlil.Config:
    d = dict(d)
    d["gnn"] = GNNConfig(**d["gnn"])
    d["train"], d["demos"] = tuple(d["train"]), tuple(d["demos"])
    return rlil.Config(**d)


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


def save_curve(out: Path, cfg: rlil.Config, metrics: list[dict]) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    it = [m["iteration"] for m in metrics]
    fig, ax = plt.subplots(figsize=(6, 4), dpi=100)
    colour = "tab:blue" if cfg.demos else "tab:red"
    ax.plot(it, [m["distance_m"] for m in metrics], "o-", color=colour,
            label=("RL+IL" if cfg.demos else "RL") + f" (seed {cfg.seed})")
    ax.fill_between(it, [m["distance_min_m"] for m in metrics], [m["distance_max_m"] for m in metrics],
                    color=colour, alpha=0.2, label="min-max over starts")
    ax.set_xlabel("iteration")
    ax.set_ylabel(f"distance in {cfg.eval_steps} steps (m)")
    ax.set_title(run_name(cfg))
    ax.set_xticks(it)
    ax.legend()
    ax.grid(alpha=0.3)
    fig.tight_layout()
    atomic_write(out / "curve.png", lambda p: fig.savefig(p, format="png"))
    plt.close(fig)


def save_checkpoint(out: Path, state: rlil.RunState) -> None:
    """policy.pt (policy + config, for --eval) and checkpoint.pt (everything, for --resume)."""
    cfg = config_to_dict(state.cfg)
    atomic_write(out / "policy.pt", lambda p: torch.save(
        {"config": cfg, "policy": state.policy.state_dict(), "iteration": state.iteration}, p))
    atomic_write(out / "checkpoint.pt", lambda p: torch.save({
        "config": cfg, "policy": state.policy.state_dict(), "model": state.model.state_dict(),
        "data": {d: {"states": t.states, "actions": t.actions} for d, t in state.data.items()},
        "il_weight": state.il_weight, "iteration": state.iteration,
        "metrics": state.metrics, "rng": state.rng_state()}, p))


def load_checkpoint(path: Path) -> dict:
    if not path.is_file():
        raise UsageError(f"no checkpoint at {path}: give a run directory written by train.py")
    try:
        return torch.load(path, weights_only=False)
    except Exception as e:   # any unreadable file: truncated, not a torch file, ...
        raise UsageError(f"cannot read checkpoint {path} ({type(e).__name__}): the file is corrupt or not from train.py")


def restore_state(ckpt: dict, cfg: rlil.Config) -> rlil.RunState:
    policy, model = ModularPolicy(cfg.gnn), ModularModel(cfg.gnn)
    policy.load_state_dict(ckpt["policy"])
    model.load_state_dict(ckpt["model"])
    data = {d: rlil.Trajectories(d, v["states"], v["actions"]) for d, v in ckpt["data"].items()}
    state = rlil.RunState(cfg, policy, model, data, ckpt["il_weight"], ckpt["iteration"],
                          ckpt["metrics"])
    state.set_rng_state(ckpt["rng"])
    return state


def save_rollouts(out: Path, state: rlil.RunState) -> None:
    """rollout.gif: the final policy on each training design (one file per extra design)."""
    for k, design in enumerate(state.data):
        result = rlil.evaluate_policy(state.policy, design, state.cfg, rlil.eval_seed(state.cfg))
        name = "rollout.gif" if k == 0 else f"rollout_{sim2d.design_name(design)}.gif"
        atomic_write(out / name, lambda p: sim2d.save_gif(design, result["states"][:, 0], p, every=2))


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


def train(cfg: rlil.Config, out: Path, resume: bool = False, force: bool = False, log=None,
          cache_dir=rlil.demo_lib.DEFAULT_CACHE_DIR) -> list[dict]:
    """Run (or continue) Algorithm 1 with every output written after each iteration."""
    log = log or rlil.ProgressLog()
    cfg = dataclasses.replace(cfg, train=tuple(sim2d.parse_design(d) for d in cfg.train),
                              demos=tuple(sim2d.parse_design(d) for d in cfg.demos))
    resuming = resume and (out / "checkpoint.pt").exists()
    prepare_run_dir(out, resume, force and not resuming)
    demo_data = rlil.load_demos(cfg, cache_dir)
    if demo_data:
        log("demos: " + ", ".join(f"{sim2d.design_name(d)} {len(v.actions)} x {v.actions.shape[1]}"
                                   for d, v in demo_data.items()))
    if resuming:
        ckpt = load_checkpoint(out / "checkpoint.pt")
        saved = config_from_dict(ckpt["config"])
        if dataclasses.replace(saved, iters=cfg.iters) != cfg:
            raise UsageError(f"--resume with a different configuration than {out}'s: "
                             "only --iters may change (start a new --out for other settings)")
        state = restore_state(ckpt, cfg)
        log(f"resuming {out} after iteration {state.iteration}")
    else:
        state = rlil.start(cfg, demo_data, log)
        save_checkpoint(out, state)
        save_metrics(out, cfg, state.metrics)
    log(f"iteration 0: {state.metrics[0]['distance_m']:.2f} m in {cfg.eval_steps} steps")
    durations = []
    while state.iteration < cfg.iters:
        t0 = time.perf_counter()
        rlil.iterate(state, demo_data, log)
        save_checkpoint(out, state)
        save_metrics(out, cfg, state.metrics)
        save_curve(out, cfg, state.metrics)
        durations.append(time.perf_counter() - t0)
        left = (cfg.iters - state.iteration) * np.mean(durations)
        log(f"iteration {state.iteration}/{cfg.iters} done; about {left:.0f} s left")
    save_curve(out, cfg, state.metrics)
    save_rollouts(out, state)
    dist = " ".join(f"{m['distance_m']:.2f}" for m in state.metrics)
    log(f"done: distance per iteration (m) {dist}; outputs in {out}")
    return state.metrics


def evaluate_run(run_dir: Path, design: str, gif: str | None = None) -> float:
    """Zero-shot or not: the saved policy on any design, distance in 200 steps from the run's
    evaluation starts."""
    ckpt = load_checkpoint(run_dir / "policy.pt")
    cfg = config_from_dict(ckpt["config"])
    policy = ModularPolicy(cfg.gnn)
    policy.load_state_dict(ckpt["policy"])
    graph = sim2d.design_graph(design)
    result = rlil.evaluate_policy(policy, graph.code, cfg, rlil.eval_seed(cfg))
    d = result["distance_m"]
    print(f"policy {run_dir} (iteration {ckpt['iteration']}) on {graph.name} ({graph.code}): "
          f"{len(d)} starts, min {d.min():.2f} m, max {d.max():.2f} m, flipped {int(result['flipped'].sum())}")
    if gif:
        sim2d.save_gif(graph, result["states"][:, 0], gif, every=2)
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


def figure3_runs(out: Path, seeds: int, iters: int) -> list[dict]:
    """One entry per run of the sweep: its panel, method, seed, directory and train.py arguments."""
    runs = []
    for panel, (design, demos) in PANELS.items():
        for method, demo_list in (("RL+IL", demos), ("RL", ())):
            for seed in range(seeds):
                cfg = rlil.Config(train=(sim2d.parse_design(design),),
                                  demos=tuple(sim2d.parse_design(d) for d in demo_list), seed=seed, iters=iters)
                args = ["--train", design, "--seed", str(seed), "--iters", str(iters)]
                args += ["--demos", *demo_list] if demo_list else []
                runs.append({"panel": panel, "train": design, "demos": "+".join(demos), "method": method,
                             "seed": seed, "dir": out / run_name(cfg), "args": args})
    return runs


def finished_iterations(run_dir: Path) -> int:
    try:
        return len(json.loads((run_dir / "metrics.json").read_text())["iterations"]) - 1
    except (OSError, ValueError, KeyError):
        return -1


def figure3(out: Path, seeds: int, iters: int, jobs: int, budget: list[str] = (), log=None) -> None:
    """Run (or reuse) every run of the sweep as its own train.py process, then plot and tabulate.

    Each run is a normal run directory under `out`, so a sweep resumes (finished
    runs are reused, interrupted ones continue) and its runs can be spread over
    machines by any scheduler and merged into one `out` before plotting.
    """
    import subprocess
    from concurrent.futures import ThreadPoolExecutor, as_completed

    log = log or rlil.ProgressLog()
    t0 = time.perf_counter()
    out.mkdir(parents=True, exist_ok=True)
    runs = figure3_runs(out, seeds, iters)
    todo = [r for r in runs if finished_iterations(r["dir"]) < iters]
    log(f"figure 3: {len(runs)} runs, {len(runs) - len(todo)} already finished, {jobs} at a time")
    threads = 1 if jobs > 1 else THREADS

    def launch(run):
        cmd = [sys.executable, str(Path(__file__).resolve()), *run["args"], *budget, "--out", str(run["dir"]),
               "--threads", str(threads)]
        if (run["dir"] / "checkpoint.pt").exists():
            cmd.append("--resume")
        run["dir"].mkdir(parents=True, exist_ok=True)
        with open(run["dir"] / "train.log", "a") as f:
            return subprocess.run(cmd, stdout=f, stderr=subprocess.STDOUT).returncode

    with ThreadPoolExecutor(max_workers=jobs) as pool:
        futures = {pool.submit(launch, r): r for r in todo}
        for done, future in enumerate(as_completed(futures), 1):
            r = futures[future]
            status = "ok" if future.result() == 0 else f"FAILED (see {r['dir'] / 'train.log'})"
            elapsed = time.perf_counter() - t0
            log(f"run {done}/{len(todo)} {r['dir'].name}: {status}; about "
                f"{elapsed / done * (len(todo) - done):.0f} s left")
    rows = figure3_rows(runs)
    write_figure3(out, rows, iters)
    summary = summarize_figure3(rows)
    atomic_write(out / "figure3.md", lambda p: Path(p).write_text(summary))
    print(summary)
    log(f"wrote {out / 'figure3.png'}, {out / 'figure3.csv'} and {out / 'figure3.md'}")


def figure3_rows(runs: list[dict]) -> list[dict]:
    """The CSV rows: panel,train,demos,method,seed,iteration,distance_m of every finished iteration."""
    rows = []
    for r in runs:
        try:
            metrics = json.loads((r["dir"] / "metrics.json").read_text())["iterations"]
        except (OSError, ValueError, KeyError):
            continue
        rows += [{"panel": r["panel"], "train": r["train"], "demos": r["demos"], "method": r["method"],
                  "seed": r["seed"], "iteration": m["iteration"], "distance_m": m["distance_m"]} for m in metrics]
    return rows


def converged_at(curve: dict, threshold: float):
    """First iteration whose distance reaches `threshold`, or None."""
    return next((i for i in sorted(curve) if curve[i] >= threshold), None)


def summarize_figure3(rows: list[dict]) -> str:
    """Markdown table per panel and method: iterations to converge, final distance, spread.

    Converged = the first iteration whose mean over seeds reaches 90 % of the
    best final mean of either method in that panel (per seed: of that seed's curve).
    """
    lines = ["| panel | method | converged at (mean curve) | per seed | final mean (m) | final min-max (m) |",
             "|---|---|---|---|---|---|"]
    for panel, (design, demos) in PANELS.items():
        runs = {}                                           # method -> seed -> iteration -> distance
        for r in rows:
            if r["panel"] == panel:
                runs.setdefault(r["method"], {}).setdefault(r["seed"], {})[r["iteration"]] = r["distance_m"]
        if not runs:
            continue
        last = min(max(c) for seeds in runs.values() for c in seeds.values())
        mean = {m: {i: np.mean([c[i] for c in seeds.values() if i in c]) for i in range(last + 1)}
                for m, seeds in runs.items()}
        threshold = 0.9 * max(curve[last] for curve in mean.values())
        for method in ("RL+IL", "RL"):
            if method not in runs:
                continue
            finals = [c[last] for c in runs[method].values()]
            per_seed = [converged_at(c, threshold) for c in runs[method].values()]
            fmt = lambda i: "not converged" if i is None else str(i)          # noqa: E731
            lines.append(f"| ({panel}) {design} ({' + '.join(demos)} demos) | {method} | "
                         f"{fmt(converged_at(mean[method], threshold))} | {', '.join(map(fmt, per_seed))} | "
                         f"{np.mean(finals):.2f} | {min(finals):.2f} - {max(finals):.2f} |")
    return "\n".join(lines) + "\n"


def write_figure3(out: Path, rows: list[dict], iters: int) -> None:
    """figure3.csv and figure3.png: mean over seeds as a line, min-max as a band."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    def write_csv(p):
        with open(p, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=["panel", "train", "demos", "method", "seed", "iteration", "distance_m"])
            w.writeheader()
            w.writerows(rows)
    atomic_write(out / "figure3.csv", write_csv)
    fig, axes = plt.subplots(1, 4, figsize=(16, 3.8), dpi=100, sharey=True)
    for ax, (panel, (design, demos)) in zip(axes, PANELS.items()):
        for method, colour in (("RL+IL", "tab:blue"), ("RL", "tab:red")):
            table = {}
            for row in rows:
                if row["panel"] == panel and row["method"] == method:
                    table.setdefault(row["iteration"], []).append(row["distance_m"])
            if not table:
                continue
            it = sorted(table)
            ax.plot(it, [np.mean(table[i]) for i in it], "o-", color=colour,
                    label=f"{method} ({len(table[it[0]])} seeds)")
            ax.fill_between(it, [min(table[i]) for i in it], [max(table[i]) for i in it], color=colour, alpha=0.2)
        ax.set_title(f"({panel}) {design}, demos: {' + '.join(demos)}", fontsize=10)
        ax.set_xlabel("iteration")
        ax.set_xticks(range(iters + 1))
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="lower right")
    axes[0].set_ylabel("distance in 200 steps (m)")
    fig.tight_layout()
    atomic_write(out / "figure3.png", lambda p: fig.savefig(p, format="png"))
    plt.close(fig)


BUDGET = {   # Config fields exposed on the command line
    "policy_steps": "K, policy gradient steps per iteration",
    "horizon": "T, model roll-out steps",
    "batch": "N_batch, initial states per policy step",
    "random_episodes": "random-action episodes of 100 steps per training design",
    "policy_episodes": "policy episodes per iteration (x2: without and with noise)",
    "model_steps": "model Adam steps at iteration 1",
    "finetune_steps": "model Adam steps at later iterations",
    "bc_steps": "behavioural-cloning steps (with --demos)",
    "demo_episodes": "demonstration episodes per demo design",
    "eval_episodes": "perturbed starts per evaluation",
    "il_weight": "lambda at iteration 1 (with --demos)",
}


def build_parser() -> sim2d.CliParser:
    p = sim2d.CliParser(description="Modular RL+IL (Algorithm 1) on the planar world.")
    p.add_argument("--train", nargs="+", metavar="DESIGN", help="design(s) to train (d_train)")
    p.add_argument("--demos", nargs="*", default=[], metavar="DESIGN", help="demonstration designs (D_demo)")
    p.add_argument("--iters", type=int, default=5, help="iterations of Algorithm 1 (default 5)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", help="run directory (default runs/<train>-<demos or rl>-seed<S>)")
    p.add_argument("--resume", action="store_true", help="continue an existing run after its last iteration")
    p.add_argument("--force", action="store_true", help="start afresh, replacing an existing run's outputs")
    p.add_argument("--eval", metavar="RUN_DIR", help="evaluate a saved policy (with --design)")
    p.add_argument("--design", help="design for --eval (any of the 728, trained on or not)")
    p.add_argument("--gif", help="with --eval: write an animation of the first start")
    p.add_argument("--threads", type=int, default=THREADS, help=f"torch threads (default {THREADS})")
    p.add_argument("--figure3", action="store_true",
                   help="run the paper's Figure 3 sweep: 4 panels x {RL, RL+IL} x seeds")
    p.add_argument("--seeds", type=int, default=3, help="with --figure3: seeds per condition (default 3)")
    p.add_argument("--jobs", type=int, default=2, help="with --figure3: runs in parallel processes (default 2)")
    budget = p.add_argument_group("budget (defaults: the 5-minute CPU run)")
    defaults = rlil.Config()
    for name, help_ in BUDGET.items():
        kind = type(getattr(defaults, name))
        budget.add_argument("--" + name.replace("_", "-"), type=kind, default=getattr(defaults, name),
                            help=f"{help_} (default {getattr(defaults, name)})")
    return p


def budget_from_args(args) -> dict:
    """The budget flags, checked: counts positive (--bc-steps may be 0), lambda not negative."""
    budget = {k: getattr(args, k) for k in BUDGET}
    for k, v in budget.items():
        if v < (0 if k in ("bc_steps", "il_weight") else 1):
            raise UsageError(f"--{k.replace('_', '-')} must be {'non-negative' if k in ('bc_steps', 'il_weight') else 'a positive integer'}, got {v}")
    return budget


def config_from_args(args) -> rlil.Config:
    try:
        train = tuple(sim2d.parse_design(d) for d in args.train)
        demos = tuple(sim2d.parse_design(d) for d in args.demos)
    except ValueError as e:
        raise UsageError(str(e))
    if args.iters < 1:
        raise UsageError(f"--iters must be a positive integer, got {args.iters}")
    return rlil.Config(train=train, demos=demos, seed=args.seed, iters=args.iters, **budget_from_args(args))


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        if args.threads < 1:
            raise UsageError(f"--threads must be a positive integer, got {args.threads}")
        torch.set_num_threads(args.threads)
        if args.figure3:
            if args.seeds < 1 or args.jobs < 1 or args.iters < 1:
                raise UsageError("--seeds, --jobs and --iters must be positive integers")
            budget = [x for k, v in budget_from_args(args).items() for x in ("--" + k.replace("_", "-"), str(v))]
            figure3(Path(args.out or "runs/figure3"), args.seeds, args.iters, args.jobs, budget)
            return 0
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
