"""Exercise 4 (docs/lesson.md, part 4): L_IL with the entropy penalty, and L_RLIL, as
modular_rlil_minimal.il_loss and rlil_loss (called as optimize_policy's line 19 calls it).

    python lesson/exercises/ex4_il_loss.py     # grades this file (= python lesson/grade.py ex4)

Read first: demos.DemoData (what T^i holds), `gnn.ModularPolicy.sequence_log_prob`,
`gnn.gaussian_log_prob` and `gnn.gaussian_entropy`, and lines 17-19 in
`optimize_policy`.  Write both functions before you read `il_loss`; the grader
compares with the project's.
"""
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:                  # the stage files are two folders up
    sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

import gnn  # noqa: E402
from modular_rlil_minimal import demo_windows  # noqa: E402  (given: the sampling is not the lesson)


def il_loss(policy: gnn.ModularPolicy, demo_data: dict, cfg, rng: np.random.Generator):
    """(L_IL, entropy) on a batch of demonstration windows of every demo design.

    The paper, eqn. (IL_loss):
        \\mathcal{L}_{\\textrm{IL}} = - \\sum_{d\\in D_{\\textrm{demo}}}
        \\sum_{(o,a)  \\in \\Tau_{\\textrm{demo}}}     \\log( \\pi_\\theta(a | o, d)  ).
    "This IL loss is the joint log likelihood that the policy will produce the
    actions from the dataset when given the observations from the dataset."
    Sec. III-J: "we penalize the entropy of the actions output by the policy when
    given observations from the demonstration dataset, that is, an additional
    loss term of the form $\\sum_{o \\in \\Tau_{\\textrm{demo}}} H(\\pi_\\theta(a|o)$ where
    $H(\\cdot)$ is the entropy function."

    Our code: per design, a batch of cfg.il_batch windows of cfg.il_window
    consecutive (o, a) pairs (`demo_windows`, given) runs through the recurrent
    policy from a zero memory; L_IL is minus the MEAN of log pi over the pairs
    (the sum divided by their number, a constant that lambda absorbs), summed
    over designs; the entropy is the mean entropy over the same pairs, summed
    over designs.  policy.sequence_log_prob(obs, actions, graph) returns both,
    (n, W) each.  Both results must keep their gradient (they train the policy).
    """
    loss, entropy = 0.0, 0.0
    for design, demo in demo_data.items():
        obs, actions, graph = demo_windows(design, demo, cfg, rng)
        # YOUR CODE HERE: this design's log pi(a | o, d) and entropy, added to loss and entropy
        raise NotImplementedError("YOUR CODE HERE")
    return loss, entropy


def rlil_loss(loss_rl, loss_il, entropy, il_weight: float, entropy_weight: float):
    """L, the loss the policy phase minimises.

    The paper, eqn. (RLIL_loss):
        \\mathcal{L} &= \\mathcal{L}_{\\textrm{RL}} + \\lambda \\mathcal{L}_{\\textrm{IL}}.
    plus the entropy penalty of Sec. III-J (quoted in il_loss).  The paper gives
    neither the penalty's weight nor where it goes; our code (optimize_policy,
    line 19) adds entropy_weight * entropy to L_IL, inside lambda's bracket, so the
    penalty decays with lambda.  il_weight is lambda.
    """
    # YOUR CODE HERE
    raise NotImplementedError("YOUR CODE HERE")


if __name__ == "__main__":
    from lesson import grade
    sys.exit(grade.main(["ex4", "--file", __file__]))
