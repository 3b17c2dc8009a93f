"""Sweeps: many train.py runs of one experiment, then one plot, one CSV and one summary table.

A sweep is a set of runs that differ only in design, demonstrations, method
and seed: the paper's Figure 3 (4 panels x {RL+IL, RL} x seeds) and the
sample-efficiency comparison (hexapod and leg_none_wheel x {RL+IL, RL, PPO} x
seeds).  Each run is a normal train.py run directory under the sweep's folder
(runs/figure3/<run name>/ with metrics.json, checkpoint.pt, ...), made by its
own `train.py` process, --jobs at a time, its output in its train.log.  A
finished run (its metrics.json at its last iteration) is reused, an interrupted
one continues with --resume, so a sweep that stops resumes where it was, and
its runs can be spread over machines and merged into one folder before
plotting.  The sweep then writes <name>.png, <name>.csv and <name>.md there.

The results tables are never typed by hand: --tables regenerates them from
the committed CSVs in results/ (figure3.md, figure3_claims.md, figure3_iterations.md,
main_command.md (Figure 3's panel d), sample_efficiency.md, and the per-iteration table of every CSV in
ITERATION_TABLES), and rewrites every block of README.md and docs/*.md between
`<!-- begin: results/NAME.md -->` and `<!-- end: results/NAME.md -->` lines
with results/NAME.md.

    python train.py --figure3 [--seeds 3] [--jobs 2] [--panels abcd] [--out runs/figure3]
    python train.py --sample-efficiency [--seeds 3] [--jobs 2] [--env-steps N] [--out runs/sample_efficiency]
    python sweeps.py --tables             # results/*.md and the README/docs blocks from results/*.csv
    python sweeps.py --tables --check     # writes nothing; exit 1 naming every file that differs
"""
from __future__ import annotations

import csv
import dataclasses
import json
import re
import shlex
import sys
import time
from pathlib import Path

import numpy as np

import modular_rlil_minimal as rlil
import ppo_minimal as ppo_lib
import sim2d
import train
from train import COLOURS, UsageError, atomic_write, config_args, config_from_dict, run_name


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
    cmd = [sys.executable, str(Path(train.__file__).resolve()), *run["args"], "--out", str(run["dir"])]
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


def converged_at(curve: dict, threshold: float):
    """First iteration whose distance reaches `threshold`, or None."""
    return next((i for i in sorted(curve) if curve[i] >= threshold), None)


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


# ----------------------------------------------------------------------------
# Statistics over seeds, numpy only (rliable: Agarwal et al. 2021; Henderson et al. 2018)
# ----------------------------------------------------------------------------
RESAMPLES = 10_000           # bootstrap resamples per interval
LEVEL = 0.95                 # confidence level of every interval


def resample(x, resamples: int, rng: np.random.Generator) -> np.ndarray:
    """(resamples, n): the n runs of x drawn with replacement, `resamples` times."""
    x = np.asarray(x, float)
    return x[rng.integers(len(x), size=(resamples, len(x)))]


def percentile_interval(values) -> tuple[float, float]:
    """The central LEVEL interval of bootstrap values: their 2.5th and 97.5th percentiles."""
    tail = 100 * (1 - LEVEL) / 2
    lo, hi = np.percentile(values, [tail, 100 - tail])
    return float(lo), float(hi)


def bootstrap_ci(x, statistic=np.mean, resamples: int = RESAMPLES, seed: int = 0) -> tuple[float, float]:
    """Percentile bootstrap CI of statistic(x) over runs (statistic takes axis=-1).

    Example: x = [0, 1] resamples to the means 0, 0.5 and 1 with probabilities
    1/4, 1/2 and 1/4, so the 95 % interval is (0, 1).
    """
    return percentile_interval(statistic(resample(x, resamples, np.random.default_rng(seed)), axis=-1))


def bootstrap_diff_ci(x, y, statistic=np.mean, resamples: int = RESAMPLES, seed: int = 0) -> tuple[float, float]:
    """Percentile bootstrap CI of statistic(x) - statistic(y), each condition's runs resampled on its own."""
    rng = np.random.default_rng(seed)
    return percentile_interval(statistic(resample(x, resamples, rng), axis=-1)
                               - statistic(resample(y, resamples, rng), axis=-1))


def probability_of_improvement(x, y):
    """P(X > Y) over runs (rliable): the mean over all pairs (i, j) of 1 if x_i > y_j, 1/2 if equal,
    0 otherwise, which is the Mann-Whitney U statistic divided by n m.  Leading axes are batches.

    Example: x = [1, 2, 3], y = [2, 2]: the six pairs score 0, 0, 1/2, 1/2, 1, 1, so 0.5.
    """
    x, y = np.asarray(x, float)[..., :, None], np.asarray(y, float)[..., None, :]
    p = ((x > y) + 0.5 * (x == y)).mean((-2, -1))
    return float(p) if p.ndim == 0 else p


def probability_of_improvement_ci(x, y, resamples: int = RESAMPLES, seed: int = 0) -> tuple[float, float]:
    """Percentile bootstrap CI of P(X > Y), each condition's runs resampled on its own."""
    rng = np.random.default_rng(seed)
    return percentile_interval(probability_of_improvement(resample(x, resamples, rng), resample(y, resamples, rng)))


def area_under_curve(curve: dict, iters: int):
    """A run's mean distance over iterations 1..iters (one number for "learns faster"); None if unfinished."""
    return float(np.mean([curve[i] for i in range(1, iters + 1)])) if all(i in curve for i in range(1, iters + 1)) \
        else None


def iterations_to_converge(curve: dict, threshold: float, iters: int) -> int:
    """`converged_at` for one run, a run that never converges counted at the cap iters + 1."""
    at = converged_at(curve, threshold)
    return iters + 1 if at is None else at


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


def verdict(ci: tuple[float, float], margin: float | None = None) -> str:
    """"holds" / "fails" / "not settled" for a difference's CI: with no margin, the claim is that the
    difference is above 0; with a margin, that it lies within +-margin (no real effect)."""
    lo, hi = ci
    if margin is None:
        return "holds" if lo > 0 else "fails" if hi < 0 else "not settled"
    return "holds" if -margin <= lo and hi <= margin else "fails" if hi < -margin or lo > margin else "not settled"


def interval(ci) -> str:
    return f"[{ci[0]:.2f}, {ci[1]:.2f}]"


# The paper's claims for Figure 3 (its caption and Sec. IV), fixed before the 10-seed sweep ran:
# (b)'s "little effect" is read as a difference within LITTLE_EFFECT of 0.
LITTLE_EFFECT = {"iterations": 1.0, "m": 1.0}


def summarize_claims(rows: list[dict], iters: int, seeds: int) -> str:
    """Markdown: each of the paper's Figure 3 claims per panel, the statistic that tests it, its
    95 % bootstrap CI, and holds / not settled / fails (`verdict`).

    Iterations to converge: summarize_figure3's rule per seed, a seed that never converges
    counted at iters + 1.  (a), (c), (d): RL+IL converges in fewer iterations (mean RL - RL+IL
    above 0) and learns faster (area under the curve, RL+IL - RL, above 0, with P(RL+IL > RL));
    (b): the car's demos have little effect (both differences within LITTLE_EFFECT); all four:
    RL+IL lowers the variance of convergence (std RL - RL+IL above 0).
    """
    lines = [f"| panel | claim | statistic ({seeds} seeds per method; a seed that never converges counts "
             f"{iters + 1}) | value | 95 % CI | verdict |",
             "|---|---|---|---|---|---|"]
    std = lambda x, axis=-1: np.std(x, axis=axis)                      # noqa: E731
    for panel, (design, demos) in PANELS.items():
        stats = per_run(panel_curves(rows, panel, iters), iters)
        if set(stats) != {"RL", "RL+IL"} or not all(stats[m]["auc"] for m in stats):
            continue
        rl, rlil = stats["RL"], stats["RL+IL"]
        name = f"({panel}) {design}"
        little = panel == "b"
        conv = bootstrap_diff_ci(rl["converge"], rlil["converge"])
        auc = bootstrap_diff_ci(rlil["auc"], rl["auc"])
        lines.append(f"| {name} | {'demos have little effect on convergence' if little else 'RL+IL converges in fewer iterations'} "
                     f"| mean iterations to converge, RL − RL+IL ({np.mean(rl['converge']):.1f} − "
                     f"{np.mean(rlil['converge']):.1f}) | {np.mean(rl['converge']) - np.mean(rlil['converge']):.2f} "
                     f"| {interval(conv)} | {verdict(conv, LITTLE_EFFECT['iterations'] if little else None)} |")
        lines.append(f"| {name} | {'demos have little effect on distance' if little else 'RL+IL learns faster'} "
                     f"| area under the curve (mean m over iterations 1-{iters}), RL+IL − RL; "
                     f"P(RL+IL > RL) = {probability_of_improvement(rlil['auc'], rl['auc']):.2f} "
                     f"{interval(probability_of_improvement_ci(rlil['auc'], rl['auc']))} "
                     f"| {np.mean(rlil['auc']) - np.mean(rl['auc']):.2f} | {interval(auc)} "
                     f"| {verdict(auc, LITTLE_EFFECT['m'] if little else None)} |")
        spread = bootstrap_diff_ci(rl["converge"], rlil["converge"], statistic=std)
        lines.append(f"| {name} | RL+IL lowers the variance of convergence | std of iterations to converge, "
                     f"RL − RL+IL ({np.std(rl['converge']):.2f} − {np.std(rlil['converge']):.2f}) "
                     f"| {np.std(rl['converge']) - np.std(rlil['converge']):.2f} | {interval(spread)} "
                     f"| {verdict(spread)} |")
    return "\n".join(lines) + "\n"


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
# Issue #23's screen: switches against collapse between iterations, panels (a)
# and (d), both methods, 5 seeds, each against the default on the same seeds
# ----------------------------------------------------------------------------
SCREEN = {   # variant: (its train.py flags, the variant whose RL runs are its own: None = its own runs)
    "paper": (("--clone-data", "off", "--keep-better", "off"), None),
    "clone_data": (("--clone-data", "on", "--keep-better", "off"), "paper"),   # acts only with demos
    "keep_better": (("--clone-data", "off", "--keep-better", "on"), None),
    "clone_data+keep_better": (("--clone-data", "on", "--keep-better", "on"), "keep_better"),
}
CONFIRM = {  # the 10-seed Figure 3 with the chosen defaults against the paper's Algorithm 1, same seeds
    "paper": SCREEN["paper"],
    "default (clone_data+keep_better)": ((), None),
}
DEFAULT = "default (clone_data+keep_better)"        # the chosen defaults: results/figure3_runs/
SCREEN_OVER_DEFAULTS = {  # the later candidates, each over the chosen defaults and against them, same seeds
    DEFAULT: ((), None),
    "contact_features": (("--gnn-contact-features", "on"), None),   # both flags removed after 0571107;
    "critic": (("--critic", "on"), None),                            # their runs stay committed
}
SCREEN_SEEDS, SCREEN_PANELS, FALL_M = 5, "ad", 3.0     # a fall: distance lost between consecutive iterations


def variant_dir(root: Path, variant: str) -> Path:
    """Where a variant's committed metrics.json live: the defaults' are the README's 10-seed Figure 3
    (results/figure3_runs/), the others' (the paper's Algorithm 1, issue #22's sweep, included) in
    results/stability_runs/<variant>/."""
    return root / "results" / ("figure3_runs" if variant.startswith("default") else f"stability_runs/{variant}")


def variant_rows(root: Path, variants: dict, seeds: int, panels: str) -> list[dict]:
    """FIGURE3_COLUMNS rows, with the variant, of every finished run of `variants` (SCREEN, CONFIRM)."""
    rows = []
    for variant, (_, rl_from) in variants.items():
        runs = figure3_runs(variant_dir(root, variant), rlil.Config(), seeds, 2, panels)
        rows += [{"variant": variant, **row} for row in figure3_rows(
            [r for r in runs if not (rl_from and r["method"] == "RL")])]
    return rows


def largest_fall(curve: dict, iters: int) -> float:
    """A run's largest loss of distance between consecutive iterations from iteration 1 on (0 if none)."""
    return max([0.0] + [curve[i] - curve[i + 1] for i in range(1, iters) if i in curve and i + 1 in curve])


def variant_stats(rows: list[dict], variant: str, rl_from: str | None, panel: str, iters: int) -> dict:
    """method -> per_run's lists (area, final) plus curves, mean curve, falls, exploitation and time,
    for one variant and panel (its RL runs those of `rl_from` when given)."""
    sub = [r for r in rows if r["panel"] == panel and (
        (r["variant"] == variant and r["method"] == "RL+IL") or (r["variant"] == (rl_from or variant)
                                                               and r["method"] == "RL"))]
    runs, gaps, mean, _ = panel_curves(sub, panel, iters)
    stats = per_run((runs, gaps, mean, float("inf")), iters)
    for method, s in stats.items():
        s.update(curves=runs[method], mean=mean[method],
                 falls=[largest_fall(c, iters) for c in runs[method].values()],
                 exploit=max([np.mean(g) for i, g in gaps.get(method, {}).items() if i >= 1], default=float("nan")),
                 seconds=np.mean([sum(r["seconds"] or 0 for r in sub if r["method"] == method and r["seed"] == seed)
                                  for seed in runs[method]]))
    return stats


def difference(x, y) -> str:
    """mean(x) - mean(y) [its 95 % bootstrap CI], or empty when either is empty."""
    return f"{np.mean(x) - np.mean(y):.2f} {interval(bootstrap_diff_ci(x, y))}" if len(x) and len(y) else ""


def summarize_variants(rows: list[dict], variants: dict = SCREEN, baseline: str = "paper") -> str:
    """Markdown, one line per variant, panel and method: mean distance per iteration, the final
    mean with its 95 % CI, the seeds that fall by more than FALL_M m between consecutive
    iterations from iteration 1 on (and the largest fall), exploitation (the largest mean over
    seeds of |model - simulator progress| over the first T steps, iterations >= 1), the area
    under the curve, the variant − `baseline` in it (same method, the variant's seeds) and, on the RL+IL
    line, RL+IL − RL in it, each with its 95 % CI, and the mean time per run."""
    iters = max(r["iteration"] for r in rows)
    lines = ["| variant | flags | panel | method | seeds | mean distance, iterations 0 → "
             f"{iters} (m) | final [95 % CI] (m) | seeds falling > {FALL_M:.0f} m (largest fall, m) "
             f"| exploitation (m) | area under the curve (m) | − {baseline.split(' (')[0]} in area [95 % CI] (m) "
             "| RL+IL − RL in area [95 % CI] (m) | time per run (s) |",
             "|---" * 13 + "|"]
    panels = [p for p in PANELS if any(r["panel"] == p for r in rows)]
    for variant, (flags, rl_from) in variants.items():
        code = f"`{' '.join(flags)}`" if flags else ""
        for panel in panels:
            stats = variant_stats(rows, variant, rl_from, panel, iters)
            paper = variant_stats(rows, baseline, None, panel, iters) if variant != baseline else {}
            for method in ("RL+IL", "RL"):
                if method not in stats:
                    continue
                s = stats[method]
                label = f"{variant} (the {rl_from} runs)" if method == "RL" and rl_from else variant
                if not s["auc"]:
                    lines.append(f"| {label} | {code} | ({panel}) {PANELS[panel][0]} | {method} | "
                                 f"{len(s['curves'])} | unfinished |" + " |" * 7)
                    continue
                curve = ", ".join(f"{s['mean'][i]:.1f}" for i in sorted(s["mean"]))
                same_runs = method == "RL" and rl_from == baseline                # nothing to compare
                paper_auc = [area_under_curve(c, iters) for seed, c in paper.get(method, {}).get("curves", {}).items()
                             if seed in s["curves"]]                                    # the same seeds only
                against = difference(s["auc"], paper_auc) if paper_auc and not same_runs else ""
                gap = difference(s["auc"], stats["RL"]["auc"]) if method == "RL+IL" and "RL" in stats else ""
                lines.append(
                    f"| {label} | {code} | ({panel}) {PANELS[panel][0]} | {method} | {len(s['auc'])} "
                    f"| {curve} "
                    f"| {np.mean(s['final']):.2f} {interval(bootstrap_ci(s['final']))} "
                    f"| {sum(f > FALL_M for f in s['falls'])} ({max(s['falls']):.2f}) | {s['exploit']:.2f} "
                    f"| {np.mean(s['auc']):.2f} | {against} | {gap} | {s['seconds']:.0f} |")
    return "\n".join(lines) + "\n"


def summarize_targets(rows: list[dict], variant: str) -> str:
    """Markdown: issue #23's targets 1-5, each measured on `variant`'s runs (seeds counted per line)."""
    iters = max(r["iteration"] for r in rows)
    stats = {p: variant_stats(rows, variant, None, p, iters) for p in PANELS if any(r["panel"] == p for r in rows)}
    met = lambda ok: "met" if ok else "missed"                              # noqa: E731
    lines = ["| target | panel | seeds (RL+IL, RL) | measured | met? |", "|---|---|---|---|---|"]
    for p, s in stats.items():
        if not (s.get("RL+IL", {}).get("auc") and s.get("RL", {}).get("auc")):
            continue
        rlil, rl = s["RL+IL"], s["RL"]
        seeds = f"{len(rlil['auc'])}, {len(rl['auc'])}"
        name = f"({p}) {PANELS[p][0]}"
        n_rlil, n_rl = sum(f > FALL_M for f in rlil["falls"]), sum(f > FALL_M for f in rl["falls"])
        lines.append(f"| 1. no RL+IL seed falls > {FALL_M:.0f} m from iteration 1 on; RL at most 1 in 10 | {name} "
                     f"| {seeds} | RL+IL {n_rlil} (largest {max(rlil['falls']):.2f} m), RL {n_rl} "
                     f"(largest {max(rl['falls']):.2f} m) | {met(n_rlil == 0 and n_rl <= len(rl['falls']) / 10)} |")
        if p == "a":
            final, start = np.mean(rlil["final"]), rlil["mean"][0]
            lines.append(f"| 2. hexapod RL+IL final ≥ iteration 0 + 2 m and ≥ 15 m | {name} | {seeds} "
                         f"| {final:.2f} m against {start:.2f} m at iteration 0 | {met(final >= start + 2 and final >= 15)} |")
        worst = max(rlil["exploit"], rl["exploit"])
        lines.append(f"| 3. exploitation ≤ 0.3 m | {name} | {seeds} | RL+IL {rlil['exploit']:.2f}, RL {rl['exploit']:.2f} m "
                     f"| {met(worst <= 0.3)} |")
        if p == "b":
            gap = np.mean(rlil["final"]) - np.mean(rl["final"])
            lines.append(f"| 4. car: RL+IL final within 1 m of RL's | {name} | {seeds} | {gap:.2f} m | {met(abs(gap) <= 1)} |")
        else:
            ci = bootstrap_diff_ci(rlil["auc"], rl["auc"])
            lines.append(f"| 4. RL+IL − RL in area under the curve: 95 % CI above 0 | {name} | {seeds} "
                         f"| {np.mean(rlil['auc']) - np.mean(rl['auc']):.2f} {interval(ci)} | {met(ci[0] > 0)} |")
        if p == "d":
            first = {seed: c for seed, c in rlil["curves"].items() if seed < 5}
            low = [seed for seed, c in first.items() if min(c[i] for i in range(1, iters + 1)) <= 15]
            lines.append(f"| 5. main command, seeds 0-4: every iteration ≥ 1 above 15 m | {name} | {len(first)} "
                         f"| {'seeds ' + ', '.join(map(str, low)) + ' below' if low else 'all above'} | {met(not low)} |")
    return "\n".join(lines) + "\n"


# ----------------------------------------------------------------------------
# Results tables: every results/*.md table from the committed CSVs, and the
# README/docs blocks that show them
# ----------------------------------------------------------------------------
ROOT = Path(__file__).resolve().parent
ITERATION_TABLES = {   # results/<csv>.csv with FIGURE3_COLUMNS: results/<md>.md, its per-iteration table, methods
    "figure3": ("figure3_iterations", ("RL+IL", "RL")),
    "class_demo": ("class_demo", ("RL",)),                       # the class demo command has no demos
}
TEXT_COLUMNS = {"variant", "panel", "train", "demos", "method", "cpu_capability"}
BEGIN, END = "<!-- begin: results/{}.md -->", "<!-- end: results/{}.md -->"


def read_rows_csv(path: Path) -> list[dict]:
    """The rows of a sweep's CSV as write_rows_csv wrote them: numbers as int or float (a float's
    text is its repr, so the value is the one written), empty cells as None, TEXT_COLUMNS as text."""
    def value(column, text):
        if column in TEXT_COLUMNS:
            return text
        if text == "":
            return None
        try:
            return int(text)
        except ValueError:
            return float(text)
    with open(path, newline="") as f:
        return [{k: value(k, v) for k, v in row.items()} for row in csv.DictReader(f)]


def summarize_iterations(rows: list[dict]) -> str:
    """Markdown, per panel and method (RL+IL before RL) and iteration: the number of seeds, the mean
    of distance_m over them with its 95 % bootstrap CI, and its min - max."""
    groups = {}                                   # (panel, train, demos) -> method -> iteration -> distances
    for r in rows:
        panel = groups.setdefault((r["panel"], r["train"], r["demos"]), {})
        distances = panel.setdefault(r["method"], {}).setdefault(r["iteration"], [])
        if r["distance_m"] is not None:
            distances.append(r["distance_m"])
    lines = ["| panel | method | iteration | seeds | mean (m) | 95 % CI of the mean (m) | min - max (m) |",
             "|---|---|---|---|---|---|---|"]
    order = {"RL+IL": 0, "RL": 1}
    for (panel, design, demos), methods in groups.items():
        for method in sorted(methods, key=lambda m: order.get(m, len(order))):
            label = f"({panel}) {design}" + (f" ({demos.replace('+', ' + ')} demos)" if method == "RL+IL" else "")
            for i, d in sorted(methods[method].items()):
                lines.append(f"| {label} | {method} | {i} | {len(d)} | {np.mean(d):.2f} | "
                             f"{interval(bootstrap_ci(d))} | {min(d):.2f} - {max(d):.2f} |")
    return "\n".join(lines) + "\n"


def seed_curves(rows: list[dict], seeds: int) -> str:
    """Markdown: one line per seed below `seeds`, its distance at every iteration (one panel and method's rows)."""
    curves = {}
    for r in rows:
        if r["seed"] < seeds:
            curves.setdefault(r["seed"], {})[r["iteration"]] = r["distance_m"]
    iters = sorted({i for c in curves.values() for i in c})
    lines = ["| seed | " + " | ".join(f"it. {i} (m)" for i in iters) + " |", "|---" * (len(iters) + 1) + "|"]
    lines += [f"| {s} | " + " | ".join(f"{c[i]:.2f}" if i in c else "" for i in iters) + " |"
              for s, c in sorted(curves.items())]
    return "\n".join(lines) + "\n"


def figure3_table(rows: list[dict]) -> str:
    """summarize_figure3 of a figure3.csv: iters = its largest iteration, seeds = its distinct
    seeds, the panels it has.  Missing or failed runs are not in a CSV, so no note names them."""
    iters = max(r["iteration"] for r in rows)
    seeds = len({r["seed"] for r in rows})
    panels = "".join(p for p in PANELS if any(r["panel"] == p for r in rows))
    return summarize_figure3(rows, iters, seeds, panels=panels)


TRANSFER_DIRS = ("transfer", "generalist")   # results/<dir>/transfer.csv, written by train.py --transfer --out


def generalist_table(root: Path) -> str:
    """transfer.generalist_table of results/generalist/transfer.csv against figure3.csv, at the first
    iteration where the four single-design RL+IL runs together have used at least the generalist's
    simulator steps, and at their last iteration (steps from the committed metrics.json)."""
    import transfer
    results = root / "results"
    generalist = transfer.read_csv(results / "generalist" / "transfer.csv")
    saved = [json.loads(p.read_text()) for p in sorted((results / "generalist_runs").glob("*/metrics.json"))]
    steps = {"generalist": max(m["iterations"][-1]["sim_steps"] for m in saved)}
    single = [json.loads((results / "figure3_runs" / f"{design}-{'_'.join(demo)}-seed0" / "metrics.json").read_text())
              ["iterations"] for design, demo in PANELS.values()]
    total = [sum(its[k]["sim_steps"] for its in single) for k in range(len(single[0]))]
    first = next((k for k, n in enumerate(total) if n >= steps["generalist"]), len(total) - 1)
    steps.update({k: total[k] for k in dict.fromkeys((first, len(total) - 1))})
    return transfer.generalist_table(generalist, read_rows_csv(results / "figure3.csv"), steps)


def regenerate_tables(root: Path) -> dict[Path, str]:
    """{results/NAME.md: its content regenerated from results/*.csv}.  figure3.csv and
    sample_efficiency.csv must exist; a CSV of ITERATION_TABLES that does not is skipped."""
    results, tables = root / "results", {}
    for name in ("figure3", "sample_efficiency"):
        if not (results / f"{name}.csv").exists():
            raise UsageError(f"{results / name}.csv is missing")
    rows = read_rows_csv(results / "figure3.csv")
    tables[results / "figure3.md"] = figure3_table(rows)
    tables[results / "figure3_claims.md"] = summarize_claims(rows, max(r["iteration"] for r in rows),
                                                             len({r["seed"] for r in rows}))
    if (results / "stability_confirm.csv").exists():     # the README's main command: panel (d), RL+IL, today's defaults
        main = [{k: v for k, v in r.items() if k != "variant"} for r in read_rows_csv(results / "stability_confirm.csv")
                if r["variant"].startswith("default") and r["panel"] == "d" and r["method"] == "RL+IL"]
        tables[results / "main_command.md"] = summarize_iterations(main)
        tables[results / "main_command_seeds.md"] = seed_curves(main, 5)
    rows = read_rows_csv(results / "sample_efficiency.csv")
    tables[results / "sample_efficiency.md"] = summarize_sample_efficiency(rows, len({r["seed"] for r in rows}))
    for name, variants, baseline in (("stability_screen", SCREEN, "paper"), ("stability_confirm", CONFIRM, "paper"),
                                     ("stability_screen_defaults", SCREEN_OVER_DEFAULTS, DEFAULT)):
        if (results / f"{name}.csv").exists():
            tables[results / f"{name}.md"] = summarize_variants(read_rows_csv(results / f"{name}.csv"), variants,
                                                                baseline)
    if (results / "stability_confirm.csv").exists():
        rows = read_rows_csv(results / "stability_confirm.csv")
        tables[results / "stability_targets.md"] = "\n".join(
            f"**{variant}**\n\n{summarize_targets(rows, variant)}" for variant in CONFIRM)
    transfer_csvs = [results / d / "transfer.csv" for d in TRANSFER_DIRS if (results / d / "transfer.csv").exists()]
    if transfer_csvs:                                   # issue #24: Figure 3's policies and the generalists
        import transfer
        tables[results / "transfer_summary.md"] = transfer.group_table(
            [r for path in transfer_csvs for r in transfer.read_csv(path)])
    if (results / "generalist" / "transfer.csv").exists():
        tables[results / "generalist.md"] = generalist_table(root)
    for name, (md, methods) in ITERATION_TABLES.items():
        if (results / f"{name}.csv").exists():
            tables[results / f"{md}.md"] = summarize_iterations(
                [r for r in read_rows_csv(results / f"{name}.csv") if r["method"] in methods])
    return tables


def fill_blocks(text: str, table, where: Path) -> str:
    """`text` with the lines between every `<!-- begin: results/NAME.md -->` line and its
    `<!-- end: ... -->` line replaced by table(NAME); the marker lines stay."""
    lines, out, k = text.splitlines(keepends=True), [], 0
    while k < len(lines):
        out.append(lines[k])
        m = re.fullmatch(r"<!-- begin: results/(.+)\.md -->", lines[k].rstrip("\r\n"))
        k += 1
        if not m:
            continue
        end = next((j for j in range(k, len(lines)) if lines[j].rstrip("\r\n") == END.format(m[1])), None)
        if end is None:
            raise UsageError(f"{where}: {BEGIN.format(m[1])} has no {END.format(m[1])} line")
        content = table(m[1])
        out += [content + "\n" * (not content.endswith("\n"))] + [lines[end]]
        k = end + 1
    return "".join(out)


def tables(root: Path = None, check: bool = False) -> list[Path]:
    """Regenerate the results tables under `root` (default: this repository) and the README.md and
    docs/*.md blocks that show them; return every file whose content differs from the regenerated
    one, writing them unless `check`.  A block naming a results/NAME.md that neither is regenerated
    nor exists is a UsageError."""
    root = Path(root or ROOT)
    new = regenerate_tables(root)

    def table(name):
        path = root / "results" / f"{name}.md"
        if path in new:
            return new[path]
        if not path.exists():
            raise UsageError(f"a block names {path}, which does not exist")
        return path.read_text()

    for doc in [root / "README.md", *sorted((root / "docs").glob("*.md"))]:
        if doc.exists():
            new[doc] = fill_blocks(doc.read_text(), table, doc)
    stale = [p for p, text in new.items() if not p.exists() or p.read_text() != text]
    if not check:
        for p in stale:
            atomic_write(p, lambda tmp, text=new[p]: Path(tmp).write_text(text))
    return stale


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
        last = ppo_lib.iterations(cfg) if train.is_ppo(cfg) else cfg.iters
        if not saved["iterations"] or saved["iterations"][-1]["iteration"] < last:
            continue                                            # unfinished
        (dest / path.parent.name).mkdir(parents=True, exist_ok=True)
        atomic_write(dest / path.parent.name / "metrics.json", lambda p, t=path.read_text(): Path(p).write_text(t))
        kept.append(path.parent.name)
    return kept


def main(argv=None) -> int:
    parser = sim2d.CliParser(description="Sweeps of train.py runs (run them with train.py --figure3 or "
                             "--sample-efficiency) and the results tables made from their CSVs.")
    parser.add_argument("--tables", action="store_true",
                        help="regenerate results/*.md from results/*.csv and the README.md and docs/*.md "
                             "blocks between <!-- begin: results/NAME.md --> and <!-- end: ... --> lines")
    parser.add_argument("--check", action="store_true",
                        help="with --tables: write nothing; exit 1 naming every file that differs")
    parser.add_argument("--keep-metrics", nargs=2, metavar=("SWEEP_DIR", "DEST"),
                        help="copy the metrics.json of every finished run (Algorithm 1 or PPO) in SWEEP_DIR to "
                             "DEST/<run name>/ (what is committed of a sweep)")
    parser.add_argument("--screen", action="store_true",
                        help="write results/stability_screen.csv, stability_confirm.csv and "
                             "stability_screen_defaults.csv from the committed runs "
                             "of issue #23 (results/stability_runs/<variant>/, the defaults' in results/figure3_runs/); with --tables, "
                             "then the tables")
    args = parser.parse_args(argv)
    if args.screen:
        for name, variants, seeds, panels in (("stability_screen", SCREEN, SCREEN_SEEDS, SCREEN_PANELS),
                                              ("stability_confirm", CONFIRM, 10, "abcd"),
                                              ("stability_screen_defaults", SCREEN_OVER_DEFAULTS, SCREEN_SEEDS,
                                               SCREEN_PANELS)):
            rows = variant_rows(ROOT, variants, seeds, panels)
            write_rows_csv(ROOT / "results" / f"{name}.csv", ["variant"] + FIGURE3_COLUMNS, rows)
            runs = len({(r["variant"], r["panel"], r["method"], r["seed"]) for r in rows})
            print(f"wrote results/{name}.csv: {runs} runs")
        if not args.tables:
            return 0
    if args.keep_metrics:
        src, dest = map(Path, args.keep_metrics)
        if not src.is_dir():
            parser.error(f"--keep-metrics: {src} is not a folder of run directories")
        print(f"kept {len(keep_metrics(src, dest))} finished runs' metrics.json in {dest}")
        return 0
    if not args.tables:
        parser.error("say --tables, --screen or --keep-metrics (the sweeps themselves run with train.py --figure3 "
                     "or --sample-efficiency)")
    try:
        stale = tables(ROOT, check=args.check)
    except UsageError as e:
        parser.error(str(e))
    for p in stale:
        print(f"{'differs' if args.check else 'wrote'}: {p.relative_to(ROOT)}")
    return 1 if args.check and stale else 0


if __name__ == "__main__":
    sys.exit(main())
