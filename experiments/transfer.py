"""Zero-shot transfer: trained policies on designs they were not trained on, against each design's demonstrator.

A modular policy controls any design, so a run trained on one design can be
evaluated on all of them.  For each (policy, design) this measures
the distance in the run's eval_steps control steps (200 by default, Sec. IV)
from the starts `train.py --eval` uses, and the ratio to the distance the
design's hand-crafted demonstrator (demos.Demonstrator) covers from the same
starts.  A design a run was trained on (its --train) is "seen" for that run;
every other design, its demonstration designs included, is "unseen".

    python train.py --transfer runs/leg_none_wheel-hexapod_car-seed0 runs/leg_none_wheel-rl-seed0
    python train.py --transfer runs/car-rl-seed0 --designs car hexapod --out runs/transfer_car --force
    python train.py --compare runs/A runs/B --gif ab.gif [--design hexapod] [--png ab.png]
    python experiments/transfer.py > results/held_out_designs.txt     # remake the committed held-out list

--transfer evaluates each run on the --designs (default the four of
Figure 3) and on the 50 held-out designs of results/held_out_designs.txt, and
writes transfer.csv, transfer.png (a heat-map) and transfer.md (the summary,
also printed) to --out (default runs/transfer).  --compare draws two runs'
policies on one design from the same start, one robot above the other.
Neither overwrites an existing file without --force.
"""
from __future__ import annotations

import csv
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

if __package__ in (None, ""):              # run as a script: the stage files are one folder up
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import demos                                                                                 # noqa: E402
import modular_rlil_minimal as rlil                                                          # noqa: E402
import sim2d                                                                                 # noqa: E402
from experiments.run_folders import (UsageError, check_new, claim_output_file, load_policy,  # noqa: E402
                                     method_of)
from experiments.stats import bootstrap_ci                                                   # noqa: E402
from sim2d import atomic_write                                                               # noqa: E402

FIGURE3_DESIGNS = tuple(sim2d.NAMED_DESIGNS)          # hexapod, car, leg_leg_wheel, leg_none_wheel
HELD_OUT_FILE = Path(__file__).resolve().parents[1] / "results" / "held_out_designs.txt"
HELD_OUT_COUNT, HELD_OUT_SEED = 50, 0
GOOD_RATIO = 0.6                                        # "transfers": at least this fraction of the demonstrator
OUTPUTS = ("transfer.csv", "transfer.png", "transfer.md")


# ----------------------------------------------------------------------------
# The held-out designs
# ----------------------------------------------------------------------------
def is_demonstrable(code: str) -> bool:
    try:
        demos.check_demonstrable(sim2d.design_graph(code))
        return True
    except ValueError:
        return False


def held_out_pool() -> list[str]:
    """Every demonstrable code that is none of the four Figure 3 designs."""
    figure3 = set(sim2d.NAMED_DESIGNS.values())
    return [c for c in sim2d.all_designs() if c not in figure3 and is_demonstrable(c)]


def held_out_designs(n: int = HELD_OUT_COUNT, seed: int = HELD_OUT_SEED) -> list[str]:
    """n codes of the pool drawn without replacement by a seeded generator, sorted."""
    return sorted(np.random.default_rng(seed).choice(held_out_pool(), size=n, replace=False).tolist())


def held_out_text() -> str:
    """The text of results/held_out_designs.txt: one comment line, then one code per line."""
    return (f"# {HELD_OUT_COUNT} held-out designs, made by `python experiments/transfer.py > results/held_out_designs.txt`: "
            f"numpy.random.default_rng({HELD_OUT_SEED}) draws them without replacement from the "
            f"{len(held_out_pool())} demonstrable codes (demos.check_demonstrable) that are none of the four "
            "Figure 3 designs; sorted\n"
            + "".join(c + "\n" for c in held_out_designs()))


def read_held_out(path: Path = HELD_OUT_FILE) -> list[str]:
    if not path.is_file():
        raise UsageError(f"no held-out design list at {path}: make it with python experiments/transfer.py > {path}")
    return [line.strip() for line in path.read_text().splitlines() if line.strip() and not line.startswith("#")]


def names(designs) -> str:
    """"hexapod+car" for ("llllll", "car")."""
    return "+".join(sim2d.design_name(sim2d.parse_design(d)) for d in designs)


def design_codes(designs) -> list[str]:
    """Names or codes -> codes, each once; a UsageError for an unknown or undemonstrable design."""
    codes = []
    for d in designs:
        try:
            graph = sim2d.design_graph(d)
            demos.check_demonstrable(graph)          # the ratio needs the design's demonstrator
        except ValueError as e:
            raise UsageError(str(e))
        codes.append(graph.code)
    return list(dict.fromkeys(codes))


# ----------------------------------------------------------------------------
# Policies and demonstrators from the same starts
# ----------------------------------------------------------------------------
@dataclass
class Trained:
    """A run's saved policy, loaded as --eval loads it (run_folders.load_policy)."""

    run_dir: Path
    cfg: object          # modular_rlil_minimal.Config or ppo_minimal.PPOConfig
    policy: object       # the policy as it acts in its run (run_folders.policy_to_evaluate)
    iteration: int

    @property
    def method(self) -> str:
        return method_of(self.cfg)

    @property
    def trained_on(self) -> list[str]:
        return [sim2d.parse_design(d) for d in self.cfg.train]

    @property
    def label(self) -> str:
        return f"{self.method}, seed {self.cfg.seed}, iteration {self.iteration}"


def load_trained(run_dir) -> Trained:
    run_dir = Path(run_dir)
    if not run_dir.is_dir():
        raise UsageError(f"no run directory {run_dir}: give a run directory written by train.py")
    return Trained(run_dir, *load_policy(run_dir))


def policy_episodes(run: Trained, design: str, starts_of: Trained | None = None) -> sim2d.Episodes:
    """--eval's roll-outs of `run`'s policy on `design`, from the evaluation starts of `starts_of`
    (default: its own run's, the ones --eval uses)."""
    cfg = (starts_of or run).cfg
    torch.set_num_threads(run.cfg.threads)      # as the run evaluated itself (torch's default: 10x slower here)
    return rlil.evaluate_policy(run.policy, design, cfg, rlil.eval_seed(cfg))


def demonstrator_episodes(design: str, cfg) -> sim2d.Episodes:
    """The design's demonstrator (noiseless) from the starts `rlil.evaluate_policy(..., cfg, eval_seed(cfg))`
    uses: the same robots, seed and number of steps."""
    return sim2d.simulate(design, demos.Demonstrator(design), n=cfg.eval_episodes, steps=cfg.eval_steps,
                          seed=rlil.eval_seed(cfg))


def transfer_rows(runs: list[Trained], designs: list[str]) -> list[dict]:
    """One row per (run, design): mean distances of the policy and of the demonstrator, and their ratio."""
    demo_m, rows = {}, []                  # demonstrator distances, once per design and set of starts
    for run in runs:
        cfg = run.cfg
        for code in designs:
            starts = (code, cfg.eval_episodes, cfg.eval_steps, rlil.eval_seed(cfg))
            if starts not in demo_m:
                demo_m[starts] = float(demonstrator_episodes(code, cfg).distance_m.mean())
            distance = float(policy_episodes(run, code).distance_m.mean())
            rows.append({"run": str(run.run_dir), "method": run.method, "seed": cfg.seed, "iteration": run.iteration,
                         "trained": names(cfg.train), "demos": names(getattr(cfg, "demos", ())),
                         "design": code, "name": sim2d.design_name(code), "seen": code in run.trained_on,
                         "distance_m": distance, "demo_distance_m": demo_m[starts],
                         "ratio": distance / demo_m[starts]})
    return rows


# ----------------------------------------------------------------------------
# The table, the heat-map and the summary
# ----------------------------------------------------------------------------
def summary(rows: list[dict]) -> list[dict]:
    """Per run, seen and unseen designs apart: mean ratio with its 95 % bootstrap CI over designs, the
    median, and how many designs reach GOOD_RATIO of their demonstrator."""
    out = []
    for run in dict.fromkeys(r["run"] for r in rows):
        for seen in (True, False):
            group = [r for r in rows if r["run"] == run and r["seen"] == seen]
            if not group:
                continue
            ratio = np.array([r["ratio"] for r in group])
            out.append({**{k: group[0][k] for k in ("run", "method", "seed", "iteration", "trained")},
                        "designs": "seen" if seen else "unseen", "n": len(ratio), "mean": float(ratio.mean()),
                        "ci": bootstrap_ci(ratio), "median": float(np.median(ratio)),
                        "good": int((ratio >= GOOD_RATIO).sum())})
    return out


def summary_markdown(rows: list[dict]) -> str:
    lines = ["ratio = policy's distance / the design's demonstrator's distance, from the same starts "
             "(the run's --eval starts); 95 % percentile-bootstrap CI of the mean over designs; "
             "seen = a design the run was trained on", "",
             f"| run | method | trained on | designs | n | mean ratio | 95 % CI | median | >= {GOOD_RATIO} |",
             "|---|---|---|---|---|---|---|---|---|"]
    for s in summary(rows):
        lines.append(f"| {s['run']} | {s['method']} seed {s['seed']} it {s['iteration']} | {s['trained']} "
                     f"| {s['designs']} | {s['n']} | {s['mean']:.2f} | [{s['ci'][0]:.2f}, {s['ci'][1]:.2f}] "
                     f"| {s['median']:.2f} | {s['good']}/{s['n']} ({100 * s['good'] / s['n']:.0f} %) |")
    return "\n".join(lines) + "\n"


def group_table(rows: list[dict]) -> str:
    """Markdown, one line per kind of run (method, training and demo designs) over its seeds: the mean
    distance on each Figure 3 design (* = trained on it; the first line: the demonstrator from the same
    starts), and on the held-out designs the mean over seeds of each run's mean ratio, with a 95 %
    bootstrap CI over seeds, and the share of designs at GOOD_RATIO of their demonstrator."""
    held_out = set(read_held_out())
    order = list(sim2d.NAMED_DESIGNS.values())          # Figure 3's designs in their order, then any other
    named = sorted({r["design"] for r in rows} - held_out, key=lambda c: (order.index(c) if c in order else 4, c))
    kinds = list(dict.fromkeys((r["method"], r["trained"], r["demos"]) for r in rows))
    lines = ["| method | trained on | demos | seeds | "
             + " | ".join(f"{sim2d.design_name(c)} (m)" for c in named)
             + " | held-out: mean ratio [95 % CI over seeds] | held-out: designs >= "
             + f"{GOOD_RATIO} |", "|---|---|---|---|" + "---|" * (len(named) + 2)]
    demo_m = [f"{np.mean([r['demo_distance_m'] for r in rows if r['design'] == c]):.2f}" for c in named]
    lines.append("| the design's demonstrator | - | - | - | " + " | ".join(demo_m) + " | 1.00 | 100 % |")
    for method, trained, demo in kinds:
        group = [r for r in rows if (r["method"], r["trained"], r["demos"]) == (method, trained, demo)]
        runs = list(dict.fromkeys(r["run"] for r in group))
        cells = []
        for c in named:
            here = [r for r in group if r["design"] == c]
            cells.append(f"{np.mean([r['distance_m'] for r in here]):.2f}" + "*" * here[0]["seen"])
        per_run = np.array([[r["ratio"] for r in group if r["run"] == run and r["design"] in held_out]
                            for run in runs])                   # [run, held-out design]
        ratio, good = per_run.mean(axis=1), (per_run >= GOOD_RATIO).mean()
        lo, hi = bootstrap_ci(ratio)
        lines.append(f"| {method} | {trained} | {demo or '-'} | {len(runs)} | " + " | ".join(cells)
                     + f" | {ratio.mean():.2f} [{lo:.2f}, {hi:.2f}] | {100 * good:.0f} % |")
    return "\n".join(lines) + "\n"


def generalist_table(generalist: list[dict], figure3: list[dict], steps: dict) -> str:
    """Markdown: the runs trained on several designs at once (their transfer.csv rows) against Figure 3's
    single-design RL+IL runs of the same seeds (figure3.csv rows), on each training design: mean
    distance over seeds with a 95 % bootstrap CI.  `steps`: {"generalist": simulator steps of one
    generalist at its last iteration, k: the single-design runs' steps at iteration k, summed over
    the designs}; the single-design columns are the iterations named in it."""
    seeds = sorted({r["seed"] for r in generalist})
    last = max(r["iteration"] for r in generalist)
    iters = sorted(k for k in steps if k != "generalist")

    def fmt(x):
        lo, hi = bootstrap_ci(np.array(x))
        return f"{np.mean(x):.2f} [{lo:.2f}, {hi:.2f}]"

    designs = list(dict.fromkeys(r["design"] for r in generalist if r["seen"]))
    lines = [f"| design | trained on all {len(designs)}, iteration {last} ({steps['generalist']:,} steps) (m) | "
             + " | ".join(f"one design each, iteration {k} ({steps[k]:,} steps for the {len(designs)}) (m)"
                          for k in iters) + " |", "|---|---|" + "---|" * len(iters)]
    for code in designs:
        name = sim2d.design_name(code)
        mine = [r["distance_m"] for r in generalist if r["design"] == code]
        cells = [fmt([r["distance_m"] for r in figure3 if r["train"] == name and r["method"] == "RL+IL"
                      and r["iteration"] == k and r["seed"] in seeds]) for k in iters]
        lines.append(f"| {name} | {fmt(mine)} | " + " | ".join(cells) + " |")
    return f"{len(seeds)} seeds ({', '.join(map(str, seeds))}) each; simulator steps include the demonstrations\n\n" \
        + "\n".join(lines) + "\n"


def read_csv(path) -> list[dict]:
    """transfer.csv's rows with their types back (write_csv's inverse)."""
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    for r in rows:
        r["seen"] = r["seen"] == "True"
        for k in ("distance_m", "demo_distance_m", "ratio"):
            r[k] = float(r[k])
        r["seed"], r["iteration"] = int(r["seed"]), int(r["iteration"])
    return rows


def write_csv(rows: list[dict], path) -> None:
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)


def save_heatmap(rows: list[dict], path) -> None:
    """One row per policy, one column per design, colour = ratio; seen cells outlined."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Rectangle
    runs = list(dict.fromkeys(r["run"] for r in rows))
    designs = list(dict.fromkeys(r["design"] for r in rows))
    cell = {(r["run"], r["design"]): r for r in rows}
    ratio = np.array([[cell[run, d]["ratio"] for d in designs] for run in runs])
    fig, ax = plt.subplots(figsize=(3 + 0.22 * len(designs), 1.6 + 0.35 * len(runs)), dpi=100)
    image = ax.imshow(ratio, cmap="viridis", vmin=0, vmax=1, aspect="auto")
    for i, run in enumerate(runs):
        for j, d in enumerate(designs):
            if cell[run, d]["seen"]:
                ax.add_patch(Rectangle((j - 0.5, i - 0.5), 1, 1, fill=False, ec="red", lw=2))
    ax.set_xticks(range(len(designs)), [sim2d.design_name(d) for d in designs], rotation=90, fontsize=7)
    labels = [f"{cell[run, designs[0]]['method']} seed {cell[run, designs[0]]['seed']} "
              f"({cell[run, designs[0]]['trained']})" for run in runs]
    ax.set_yticks(range(len(runs)), labels, fontsize=8)
    ax.set_title("distance / demonstrator's distance (red outline: a design the run was trained on)", fontsize=9)
    fig.colorbar(image, ax=ax, extend="both", fraction=0.03, pad=0.01)
    fig.tight_layout()
    fig.savefig(path, format="png")
    plt.close(fig)


def transfer(run_dirs, named=FIGURE3_DESIGNS, out="runs/transfer", force: bool = False) -> list[dict]:
    """--transfer: every run on the named designs and the held-out ones; writes and prints the outputs.
    Everything is checked before anything is evaluated."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise UsageError(f"--out {out} is a file, not a directory: name a new or existing folder")
    check_new([out / f for f in OUTPUTS], force)
    runs = [load_trained(d) for d in run_dirs]
    designs = list(dict.fromkeys(design_codes(named) + read_held_out()))
    created = not out.exists()
    try:
        out.mkdir(parents=True, exist_ok=True)
        tempfile.TemporaryFile(dir=out).close()                  # can files be written there?
    except OSError as e:
        raise UsageError(f"cannot write the folder {out} ({e.strerror or type(e).__name__}): name another --out")
    try:
        rows = transfer_rows(runs, designs)
    except BaseException:
        if created and not any(out.iterdir()):
            out.rmdir()                                          # nothing half-made is left behind
        raise
    atomic_write(out / "transfer.csv", lambda p: write_csv(rows, p))
    atomic_write(out / "transfer.png", lambda p: save_heatmap(rows, p))
    text = summary_markdown(rows)
    atomic_write(out / "transfer.md", lambda p: Path(p).write_text(text))
    print(text + f"wrote {', '.join(str(out / f) for f in OUTPUTS)}")
    return rows


# ----------------------------------------------------------------------------
# Side by side: two policies on one design from one start
# ----------------------------------------------------------------------------
def compare_trajectories(a: Trained, b: Trained, design: str) -> list[np.ndarray]:
    """Both policies on `design` from the first of run a's evaluation starts (the start --eval --gif
    draws for a): the same initial state and observation noise; (T + 1, S) states each."""
    return [policy_episodes(run, design, starts_of=a).states[0] for run in (a, b)]


def save_compare_gif(graph, trajectories, labels, path, every: int = 2) -> int:
    """Animate trajectories (T+1, S) one above the other, each view following its robot; returns the frames."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.animation import PillowWriter
    fig, axes = plt.subplots(len(trajectories), 1, figsize=(8, 0.4 + 2.8 * len(trajectories)), dpi=80)
    angles = [sim2d._wheel_angles(graph, s) for s in trajectories]
    for ax, s in zip(axes, trajectories):
        sim2d._style_axes(ax, s[0, 0] / sim2d.M_PER_CM)
        ax.set_title(" ", fontsize=12)
    fig.suptitle(" ", fontsize=13)
    fig.tight_layout()                                      # room for the titles drawn below
    drawn, frames, writer = [], 0, PillowWriter(fps=12 // every)
    with writer.saving(fig, path, dpi=fig.dpi):
        for t in range(0, len(trajectories[0]), every):
            for artist in drawn:
                artist.remove()
            drawn = []
            for ax, s, angle, label in zip(axes, trajectories, angles, labels):
                sim2d._style_axes(ax, s[t, 0] / sim2d.M_PER_CM, static=False)
                drawn += sim2d._draw_robot(ax, graph, s[t], angle[t])
                ax.set_title(f"{label}: {s[t, 0] - s[0, 0]:5.2f} m", fontsize=12)
            fig.suptitle(f"{graph.name} ({graph.code})   t = {t * sim2d.CONTROL_DT:4.1f} s", fontsize=13)
            writer.grab_frame()
            frames += 1
    plt.close(fig)
    return frames


def save_compare_png(graph, trajectories, labels, path, poses: int = 6) -> None:
    """Six snapshots per trajectory, one row each (sim2d.save_png's layout)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(len(trajectories), poses, figsize=(2.6 * poses, 0.5 + 2.5 * len(trajectories)),
                             dpi=100, squeeze=False)
    for row, s, label in zip(axes, trajectories, labels):
        angles, times = sim2d._wheel_angles(graph, s), np.linspace(0, len(s) - 1, poses).astype(int)
        for ax, t in zip(row, times):
            sim2d._style_axes(ax, s[t, 0] / sim2d.M_PER_CM, width=160.0)
            sim2d._draw_robot(ax, graph, s[t], angles[t])
            ax.set_title(f"t = {t * sim2d.CONTROL_DT:.1f} s, {s[t, 0] - s[0, 0]:.2f} m", fontsize=11)
        row[0].set_ylabel(label, fontsize=10)
    fig.suptitle(f"{graph.name} ({graph.code}), the same start", fontsize=14)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def compare(run_a, run_b, gif, design: str | None = None, png: str | None = None,
            force: bool = False) -> list[np.ndarray]:
    """--compare: both runs' policies on `design` (default run a's first training design)."""
    a, b = load_trained(run_a), load_trained(run_b)
    try:
        graph = sim2d.design_graph(design or a.cfg.train[0])
    except ValueError as e:
        raise UsageError(str(e))
    claim_output_file(gif, ".gif", "--gif", force)
    claim_output_file(png, ".png", "--png", force)
    trajectories = compare_trajectories(a, b, graph.code)
    labels = [run.label for run in (a, b)]
    for run, s in zip((a, b), trajectories):
        print(f"{run.run_dir} ({run.label}) on {graph.name}: {s[-1, 0] - s[0, 0]:.2f} m in {len(s) - 1} steps")
    atomic_write(Path(gif), lambda p: save_compare_gif(graph, trajectories, labels, p))
    print(f"wrote {gif}")
    if png:
        atomic_write(Path(png), lambda p: save_compare_png(graph, trajectories, labels, p))
        print(f"wrote {png}")
    return trajectories


def main(args) -> int:
    """train.py --transfer or --compare, with the flags parsed by train.build_parser."""
    if args.eval or args.train:
        raise UsageError("--transfer and --compare evaluate saved runs: leave out --eval and --train")
    if args.transfer and args.compare:
        raise UsageError("--transfer and --compare exclude each other")
    if args.transfer:
        if args.gif or args.png or args.design:
            raise UsageError("--gif, --png and --design go with --eval or --compare; --transfer takes --designs")
        transfer(args.transfer, args.designs or FIGURE3_DESIGNS, args.out or "runs/transfer", args.force)
        return 0
    if not args.gif:
        raise UsageError("--compare needs --gif FILE (and optionally --png FILE)")
    if args.out or args.designs:
        raise UsageError("--compare takes one --design and writes --gif and --png, not --out or --designs")
    compare(*args.compare, args.gif, args.design, args.png, args.force)
    return 0


if __name__ == "__main__":
    sys.stdout.write(held_out_text())
