"""RL+IL against PPO in seconds, side by side: each seed's two runs at once, one core each.

The sample-efficiency sweep (train.py --sample-efficiency) runs whatever is queued two at a time,
so the seconds of a method depend on what ran beside it.  Here RL+IL seed S (Algorithm 1 at the
defaults, Figure 3's demos for the design) and PPO seed S (ppo_minimal at its defaults) start
together and share the machine for the same stretch; PPO stops after --seconds (it writes its
metrics at every evaluation, so what it reached by then is kept).  The rows (sample_efficiency's
CSV columns) go to --csv; `python experiments/tables.py` makes results/side_by_side.md from
results/side_by_side.csv.

    python experiments/side_by_side.py --design leg_none_wheel --seeds 3 --seconds 400 \\
        --out runs/side_by_side --csv results/side_by_side.csv
"""
from __future__ import annotations

import signal
import subprocess
import sys
from pathlib import Path

if __package__ in (None, ""):              # run as a script: the stage files are one folder up
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import sim2d                                                                                 # noqa: E402
from experiments.run_folders import UsageError, claim_output_file                            # noqa: E402
from experiments.sweeps import (SAMPLE_COLUMNS, SAMPLE_EFFICIENCY, sample_efficiency_rows,   # noqa: E402
                               write_rows_csv)

ROOT = Path(__file__).resolve().parents[1]


def commands(design: str, seed: int, out: Path, ppo_eval_every: int | None = None) -> dict:
    """method -> (run folder, train.py arguments) of one seed's pair; ppo_eval_every: PPO's
    --eval-every (None: its default)."""
    demos = SAMPLE_EFFICIENCY[design]
    rlil_dir, ppo_dir = out / f"{design}-rlil-seed{seed}", out / f"{design}-ppo-seed{seed}"
    grid = [] if ppo_eval_every is None else ["--eval-every", str(ppo_eval_every)]
    return {"RL+IL": (rlil_dir, ["--train", design, "--demos", *demos, "--seed", str(seed), "--out", str(rlil_dir)]),
            "PPO": (ppo_dir, ["--method", "ppo", "--train", design, *grid, "--seed", str(seed), "--out", str(ppo_dir)])}


def run_pair(pair: dict, seconds: float) -> None:
    """Start both runs at once; PPO is stopped (SIGTERM, as Ctrl-C would) after `seconds`.  If
    this process is stopped first, both runs are stopped with it."""
    procs = {m: subprocess.Popen([sys.executable, str(ROOT / "train.py"), *args], stdout=subprocess.DEVNULL,
                                 stderr=subprocess.PIPE if m == "RL+IL" else subprocess.DEVNULL, text=True)
             for m, (_, args) in pair.items()}
    try:
        try:
            procs["PPO"].wait(timeout=seconds)
        except subprocess.TimeoutExpired:
            procs["PPO"].send_signal(signal.SIGTERM)
            procs["PPO"].wait()
        _, err = procs["RL+IL"].communicate()
    finally:
        for proc in procs.values():
            if proc.poll() is None:
                proc.send_signal(signal.SIGTERM)
                proc.wait()
    if procs["RL+IL"].returncode != 0:
        raise UsageError(f"the RL+IL run failed: {(err.strip().splitlines() or ['no message'])[-1]}")


def main(argv=None) -> int:
    parser = sim2d.CliParser(description=__doc__.split("\n")[0])
    parser.add_argument("--design", default="leg_none_wheel", choices=sorted(SAMPLE_EFFICIENCY))
    parser.add_argument("--seeds", type=int, default=3, help="seeds 0..N-1, one pair each (default 3)")
    parser.add_argument("--seconds", type=float, default=400.0, help="PPO's time per pair (default 400)")
    parser.add_argument("--ppo-eval-every", type=int, default=None,
                        help="PPO's simulator steps between evaluations (default: PPO's own, 50,000); its "
                             "evaluations count in its seconds, as RL+IL's do")
    parser.add_argument("--out", type=Path, default=Path("runs/side_by_side"), help="folder of the run folders")
    parser.add_argument("--csv", type=Path, default=Path("results/side_by_side.csv"))
    parser.add_argument("--force", action="store_true", help="replace an existing --csv")
    args = parser.parse_args(argv)
    if not 1 <= args.seeds <= 100 or not 1 <= args.seconds <= 36000:
        parser.error("--seeds takes 1 to 100 and --seconds 1 to 36000")
    try:
        claim_output_file(args.csv, ".csv", "--csv", args.force)
        pairs = [commands(args.design, seed, args.out, args.ppo_eval_every) for seed in range(args.seeds)]
        taken = [d for pair in pairs for d, _ in pair.values() if d.exists()]
        if taken:                                           # never over a run the user has
            raise UsageError(f"{taken[0]} exists: name another --out (a run folder is never replaced here)")
        runs = []
        for seed, pair in enumerate(pairs):
            print(f"seed {seed}: RL+IL and PPO side by side", flush=True)
            run_pair(pair, args.seconds)
            runs += [{"train": args.design, "method": m, "seed": seed, "dir": d} for m, (d, _) in pair.items()]
    except UsageError as e:
        parser.error(str(e))
    rows = sample_efficiency_rows(runs)
    write_rows_csv(args.csv, SAMPLE_COLUMNS, rows)
    print(f"wrote {args.csv} ({len(rows)} rows)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
