"""Exercise 5 (docs/lesson.md, part 5): the adaptive learning rate with validation revert, as
modular_rlil_minimal.AdaptiveLearningRate (Sec. III-J).

    python lesson/exercises/ex5_adaptive_lr.py     # grades this file (= python lesson/grade.py ex5)

Read first: `validation_reward` and `optimize_policy` (where `check` and `revert`
are called).  Write `revert` and `check` before you read the project's class;
the grader runs yours and the project's through the same five events.
"""
import copy
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:                  # the stage files are two folders up
    sys.path.insert(0, str(ROOT))

import torch  # noqa: E402


class AdaptiveLearningRate:
    """The paper, Sec. III-J: "with a fixed or decaying learning rate, the policy
    optimization would sometimes diverge.  We used a simple adaptive learning rate
    rule to stabilize policy optimization.  At the start of each policy
    optimization phase, we compute the net reward from applying the policy for
    $T$ steps to a large set (e.g. 10x the batch size) of initial states.  This
    ``validation reward'' acts similarly to a validation loss in a supervised
    learning problem.  If the current validation reward is lower than the initial
    validation reward, the policy parameters revert to the last point when the
    validation reward was computed, the learning rate reduces, and continues."

    Our code: `check(value)` is called every validate_every steps with the
    validation reward.  A value below the phase's start value, or not finite
    (NaN, inf: math.isfinite), reverts; any other value passes, becomes `last`
    and the new point to revert to.  `revert()` loads the policy AND Adam back
    from the last snapshot (Adam's moments belong to those parameters),
    multiplies the learning rate by lr_drop (in self.lr and in every group of
    self.opt.param_groups) and counts the revert in self.reverts.  optimize_policy
    also calls `revert()` alone for a step whose loss or gradient is not finite.
    """

    def __init__(self, policy: torch.nn.Module, opt: torch.optim.Optimizer, start_value: float, lr_drop: float):
        self.policy, self.opt, self.lr_drop = policy, opt, lr_drop
        self.start = self.last = start_value            # the phase's reference, the last passed check
        self.lr, self.reverts = opt.param_groups[0]["lr"], 0
        self.snapshot()

    def snapshot(self) -> None:
        """The point to revert to: copies of the policy's and Adam's state."""
        self.saved = (copy.deepcopy(self.policy.state_dict()), copy.deepcopy(self.opt.state_dict()))

    def revert(self) -> None:
        # YOUR CODE HERE
        raise NotImplementedError("YOUR CODE HERE")

    def check(self, value: float) -> None:
        # YOUR CODE HERE (import math at the top for math.isfinite)
        raise NotImplementedError("YOUR CODE HERE")


if __name__ == "__main__":
    from lesson import grade
    sys.exit(grade.main(["ex5", "--file", __file__]))
