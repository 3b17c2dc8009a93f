"""Exercise 3 (docs/lesson.md, part 3): L_RL through a T-step model roll-out, as
modular_rlil_minimal.rollout (Algorithm 1 lines 10-15) and line 16 of rl_loss.

    python lesson/exercises/ex3_rl_loss.py     # grades this file (= python lesson/grade.py ex3)

Read first: Algorithm 1 (modular_rlil_minimal.py's docstring and `algorithm1`),
`gnn.PolicyOnDesign.act`, `gnn.ModelOnDesign.__call__`, `sim2d.observe` and
`sim2d.obs_noise_like`.  Write the function before you read `rollout`; the grader
compares with it.
"""
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:                  # the stage files are two folders up
    sys.path.insert(0, str(ROOT))

import torch  # noqa: E402

import gnn  # noqa: E402
import sim2d  # noqa: E402


def rl_loss_of_batch(policy: gnn.ModularPolicy, model: gnn.ModularModel, s0: torch.Tensor, h0: torch.Tensor,
                     graph: sim2d.DesignGraph, horizon: int, deterministic: bool = False):
    """L_RL of one batch of initial states s0 (B, S) with their policy hidden states h0 (nodes, B, H).

    The paper, eqn. (RL_loss):
        \\mathcal{L}_{\\textrm{RL}} =  - \\mathbb{E}_{a \\sim \\pi_\\theta} \\sum_{t=1}^T r (\\tilde s_t, a_t,  d_\\textrm{train}).
    "the approximate state evolves according to the model $\\tilde s_{t+1} = \\tilde
    f_\\phi(\\tilde s_t, a_t, d_\\textrm{train})$. [...] Actions are sampled according to
    the policy, $a_t \\sim  \\pi_\\theta(a_t|o_t, d_\\textrm{train})$, and observations from
    the observation function $o_t \\sim O(\\tilde s_t)$."
    Algorithm 1, after line 9 ("Sample a batch of initial states $s_0$ with
    hidden-state vectors from $\\mathcal{B}$, and set hidden state of $\\pi_\\theta$"):
        10  $R=0$, $\\tilde s_0 = s_0$
        12  for t = 1 ... T:
        13      $a_t \\sim \\pi_\\theta(a_t|O(\\tilde s_t))$, $\\tilde s_{t+1} = \\tilde f_\\phi(\\tilde s_t, a_t)$
        14      $R = R+ r(\\tilde s_t, a_t)$
        16  $\\mathcal{L}_{\\textrm{RL}} = -R$

    Our code: the reward of a step is sim2d.reward(s, a, s_next, graph) (it needs
    the next state for the progress), and the expectation over the batch is its
    mean: L_RL = -R.mean() over the B robots, one number.

    pi = policy.on_design(graph): pi.act(obs, h, deterministic) -> (a (B, A), h).
    f = model.on_design(graph): f(s, a) -> s_next (B, S).  Each step, draw first
    the observation noise, noise = None if deterministic else
    sim2d.obs_noise_like(s, graph), observe with sim2d.observe(s, graph, noise),
    then act: the grader replays the same seeded draws in that order.
    Keep everything differentiable (no .item(), no torch.no_grad()): the policy
    learns from dL_RL/dtheta through every model step.

    Returns (L_RL (), s_T (B, S) the state after T model steps, h_T the policy's memory then).
    """
    # YOUR CODE HERE: line 10, the loop of lines 12-15, line 16.  Start with
    #     pi, f = policy.on_design(graph), model.on_design(graph)   # the layers gathered along the nodes once
    raise NotImplementedError("YOUR CODE HERE")


if __name__ == "__main__":
    from lesson import grade
    sys.exit(grade.main(["ex3", "--file", __file__]))
