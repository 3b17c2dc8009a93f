"""Exercise 1 (docs/lesson.md, part 1): the reward of a transition, r(s, a, s'), as sim2d.reward.

    python lesson/exercises/ex1_reward.py      # grades this file (the same as: python lesson/grade.py ex1)

Read first: sim2d.py's docstring (the flat state vector), `split_state` and the
reward constants (W_PITCH, W_EFFORT, W_POSE, HIP_NOMINAL, KNEE_NOMINAL).  Write
the function before you read `sim2d.reward`'s body; the grader compares with it.
"""
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:                  # the stage files are two folders up
    sys.path.insert(0, str(ROOT))

import sim2d  # noqa: E402


def reward(s, a, s_next, graph: sim2d.DesignGraph):
    """r(s_t, a_t, s_t+1): one number per robot.

    The paper, Sec. III-F: "The main term in the reward function $r$ rewards the
    locomotion forward in the $+x$ direction.  Other terms with smaller relative
    weights penalize roll, pitch, yaw, deviation from $y=0$, control effort, and
    distance from a nominal pose."  It gives no weights.

    Our code (a planar world: no roll, no yaw, no sideways y) keeps the progress
    and three penalties, with sim2d's weights:

        r = (x' - x)                                          progress in metres, s_next[..., 0] - s[..., 0]
            - W_PITCH * pitch'^2                              pitch after the step, s_next[..., 2]
            - W_EFFORT * mean over the A entries of a^2       a as given (not clipped)
            - W_POSE * mean over legs of ((hip' - HIP_NOMINAL)^2 + (knee' - KNEE_NOMINAL)^2) / 2
                                                              leg angles of s_next; no legs: no term

    s, s_next: (..., S) states, a: (..., A) actions: torch tensors or numpy arrays
    (use only slicing, ** and .mean(-1), which both have).  Returns (...,).
    The leading dims may be (n,) or (T, n): index the last axis, s[..., k].
    `sim2d.split_state(s_next, graph)["leg"]` is (..., L, 4): [hip, knee, hip rate,
    knee rate] per leg; graph.n_legs is L.
    """
    # YOUR CODE HERE: the progress, then subtract the three penalties
    raise NotImplementedError("YOUR CODE HERE")


if __name__ == "__main__":
    from lesson import grade
    sys.exit(grade.main(["ex1", "--file", __file__]))
