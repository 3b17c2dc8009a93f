"""Exercise 2 (docs/lesson.md, part 2): one step of a modular network, node by node, as gnn.node_by_node.

    python lesson/exercises/ex2_message_passing.py     # grades this file (= python lesson/grade.py ex2)

Read first: gnn.py's docstring ("How a design becomes a network", steps 1-3) and
`type_net` (the layers of one module type).  Write the function before you read
`gnn.node_by_node`; the grader compares with it.
"""
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:                  # the stage files are two folders up
    sys.path.insert(0, str(ROOT))

import torch  # noqa: E402

import sim2d  # noqa: E402


def node_by_node(nets: torch.nn.ModuleDict, graph: sim2d.DesignGraph, x: list[torch.Tensor],
                 h: list[torch.Tensor] | None, rounds: int):
    """One step of a modular network, one node at a time.

    The paper, Sec. II-B: "Within a policy graph, each type of module has a
    neural network associated with it-- i.e., there is one network used to
    control all of the ``leg'' modules, and a different one used to control all
    of the ``wheel'' modules."  and "Modular policies are implemented using
    message-passing graph neural networks (GNN) [...], which allows modules to
    learn to modulate their outputs via a communication procedure in which they
    exchange information over the graph edges."  Sec. III-J: "the policy in this
    work is recurrent over time."  The paper does not write the message-passing
    equations (it uses the architecture of its earlier work); these steps are
    gnn.py's, ours:

      1. encode every node: z = tanh(W_enc x + p), W_enc = nets[kind].encode; p is
         the port vector nets.body.ports.weight[port] for a limb, 0 for the body.
      2. `rounds` times, on the star: the body sums the messages W_up z_limb
         (nets[kind].up) of all limbs and updates z_body += tanh(W_own z_body + sum)
         (nets.body.own); then every limb hears the updated body:
         z_limb += tanh(W_own z_limb + W_down z_body) (nets[kind].own, nets[kind].down).
      3. if h is given (the policy): h <- GRU(z, h) per node (nets[kind].gru(z, h)),
         and the new h is what the heads read; then read out per node:
         nets[kind].head(z), or None for a node whose type has no "head".

    graph.nodes is [(kind, port), ...]: ("body", None), then legs, then wheels.
    x: each node's input (n, in) in that order; h: each node's memory (n, H), or
    None (the model).  Returns (outputs, new memories): a list with each node's
    head output (n, out) or None, and the list of new h (None if h was None).
    """
    # YOUR CODE HERE: steps 1, 2 and 3 (kinds = [kind for kind, _ in graph.nodes] is a good start)
    raise NotImplementedError("YOUR CODE HERE")


if __name__ == "__main__":
    from lesson import grade
    sys.exit(grade.main(["ex2", "--file", __file__]))
