"""Sweeps: many train.py runs of one experiment, then one plot, one CSV and one summary table.

A sweep is a set of runs that differ only in design, demonstrations, method
and seed: the paper's Figure 3 (4 panels x {RL+IL, RL} x seeds) and the
sample-efficiency comparison (hexapod and leg_none_wheel x {RL+IL, RL, PPO,
PPO+IL} x seeds).  Each run is a normal train.py run directory under the
sweep's folder (runs/figure3/<run name>/ with metrics.json, checkpoint.pt,
...), made by its own `train.py` process, --jobs at a time, its output in its
train.log.  A finished run (its metrics.json at its last iteration) is reused,
an interrupted one continues with --resume, so a sweep that stops resumes where
it was, and its runs can be spread over machines and merged into one folder
before plotting.  The sweep then writes <name>.png, <name>.csv and <name>.md
there.  The committed tables are made from the committed CSVs by
experiments/tables.py.

    python train.py --figure3 [--seeds 3] [--jobs 2] [--panels abcd] [--out runs/figure3]
    python train.py --sample-efficiency [--seeds 3] [--jobs 2] [--env-steps N] [--out runs/sample_efficiency]
    python experiments/sweeps.py --keep-metrics SWEEP_DIR DEST   # what is committed of a sweep
"""
from __future__ import annotations

import csv
import dataclasses
import json
import shlex
import sys
import time
from pathlib import Path

import numpy as np

if __package__ in (None, ""):              # run as a script: the stage files are one folder up
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import modular_rlil_minimal as rlil                                                          # noqa: E402
import ppo_minimal as ppo_lib                                                                 # noqa: E402
import sim2d                                                                                  # noqa: E402
from experiments.run_folders import (COLOURS, UsageError, config_args, config_from_dict, is_ppo,  # noqa: E402
                                     run_name)
from experiments.stats import (area_under_curve, bootstrap_ci, interval, iterations_to_converge)  # noqa: E402
from sim2d import atomic_write                                                                # noqa: E402

ROOT = Path(__file__).resolve().parents[1]          # the repository: train.py, results/
LAUNCHERS = ("local", "ray")                        # how a sweep runs its runs (launch_runs)


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


def run_command(run: dict) -> list[str]:
    """The train.py command of one run: its arguments and directory, --resume once it has a checkpoint."""
    cmd = [sys.executable, str(ROOT / "train.py"), *run["args"], "--out", str(run["dir"])]
    return cmd + (["--resume"] if (run["dir"] / "checkpoint.pt").exists() else [])


def run_one(cmd: list[str], run_dir: str) -> int:
    """Run one train.py command, its output appended to run_dir/train.log; returns its exit status."""
    import subprocess
    Path(run_dir).mkdir(parents=True, exist_ok=True)
    with open(Path(run_dir) / "train.log", "a") as f:
        return subprocess.run(cmd, stdout=f, stderr=subprocess.STDOUT).returncode


def unfinished(runs: list[dict], last: int) -> list[dict]:
    """The runs whose metrics.json has not reached iteration `last` (a run's own "last" if it has one)."""
    return [r for r in runs if last_iteration(r["dir"]) < r.get("last", last)]


def plan_lines(runs: list[dict], last: int) -> list[str]:
    """One shell line per unfinished run, for a SLURM job array, GNU parallel or any scheduler:
    `mkdir -p DIR && python .../train.py ARGS --out DIR >> DIR/train.log 2>&1`."""
    q = shlex.quote
    return [f"mkdir -p {q(str(r['dir']))} && {' '.join(map(q, ['python', *run_command(r)[1:]]))} "
            f">> {q(str(r['dir'] / 'train.log'))} 2>&1" for r in unfinished(runs, last)]


def ray_results(todo: list[dict], jobs: int, address: str | None):
    """Yield (run, exit status) as Ray tasks finish, one task of one CPU per run's train.py command:
    on the cluster at `address`, else on a local Ray instance of `jobs` CPUs.  The workers must see
    this repository and the sweep folder at the same paths (a shared filesystem)."""
    try:
        import ray
    except ImportError:
        raise UsageError("--launcher ray needs Ray: pip install -r requirements-ray.txt")

    def task(cmd, run_dir):                       # defined here so Ray ships it by value to any worker
        return run_one(cmd, run_dir)

    started = not ray.is_initialized()
    if started:
        ray.init(address=address, num_cpus=None if address else jobs, include_dashboard=False,
                 log_to_driver=False)
    remote = ray.remote(num_cpus=1)(task)
    pending = {remote.remote(run_command(r), str(r["dir"])): r for r in todo}
    try:
        while pending:
            [ref], _ = ray.wait(list(pending), num_returns=1)
            yield pending.pop(ref), ray.get(ref)
    finally:
        if started:
            ray.shutdown()


def launch_runs(runs: list[dict], last: int, jobs: int, log, what: str, launcher: str = "local",
                ray_address: str | None = None) -> None:
    """Run every unfinished run of a sweep as its own train.py process, continuing interrupted ones
    with --resume: `jobs` at a time as local processes, or as Ray tasks (`ray_results`).  Each
    run's output goes to its train.log, its exit status to r["returncode"]."""
    from concurrent.futures import ThreadPoolExecutor, as_completed

    t0, todo = time.perf_counter(), unfinished(runs, last)
    where = f"on Ray ({ray_address or 'a local instance'})" if launcher == "ray" else f"{jobs} at a time"
    log(f"{what}: {len(runs)} runs, {len(runs) - len(todo)} already finished, {where}")

    def finished(done: int, r: dict, code: int) -> None:
        r["returncode"] = code
        status = "ok" if code == 0 else f"FAILED (see {r['dir'] / 'train.log'})"
        log(f"run {done}/{len(todo)} {r['dir'].name}: {status}; about "
            f"{(time.perf_counter() - t0) / done * (len(todo) - done):.0f} s left")

    if launcher == "ray":
        for done, (r, code) in enumerate(ray_results(todo, jobs, ray_address), 1):
            finished(done, r, code)
        return
    with ThreadPoolExecutor(max_workers=jobs) as pool:
        futures = {pool.submit(run_one, run_command(r), str(r["dir"])): r for r in todo}
        for done, future in enumerate(as_completed(futures), 1):
            finished(done, futures[future], future.result())


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


def figure3(out: Path, base: rlil.Config, seeds: int, jobs: int, log=None, panels: str = "abcd",
            launcher: str = "local", ray_address: str | None = None, collect: Path | None = None) -> list[str]:
    """Run (or reuse) every run of the sweep as its own train.py process, then plot and tabulate.

    Each run is a normal run directory under `out`, so a sweep resumes (finished
    runs are reused, interrupted ones continue) and its runs can be spread over
    machines by any scheduler (`plan_lines`) and merged into one folder.  With
    `collect`, nothing runs: the figure, CSV and summary are made from the run
    directories under `collect` that exist, and written to `out`.  Returns the
    runs that failed, are missing or did not finish all `base.iters` iterations,
    one line each; they are named in the summary and on the plot too.
    """
    log = log or rlil.ProgressLog()
    out.mkdir(parents=True, exist_ok=True)
    runs = figure3_runs(collect or out, base, seeds, jobs, panels)
    if collect is None:
        launch_runs(runs, base.iters, jobs, log, "figure 3", launcher, ray_address)
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
                   "model_progress_m", "sim_progress_m", "seconds", "cpu_capability"]


def figure3_rows(runs: list[dict]) -> list[dict]:
    """The CSV rows (FIGURE3_COLUMNS) of every finished iteration; the model's and the simulator's
    progress over the first T steps are empty at iteration 0 (no model yet)."""
    rows = []
    for r in runs:
        try:
            saved = json.loads((r["dir"] / "metrics.json").read_text())
            metrics = saved["iterations"]
        except (OSError, ValueError, KeyError):
            continue
        cpu = saved.get("config", {}).get("versions", {}).get("cpu_capability")    # None before it was recorded
        rows += [{"panel": r["panel"], "train": r["train"], "demos": r["demos"], "method": r["method"],
                  "seed": r["seed"], "iteration": m["iteration"], "distance_m": m["distance_m"],
                  "model_progress_m": m.get("model_progress_m"), "sim_progress_m": m.get("sim_progress_m"),
                  "seconds": m.get("seconds"), "cpu_capability": cpu}
                 for m in metrics]
    return rows


def panel_curves(rows: list[dict], panel: str, iters: int):
    """One panel's curves: runs (method -> seed -> iteration -> distance), gaps (method ->
    iteration -> [|model - simulator progress| per seed]), the mean curve per method, and the
    convergence threshold: 90 % of the best mean at iteration `iters` of either method."""
    runs, gaps = {}, {}
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
    return runs, gaps, mean, 0.9 * max(finals) if finals else float("inf")


def per_run(curves: tuple, iters: int) -> dict:
    """method -> {"converge": [iterations to converge per finished run], "auc": [...], "final": [...]},
    from one panel's `panel_curves` (its runs and its convergence threshold)."""
    runs, _, _, threshold = curves
    out = {}
    for method, curves in runs.items():
        done = [c for c in curves.values() if area_under_curve(c, iters) is not None]
        out[method] = {"converge": [iterations_to_converge(c, threshold, iters) for c in done],
                       "auc": [area_under_curve(c, iters) for c in done], "final": [c[iters] for c in done]}
    return out



def provenance(rows: list[dict]) -> str:
    """One line: how many runs, on which CPU capabilities, and their summed time."""
    cpus, seconds = {}, 0.0
    for r in rows:
        if r["iteration"] == 0:
            cpus[r.get("cpu_capability") or "not recorded"] = cpus.get(r.get("cpu_capability") or "not recorded", 0) + 1
        seconds += r.get("seconds") or 0.0
    where = ", ".join(f"{n} with CPU capability {cpu}" for cpu, n in sorted(cpus.items()))
    return (f"{sum(cpus.values())} runs ({where}, as torch reports it; one torch thread each); "
            f"their iterations took {seconds / 3600:.1f} h of one core in all.")


def summarize_figure3(rows: list[dict], iters: int, seeds: int, problems: list[str] = (), panels: str = "abcd") -> str:
    """Markdown: the runs' provenance, then per panel and method: iterations to converge (per seed
    and their median with its 95 % bootstrap CI), the area under the curve and the final distance
    (mean with CI), the final min-max, the largest drop of a seed, and model exploitation.

    Converged = the first iteration whose distance reaches 90 % of the best mean
    at iteration `iters` of either method in that panel; a seed that never does
    is counted at iters + 1 ("never") in the median.  Area under the curve = a
    run's mean distance over iterations 1..iters.  Largest drop = the largest
    fall of one seed from one iteration to the next after iteration 1 (negative
    when every seed only rises).  Exploitation = the largest, over iterations
    >= 1, of the mean over seeds of |model_progress_m - sim_progress_m| (the
    first T steps).  Statistics are over the seeds that finished.
    """
    lines = [provenance(rows), "",
             "| panel | method | seeds | iterations to converge, per seed | median [95 % CI] "
             "| area under the curve (m) [95 % CI] | final (m) [95 % CI] | final min-max (m) "
             "| largest drop after it. 1 (m) | exploitation (m) |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    fmt = lambda i: "never" if i == iters + 1 else str(i)             # noqa: E731
    for panel, (design, demos) in PANELS.items():
        if panel not in panels:
            continue
        curves = panel_curves(rows, panel, iters)
        runs, gaps, _, _ = curves
        stats = per_run(curves, iters)
        for method in ("RL+IL", "RL"):
            head = f"| ({panel}) {design} ({' + '.join(demos)} demos) | {method} |"
            st = stats.get(method)
            if not st or not st["final"]:
                lines.append(f"{head} 0 of {seeds} | no run finished | | | | | | |")
                continue
            drops = [c[i] - c[i + 1] for c in runs[method].values() for i in range(1, iters) if i + 1 in c]
            gap = max((np.mean(v) for v in gaps.get(method, {}).values()), default=float("nan"))
            lines.append(f"{head} {len(st['final'])} of {seeds} | {', '.join(map(fmt, st['converge']))} "
                         f"| {np.median(st['converge']):g} {interval(bootstrap_ci(st['converge'], np.median))} "
                         f"| {np.mean(st['auc']):.2f} {interval(bootstrap_ci(st['auc']))} "
                         f"| {np.mean(st['final']):.2f} {interval(bootstrap_ci(st['final']))} "
                         f"| {min(st['final']):.2f} - {max(st['final']):.2f} "
                         f"| {max(drops, default=0.0):.2f} | {gap:.2f} |")
    if problems:
        lines += ["", "Missing or failed runs (left out of the statistics above):"] + [f"- {p}" for p in problems]
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
    """figure3.csv and figure3.png: the mean over seeds as a line, its 95 % bootstrap CI as a band,
    min and max over seeds as dotted lines."""
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
            band = [bootstrap_ci(table[i]) for i in it]                              # 95 % CI of the mean
            ax.fill_between(it, [lo for lo, _ in band], [hi for _, hi in band], color=colour, alpha=0.25)
            for edge in (min, max):                                                   # min-max over seeds
                ax.plot(it, [edge(table[i]) for i in it], ":", color=colour, lw=1)
        ax.set_title(f"({panel}) {design}, demos: {' + '.join(demos)}", fontsize=10)
        ax.set_xlabel("iteration")
        ax.set_xticks(range(iters + 1))
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="lower right")
    axes[0].set_ylabel("distance in 200 steps (m)")
    fig.suptitle(f"mean over seeds, its 95 % bootstrap interval (band) and min-max (dotted); {provenance(rows)}",
                 fontsize=8)
    save_sweep_plot(fig, out / "figure3.png", problems)


# ----------------------------------------------------------------------------
# Sample efficiency (not in the paper): Algorithm 1 against PPO per simulator step and per second
# ----------------------------------------------------------------------------
SAMPLE_EFFICIENCY = {"hexapod": PANELS["a"][1], "leg_none_wheel": PANELS["d"][1]}   # design: Figure 3's demos
SAMPLE_METHODS = ("RL+IL", "RL", "PPO", "PPO+IL")     # PPO+IL: PPO with the same demos (issue #24)
THRESHOLDS_M = (5.0, 10.0, 15.0)
SAMPLE_COLUMNS = ["train", "method", "seed", "iteration", "sim_steps", "seconds", "distance_m"]


def sample_efficiency_runs(out: Path, base: rlil.Config, base_ppo: ppo_lib.PPOConfig, seeds: int,
                           jobs: int) -> list[dict]:
    """One entry per run: hexapod and leg_none_wheel x SAMPLE_METHODS x seeds, with `base`'s and
    `base_ppo`'s budgets (the demos: Figure 3's for the design, for RL+IL and PPO+IL); one torch
    thread per run when several run at once."""
    runs = []
    for design, demos in SAMPLE_EFFICIENCY.items():
        code = (sim2d.parse_design(design),)
        for method in SAMPLE_METHODS:
            with_demos = tuple(sim2d.parse_design(d) for d in demos) if method.endswith("+IL") else ()
            ppo = method.startswith("PPO")
            for seed in range(seeds):
                cfg = dataclasses.replace(base_ppo if ppo else base, train=code, seed=seed, demos=with_demos,
                                          threads=1 if jobs > 1 else (base_ppo if ppo else base).threads)
                last = ppo_lib.iterations(cfg) if ppo else cfg.iters
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
    first reaches each of THRESHOLDS_M in 200 steps, and where each ends."""
    head = " | ".join(f"{t:g} m: steps | {t:g} m: seconds" for t in THRESHOLDS_M)
    lines = [f"| design | method | seeds | {head} | final steps | final seconds | final mean (m) | final min-max (m) |",
             "|---|---|---|" + "---|" * (2 * len(THRESHOLDS_M) + 4)]
    for design in SAMPLE_EFFICIENCY:
        for method in SAMPLE_METHODS:
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
            label = (f"{method}" + (f" ({' + '.join(demos)} demos)" if method.endswith("+IL") else "")
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
                      log=None, launcher: str = "local", ray_address: str | None = None,
                      collect: Path | None = None) -> list[str]:
    """Run (or reuse) every run as its own train.py process (or, with `collect`, only read the run
    directories under `collect`), then plot, tabulate and summarise (sample_efficiency.png, .csv,
    .md in `out`).  Returns the runs that failed, are missing or did not finish."""
    log = log or rlil.ProgressLog()
    out.mkdir(parents=True, exist_ok=True)
    runs = sample_efficiency_runs(collect or out, base, base_ppo, seeds, jobs)
    if collect is None:
        launch_runs(runs, 0, jobs, log, "sample efficiency", launcher, ray_address)
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
# What is committed of a sweep: each finished run's metrics.json
# ----------------------------------------------------------------------------
def keep_metrics(src: Path, dest: Path) -> list[str]:
    """Copy the metrics.json of every finished run directory under `src` (its last row at the
    iteration its config asks for: Algorithm 1's iters, PPO's `ppo_minimal.iterations`) to
    dest/<run name>/metrics.json, the small per-run results a sweep is committed as; `--collect
    dest` rebuilds the figure from them, and copied into a sweep folder they count as finished
    runs.  Returns the run names copied."""
    kept = []
    for path in sorted(Path(src).glob("*/metrics.json")):
        saved = json.loads(path.read_text())
        cfg = config_from_dict(saved["config"])
        last = ppo_lib.iterations(cfg) if is_ppo(cfg) else cfg.iters
        if not saved["iterations"] or saved["iterations"][-1]["iteration"] < last:
            continue                                            # unfinished
        (dest / path.parent.name).mkdir(parents=True, exist_ok=True)
        atomic_write(dest / path.parent.name / "metrics.json", lambda p, t=path.read_text(): Path(p).write_text(t))
        kept.append(path.parent.name)
    return kept


def main(argv=None) -> int:
    parser = sim2d.CliParser(description="Keep what is committed of a sweep (the sweeps themselves run with "
                             "train.py --figure3 or --sample-efficiency).")
    parser.add_argument("--keep-metrics", nargs=2, metavar=("SWEEP_DIR", "DEST"), required=True,
                        help="copy the metrics.json of every finished run (Algorithm 1 or PPO) in SWEEP_DIR to "
                             "DEST/<run name>/")
    args = parser.parse_args(argv)
    src, dest = map(Path, args.keep_metrics)
    if not src.is_dir():
        parser.error(f"--keep-metrics: {src} is not a folder of run directories")
    print(f"kept {len(keep_metrics(src, dest))} finished runs' metrics.json in {dest}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
