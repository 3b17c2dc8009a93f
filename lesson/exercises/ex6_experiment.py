"""Exercise 6 (docs/lesson.md, part 6): an experiment.  Do the car's own demonstrations help the car?

1. Before you run anything, write your prediction in PREDICTION below.
2. Run the class demo with and without demonstrations (about 10 s each):
       python train.py --train car --preset tiny --out runs/lesson/car-rl
       python train.py --train car --demos car --preset tiny --out runs/lesson/car-rlil
3. Write `auc_difference` and grade it:
       python lesson/exercises/ex6_experiment.py         # (= python lesson/grade.py ex6)
4. Compare your runs with the committed ones (results/class_demo.csv, seeds 0-4):
       python lesson/exercises/ex6_experiment.py runs/lesson/car-rl runs/lesson/car-rlil
"""
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:                  # the stage files are two folders up
    sys.path.insert(0, str(ROOT))

# Before you run: "RL+IL higher", "RL higher" or "about the same" (mean distance over iterations 1-2), and why.
PREDICTION = ""


def read_iterations(run) -> list[dict]:
    """Given: the metrics rows of a run directory (or of its metrics.json), one dict per iteration,
    iteration 0 first; each has "iteration" and "distance_m" (metres in eval_steps control steps)."""
    path = Path(run)
    return json.loads((path / "metrics.json" if path.is_dir() else path).read_text())["iterations"]


def auc_difference(rl_run, rlil_run) -> float:
    """RL+IL - RL of the area under the learning curve, in metres.

    The paper, Sec. IV: "However, since the car is able to learn to locomote
    nearly optimally in a single iteration, the car demonstrations had little
    effect on the car policy convergence.  This result suggests that when the
    learning task is less complex (lower dimensional, smoother), the
    demonstrations have less of an effect, but do not impede the RL+IL algorithm."

    Our code (README, experiments/stats.area_under_curve): a run's area under the
    curve is its mean distance over iterations 1..N (iteration 0 is before any
    policy optimisation: lines 1-2 only); above 0 means the demos helped.
    """
    # YOUR CODE HERE: read_iterations(rl_run) and read_iterations(rlil_run) give the rows
    raise NotImplementedError("YOUR CODE HERE")


if __name__ == "__main__":
    from lesson import grade
    if len(sys.argv) == 3:                     # two runs: the comparison
        sys.exit(grade.experiment_report(auc_difference, PREDICTION, sys.argv[1], sys.argv[2]))
    if len(sys.argv) != 1:
        sys.exit(print("usage: python lesson/exercises/ex6_experiment.py [RL_RUN RLIL_RUN]", file=sys.stderr) or 2)
    sys.exit(grade.main(["ex6", "--file", __file__]))
