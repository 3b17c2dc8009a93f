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
        cmd = [sys.executable, str(Path(train.__file__).resolve()), *run["args"], "--out", str(run["dir"])]
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


# The paper's claims for Figure 3 (its caption and Sec. IV): iterations to converge, RL -> RL+IL
PAPER_CLAIMS = {"a": ("never", 2), "b": ("1", "1 (little effect)"), "c": (3, 2), "d": (4, 1)}


def summarize_claims(rows: list[dict], iters: int, seeds: int) -> str:
    """Markdown: the paper's two Figure 3 claims per panel beside ours.  (1) RL+IL converges in
    fewer iterations (panel b: demos have little effect, read as within one iteration), on the
    mean curve with summarize_figure3's rule; (2) RL+IL has less variance in convergence: the
    range (max - min) over seeds of each seed's iteration of convergence, a seed that never
    converges counted at iters + 1.  With a few seeds neither is settled."""
    fmt = lambda i: "never" if i is None else str(i)                   # noqa: E731
    capped = lambda i: iters + 1 if i is None else i                   # noqa: E731
    lines = [f"| panel | paper: converged at, RL → RL+IL | ours, {seeds} seeds: RL → RL+IL | RL+IL sooner (b: within 1) "
             "| ours: per seed, RL; RL+IL | range over seeds, RL → RL+IL | less variance |",
             "|---|---|---|---|---|---|---|"]
    for panel, (design, demos) in PANELS.items():
        runs, _, mean, threshold = panel_curves(rows, panel, iters)
        if set(runs) != {"RL", "RL+IL"}:
            continue
        at = {m: capped(converged_at(mean[m], threshold)) for m in runs}
        per_seed = {m: [converged_at(c, threshold) for c in runs[m].values()] for m in runs}
        spread = {m: max(map(capped, v)) - min(map(capped, v)) for m, v in per_seed.items()}
        sooner = abs(at["RL+IL"] - at["RL"]) <= 1 if panel == "b" else at["RL+IL"] < at["RL"]
        paper_rl, paper_rlil = PAPER_CLAIMS[panel]
        lines.append(
            f"| ({panel}) {design} ({' + '.join(demos)} demos) | {paper_rl} → {paper_rlil} "
            f"| {fmt(converged_at(mean['RL'], threshold))} → {fmt(converged_at(mean['RL+IL'], threshold))} "
            f"| {'yes' if sooner else 'no'} | {', '.join(map(fmt, per_seed['RL']))}; "
            f"{', '.join(map(fmt, per_seed['RL+IL']))} | {spread['RL']} → {spread['RL+IL']} "
            f"| {'yes' if spread['RL+IL'] < spread['RL'] else 'equal' if spread['RL+IL'] == spread['RL'] else 'no'} |")
    return "\n".join(lines) + "\n"


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
    fmt = lambda i: "not converged" if i is None else str(i)          # noqa: E731
    for panel, (design, demos) in PANELS.items():
        if panel not in panels:
            continue
        runs, gaps, mean, threshold = panel_curves(rows, panel, iters)
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
# Results tables: every results/*.md table from the committed CSVs, and the
# README/docs blocks that show them
# ----------------------------------------------------------------------------
ROOT = Path(__file__).resolve().parent
ITERATION_TABLES = {   # results/<csv>.csv with FIGURE3_COLUMNS: results/<md>.md, its per-iteration table
    "figure3": "figure3_iterations",
    "class_demo": "class_demo",
}
TEXT_COLUMNS = {"panel", "train", "demos", "method"}
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
    """Markdown, one row per panel and method (RL+IL before RL): the mean over seeds of
    distance_m at each iteration, with [min, max] over seeds."""
    groups = {}                                   # (panel, train, demos) -> method -> iteration -> distances
    for r in rows:
        panel = groups.setdefault((r["panel"], r["train"], r["demos"]), {})
        distances = panel.setdefault(r["method"], {}).setdefault(r["iteration"], [])
        if r["distance_m"] is not None:
            distances.append(r["distance_m"])
    iterations = sorted({r["iteration"] for r in rows})
    lines = ["| panel | method | seeds | " + " | ".join(f"iteration {i}" for i in iterations) + " |",
             "|---|---|---|" + "---|" * len(iterations)]
    order = {"RL+IL": 0, "RL": 1}
    for (panel, design, demos), methods in groups.items():
        label = f"({panel}) {design}" + (f" ({demos.replace('+', ' + ')} demos)" if demos else "")
        for method in sorted(methods, key=lambda m: order.get(m, len(order))):
            curve = methods[method]
            cells = [f"{np.mean(curve[i]):.2f} [{min(curve[i]):.2f}, {max(curve[i]):.2f}]" if curve.get(i) else ""
                     for i in iterations]
            seeds = len(curve.get(iterations[-1], []))
            lines.append(f"| {label} | {method} | {seeds} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def figure3_table(rows: list[dict]) -> str:
    """summarize_figure3 of a figure3.csv: iters = its largest iteration, seeds = its distinct
    seeds, the panels it has.  Missing or failed runs are not in a CSV, so no note names them."""
    iters = max(r["iteration"] for r in rows)
    seeds = len({r["seed"] for r in rows})
    panels = "".join(p for p in PANELS if any(r["panel"] == p for r in rows))
    return summarize_figure3(rows, iters, seeds, panels=panels)


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
    tables[results / "main_command.md"] = summarize_iterations([r for r in rows if r["panel"] == "d"])  # README
    rows = read_rows_csv(results / "sample_efficiency.csv")
    tables[results / "sample_efficiency.md"] = summarize_sample_efficiency(rows, len({r["seed"] for r in rows}))
    for name, md in ITERATION_TABLES.items():
        if (results / f"{name}.csv").exists():
            tables[results / f"{md}.md"] = summarize_iterations(read_rows_csv(results / f"{name}.csv"))
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


def main(argv=None) -> int:
    parser = sim2d.CliParser(description="Sweeps of train.py runs (run them with train.py --figure3 or "
                             "--sample-efficiency) and the results tables made from their CSVs.")
    parser.add_argument("--tables", action="store_true",
                        help="regenerate results/*.md from results/*.csv and the README.md and docs/*.md "
                             "blocks between <!-- begin: results/NAME.md --> and <!-- end: ... --> lines")
    parser.add_argument("--check", action="store_true",
                        help="with --tables: write nothing; exit 1 naming every file that differs")
    args = parser.parse_args(argv)
    if not args.tables:
        parser.error("say --tables (the sweeps themselves run with train.py --figure3 or --sample-efficiency)")
    try:
        stale = tables(ROOT, check=args.check)
    except UsageError as e:
        parser.error(str(e))
    for p in stale:
        print(f"{'differs' if args.check else 'wrote'}: {p.relative_to(ROOT)}")
    return 1 if args.check and stale else 0


if __name__ == "__main__":
    sys.exit(main())
