"""Modular graph neural networks: the policy pi_theta(a | o, d) and the model f~_phi(s, a, d)
(and, for the PPO baseline of ppo_minimal.py, a critic V_psi(o, d)).

Paper (Whitman & Choset, "Learning Modular Robot Locomotion from
Demonstrations"): Sec. II-B "Modular policies" (one network per module type,
message passing over the design graph), Sec. III-C "Train approximate dynamics
model" (the same modular structure, predicting the change of state) and
Sec. III-J "Implementation details" (the policy is recurrent over time).

    python gnn.py                           # parameter counts per module type and per design
    python tools/bench.py --networks        # speed of policy updates through model roll-outs, of model
                                            # fitting, and of the default run's policy, BC and model steps
    python tools/bench.py --profile policy  # operators of the default run's policy step, by self CPU time

How a design becomes a network
------------------------------
The design graph is a star: node 0 is the body, nodes 1.. are the legs, then
the wheels (sim2d's order of state and action).  Each module type (body, leg,
wheel) owns one set of layers, shared by every module of that type in every
design, so the parameter count does not depend on the design.  One step:

  1. encode every node: z = tanh(W_enc x + p), with x the node's input and p
     a learned vector of the body port the limb is plugged into (the same as
     appending a one-hot port code to x; zero for the body).  Messages carry
     p, so the body can tell a front leg from a rear one.
  2. message passing, `rounds` times on the star: each limb sends W_up z_limb,
     the body updates z_body += tanh(W_own z_body + sum of messages); then each
     limb updates z_limb += tanh(W_own z_limb + W_down z_body).
  3. read out per node: the model decodes the node's change of state; the policy
     first updates the node's memory h <- GRU(z, h), then decodes a Gaussian
     over the node's joint-velocity commands.

A batch holds many robots of one design.  `gather_layers` gathers each per-type layer
along the design's node list into a (nodes, in, out) stack, once per roll-out
or batch of windows, so each layer above is one batched matrix product
(torch.baddbmm) over (nodes, robots, features) for all module types at once:
no loop over robots, nodes or types.  Types whose inputs or outputs are
narrower are zero-padded to the widest.  Gathering is differentiable, so the
parameters stay one set per type (`nets`), and module types a design lacks
get no gradient.  `node_by_node` writes one step plainly, node by node (read
it first); the classes' `forward_node_by_node` use it, and tests/test_gnn.py
checks that the batched path computes the same numbers.  Node tensors of the
batched path, the policy's memory among them, are node-major: (nodes, robots,
features).
"""
from __future__ import annotations

import argparse
import functools
import math
from dataclasses import dataclass

import torch
import torch.nn as nn

import sim2d
from sim2d import (BODY_DIM, BODY_OBS_DIM, LEG_ACT_DIM, LEG_DIM, LEG_OBS_DIM,
                   WHEEL_ACT_DIM, WHEEL_DIM, WHEEL_OBS_DIM)


@dataclass
class GNNConfig:
    """The networks' sizes (train.py's --gnn-<name> flags; the docstring under a field is its help)."""

    hidden: int = 64
    """width of every per-type layer, node state and memory; 32-256"""
    rounds: int = 2
    """message-passing rounds per step; 1-4 (1 lets each limb hear all others)"""
    log_std_min: float = -2.5
    """policy log-std lower bound (std 0.08 in normalised action units)"""
    log_std_max: float = 0.0
    """policy log-std upper bound (std 1, half the action range)"""


TYPES = ("body", "leg", "wheel")
N_PORTS = 6
# The policy divides observations by fixed typical magnitudes (not fitted): angles (rad)
# and height (m) are O(1) already; joint rates are divided by the joints' speed at
# action 1 (sim2d.LEG_MAX_SPEED, WHEEL_MAX_SPEED) and the body's pitch rate by 3 rad/s.
OBS_SCALE = {"body": torch.tensor([1.0, 1.0, 1 / 3.0]),                                 # y, pitch, pitch rate
             "leg": torch.tensor([1.0, 1.0, 1 / sim2d.LEG_MAX_SPEED, 1 / sim2d.LEG_MAX_SPEED]),
             "wheel": torch.tensor([1 / sim2d.WHEEL_MAX_SPEED])}


# ----------------------------------------------------------------------------
# Small pure helpers
# ----------------------------------------------------------------------------
def gaussian_log_prob(mean, log_std, a) -> torch.Tensor:
    """log N(a; mean, exp(log_std)^2) summed over the last (action) dim: (...,).

    Per dim: -((a - mean) / std)^2 / 2 - log std - log(2 pi) / 2.
    """
    z = (a - mean) * torch.exp(-log_std)
    return (-0.5 * z ** 2 - log_std - 0.5 * math.log(2 * math.pi)).sum(-1)


def gaussian_entropy(log_std) -> torch.Tensor:
    """Entropy of N(mean, exp(log_std)^2) summed over the last dim: (...,).

    Per dim: log std + log(2 pi e) / 2.
    """
    return (log_std + 0.5 * math.log(2 * math.pi * math.e)).sum(-1)


def node_types(graph) -> list[str]:
    """The module types a design has, in node order: "body" first, then "leg" and/or "wheel"."""
    return ["body"] + [k for k, n in (("leg", graph.n_legs), ("wheel", graph.n_wheels)) if n]


def node_state(s, graph) -> dict:
    """Flat state (n, S) -> {"body": (n, 1, 6), "leg": (n, L, 4), "wheel": (n, W, 1)}."""
    return {**sim2d.split_state(s, graph), "body": s[:, None, :BODY_DIM]}


def node_obs(obs: dict) -> list:
    """`observe`'s dict -> each node's observation (n, F) in node order (body, legs, wheels)."""
    return [obs["body"]] + list(obs["leg"].unbind(1)) + list(obs["wheel"].unbind(1))


def count_parameters(module: nn.Module) -> int:
    return sum(p.numel() for p in module.parameters())


# ----------------------------------------------------------------------------
# Per-type networks, and one step of a modular network node by node (read this first)
# ----------------------------------------------------------------------------
def type_net(kind: str, in_dim: int, out_dim: int, hidden: int, recurrent: bool) -> nn.ModuleDict:
    """The layers of one module type; every module of that type, in every design, uses them."""
    net = nn.ModuleDict({"encode": nn.Linear(in_dim, hidden),       # W_enc: node input -> node state z
                         "own": nn.Linear(hidden, hidden)})         # W_own: a node's own part of its update
    if kind == "body":
        net["ports"] = nn.Embedding(N_PORTS, hidden)                 # p: one vector per body port
    else:
        net["up"] = nn.Linear(hidden, hidden, bias=False)            # W_up: message limb -> body
        net["down"] = nn.Linear(hidden, hidden, bias=False)          # W_down: message body -> limb
    if recurrent:
        net["gru"] = nn.GRUCell(hidden, hidden)                      # node memory h
    if out_dim:
        net["head"] = nn.Linear(hidden, out_dim)                     # node state -> node output
    return net


def node_by_node(nets: nn.ModuleDict, graph, x: list, h: list | None, rounds: int):
    """One step of a modular network, written plainly, one node at a time (docstring steps 1-3).

    x: each node's input (n, in) in node order (body, legs, wheels); h: each
    node's memory (n, H) for the policy, None for the model and the critic.
    Returns each node's head output (n, out), None for a node without a head
    (the policy's body), and the new memories (None without memory).  The
    batched path below (`gather_layers`) computes the same numbers for all nodes at
    once; tests/test_gnn.py checks that it does.
    """
    kinds = [kind for kind, _ in graph.nodes]
    z = [torch.tanh(nets[kind].encode(xi) + (nets.body.ports.weight[port] if port is not None else 0))
         for (kind, port), xi in zip(graph.nodes, x)]                               # 1. encode, + port vector
    for _ in range(rounds):                                                          # 2. messages on the star
        inbox = sum(nets[kind].up(zi) for kind, zi in zip(kinds[1:], z[1:]))        # limbs -> body
        body = z[0] + torch.tanh(nets.body.own(z[0]) + inbox)
        z = [body] + [zi + torch.tanh(nets[kind].own(zi) + nets[kind].down(body))  # body -> limbs
                      for kind, zi in zip(kinds[1:], z[1:])]
    if h is not None:                                                                # 3. memory: h <- GRU(z, h)
        z = h = [nets[kind].gru(zi, hi) for kind, zi, hi in zip(kinds, z, h)]
    return [nets[kind].head(zi) if "head" in nets[kind] else None for kind, zi in zip(kinds, z)], h  # 3. read out

# ----------------------------------------------------------------------------
# The modular policy pi_theta(a | o, d), recurrent over time
# ----------------------------------------------------------------------------
def sample_action(mean, log_std, deterministic: bool):
    """a ~ N(mean, exp(log_std)^2), reparameterised (or the mean)."""
    return mean if deterministic else mean + torch.exp(log_std) * torch.randn_like(mean)


class ModularPolicy(nn.Module):
    """pi_theta(a | o, d): a Gaussian over each joint's normalised velocity command.

    Every node keeps a memory h, updated by its type's GRUCell after message
    passing.  The memory is an explicit tensor (1 + L + W, n, hidden), node
    major like every node tensor here: reset
    with `initial_hidden`, read from what `forward`/`act` return, set by
    passing it in (detach it between batches for truncated BPTT).  A node's
    input is its scaled observation and its memory, so messages carry memory.
    The log-std is state-dependent: a second output per joint, squashed into
    [log_std_min, log_std_max] by a sigmoid (about mid-way at initialisation).

    `on_design(graph)` gathers the layers along a design's nodes once, for many
    steps (`PolicyOnDesign`); `forward` and `act` gather them for one step.
    """

    def __init__(self, cfg: GNNConfig = GNNConfig()):
        super().__init__()
        self.cfg = cfg
        H = cfg.hidden
        self.nets = nn.ModuleDict({                      # limb heads: mean and raw log-std per joint
            "body": type_net("body", BODY_OBS_DIM + H, 0, H, recurrent=True),
            "leg": type_net("leg", LEG_OBS_DIM + H, 2 * LEG_ACT_DIM, H, recurrent=True),
            "wheel": type_net("wheel", WHEEL_OBS_DIM + H, 2 * WHEEL_ACT_DIM, H, recurrent=True)})

    def initial_hidden(self, n: int, graph) -> torch.Tensor:
        """h_0 = 0: (1 + n_legs + n_wheels, n, hidden), node 0 the body, then the legs, then the wheels."""
        return torch.zeros(1 + graph.n_legs + graph.n_wheels, n, self.cfg.hidden)

    def on_design(self, graph) -> "PolicyOnDesign":
        return PolicyOnDesign(self, graph)

    def forward(self, obs: dict, graph, hidden):
        """One control step from `observe`'s dict of tensors: mean (n, A), log_std (n, A), next hidden."""
        return self.on_design(graph).step(obs, hidden)                                   # (n, A), (n, A), (N, n, H)

    def forward_node_by_node(self, obs: dict, graph, hidden):
        """`forward` written plainly with `node_by_node` (what the batched `on_design` path computes).
        A node's input is its scaled observation and its memory; each limb's head gives the
        mean and the raw log-std of its joints, in sim2d's action order."""
        x = [torch.cat([o * OBS_SCALE[kind], h], -1) for (kind, _), o, h in zip(graph.nodes, node_obs(obs), hidden)]
        out, h = node_by_node(self.nets, graph, x, list(hidden), self.cfg.rounds)
        mean, raw = zip(*(y.chunk(2, -1) for y in out[1:]))                             # limbs only
        lo, hi = self.cfg.log_std_min, self.cfg.log_std_max
        return torch.cat(mean, -1), lo + (hi - lo) * torch.sigmoid(torch.cat(raw, -1)), torch.stack(h)

    def act(self, obs: dict, graph, hidden, deterministic: bool = False):
        """a_t ~ pi_theta(. | o_<=t), reparameterised (or the mean), and the next hidden.

        Not clipped: the world clips actions to [-1, 1], and so does the model.
        """
        mean, log_std, hidden = self(obs, graph, hidden)
        return sample_action(mean, log_std, deterministic), hidden                          # (n, A)

    def sequence_log_prob(self, obs_seq: dict, actions_seq, graph, hidden=None):
        """Returns (log pi(a_t | o_<=t), entropy of pi(. | o_<=t)), each (n, T), running the recurrence.

        obs_seq: `observe`'s dict with a time axis, values (n, T, ...); actions_seq: (n, T, A);
        hidden: h_0 (zeros if None).  Feeds eqn. (IL_loss) (Sec. III-E) and the entropy
        penalty on demonstration observations (Sec. III-J).
        """
        n, T = actions_seq.shape[:2]
        pi = self.on_design(graph)
        h = self.initial_hidden(n, graph) if hidden is None else hidden                    # (N, n, H)
        means, log_stds = [], []
        for t in range(T):
            mean, log_std, h = pi.step({k: v[:, t] for k, v in obs_seq.items()}, h)
            means.append(mean)
            log_stds.append(log_std)
        mean, log_std = torch.stack(means, 1), torch.stack(log_stds, 1)                    # (n, T, A)
        return gaussian_log_prob(mean, log_std, actions_seq), gaussian_entropy(log_std)     # (n, T) x 2


class ModularValue(nn.Module):
    """V_psi(o, d): the value of an observation, for the model-free baseline (ppo_minimal.py).

    Not in the paper, whose Algorithm 1 needs no critic.  The same modular
    structure as the policy without the memory: one set of layers per module
    type, encode + message passing on the design graph, a scalar per node;
    V = the mean of the node scalars, so its scale does not grow with the
    number of limbs.
    """

    def __init__(self, cfg: GNNConfig = GNNConfig()):
        super().__init__()
        self.cfg = cfg
        self.nets = nn.ModuleDict({"body": type_net("body", BODY_OBS_DIM, 1, cfg.hidden, recurrent=False),
                                   "leg": type_net("leg", LEG_OBS_DIM, 1, cfg.hidden, recurrent=False),
                                   "wheel": type_net("wheel", WHEEL_OBS_DIM, 1, cfg.hidden, recurrent=False)})

    def forward_node_by_node(self, obs: dict, graph) -> torch.Tensor:
        """`forward` written plainly with `node_by_node`: V (n,), the mean of the node scalars."""
        x = [o * OBS_SCALE[kind] for (kind, _), o in zip(graph.nodes, node_obs(obs))]
        return torch.stack(node_by_node(self.nets, graph, x, None, self.cfg.rounds)[0]).mean((0, 2))

    def forward(self, obs: dict, graph) -> torch.Tensor:
        """`observe`'s dict of tensors (n, ...) -> V (n,)."""
        w = gather_layers(self.nets, graph, self.cfg.rounds, lambda l: pad_to(l.weight, OBS_WIDTH))
        o = nodes_first(obs, node_index(graph).kinds, OBS_WIDTH) * node_obs_scale(graph)    # (N, n, O)
        return read_out(w, propagate(w, encode_nodes(w, o))).mean((0, 2))                  # (n,)


# ----------------------------------------------------------------------------
# The modular dynamics model f~_phi(s, a, d)
# ----------------------------------------------------------------------------
class Normalizer(nn.Module):
    """Per-feature mean and std, fitted from data and saved in the state_dict."""

    def __init__(self, dim: int):
        super().__init__()
        self.register_buffer("mean", torch.zeros(dim))
        self.register_buffer("std", torch.ones(dim))

    def fit(self, x):
        """x: (rows, dim).  A feature that never varies gets std 1e-6 instead of 0."""
        self.mean.copy_(x.mean(0))
        self.std.copy_(x.std(0).clamp_min(1e-6))


class ModularModel(nn.Module):
    """f~_phi(s, a, d) = s + Delta(s, a, d): predicts every module's change of state.

    Node inputs: body [y, pitch, vx, vy, pitch_rate] (x is left out, so the
    prediction is the same wherever the robot is), leg [4 joint states,
    2 actions], wheel [rate, action]; actions are clipped to [-1, 1] as the
    world clips them.  Node outputs: body [dx, dy, dpitch, dvx, dvy,
    dpitch_rate], leg 4 joint changes, wheel 1.  Inputs and outputs are
    normalised per type with statistics from `fit_normalization`.

    `on_design(graph)` gathers the layers along a design's nodes once, for many
    steps (`ModelOnDesign`); `forward` and `loss` gather them for one call.
    """

    OUT_DIMS = {"body": BODY_DIM, "leg": LEG_DIM, "wheel": WHEEL_DIM}

    def __init__(self, cfg: GNNConfig = GNNConfig()):
        super().__init__()
        self.cfg = cfg
        self.in_dims = {"body": BODY_DIM - 1, "leg": LEG_DIM + LEG_ACT_DIM, "wheel": WHEEL_DIM + WHEEL_ACT_DIM}
        self.nets = nn.ModuleDict({k: type_net(k, self.in_dims[k], self.OUT_DIMS[k], cfg.hidden,
                                               recurrent=False) for k in TYPES})
        self.norm_in = nn.ModuleDict({k: Normalizer(d) for k, d in self.in_dims.items()})
        self.norm_out = nn.ModuleDict({k: Normalizer(d) for k, d in self.OUT_DIMS.items()})

    def inputs(self, s, a, graph) -> dict:
        """Raw node inputs: {"body": (n, 1, 5), "leg": (n, L, 6), "wheel": (n, W, 2)}."""
        ps, pa = node_state(s, graph), sim2d.split_action(a.clamp(-1.0, 1.0), graph)
        return {"body": ps["body"][..., 1:],                                                # drop x
                "leg": torch.cat([ps["leg"], pa["leg"]], -1),
                "wheel": torch.cat([ps["wheel"], pa["wheel"]], -1)}

    def on_design(self, graph) -> "ModelOnDesign":
        return ModelOnDesign(self, graph)

    def forward(self, s, a, graph) -> torch.Tensor:
        """s_t+1 = s_t + Delta(s_t, a_t): (n, S), differentiable in s and a."""
        return self.on_design(graph)(s, a)

    def forward_node_by_node(self, s, a, graph) -> torch.Tensor:
        """`forward` written plainly with `node_by_node`: normalised node inputs -> each node's
        normalised change of state, un-normalised and added to s: (n, S)."""
        raw, kinds = self.inputs(s, a, graph), [kind for kind, _ in graph.nodes]
        x = [raw["body"][:, 0]] + list(raw["leg"].unbind(1)) + list(raw["wheel"].unbind(1))
        x = [(xi - self.norm_in[kind].mean) / self.norm_in[kind].std for kind, xi in zip(kinds, x)]
        out, _ = node_by_node(self.nets, graph, x, None, self.cfg.rounds)
        return s + torch.cat([y * self.norm_out[kind].std + self.norm_out[kind].mean for kind, y in zip(kinds, out)], -1)

    def change_stats(self, graph):
        """The fitted mean and std of each state entry's change, in sim2d's flat layout: (S,) each."""
        kinds = [k for k, _ in graph.nodes]
        return (torch.cat([self.norm_out[k].mean for k in kinds]), torch.cat([self.norm_out[k].std for k in kinds]))

    def state_error(self, s_pred, s_true, graph) -> torch.Tensor:
        """Mean squared error of predicted against true states, each entry divided by the fitted
        std of its change: for a one-step prediction the same number as `loss`."""
        return ((s_pred - s_true) / self.change_stats(graph)[1]).pow(2).sum() / s_true.numel()

    def loss(self, s, a, s_next, graph) -> torch.Tensor:
        """Mean squared error of the normalised change of state, averaged over the n x S state entries."""
        f = self.on_design(graph)
        target = (s_next - s - f.out_mean) / f.out_std                                      # (n, S)
        return (f.delta_normalised(s, a) - target).pow(2).sum() / s.numel()

    @torch.no_grad()
    def fit_normalization(self, batches):
        """Fit per-type input and output statistics from [(graph, s, a, s_next), ...] of tensors.

        Statistics pool all modules of a type across all batches; a type absent
        from the data keeps mean 0 and std 1.
        """
        xs, ds = {k: [] for k in TYPES}, {k: [] for k in TYPES}
        for graph, s, a, s_next in batches:
            x, d = self.inputs(s, a, graph), node_state(s_next - s, graph)
            for k in TYPES:
                xs[k].append(x[k].reshape(-1, self.in_dims[k]))
                ds[k].append(d[k].reshape(-1, self.OUT_DIMS[k]))
        for k in TYPES:
            x, d = torch.cat(xs[k]), torch.cat(ds[k])
            if len(x) > 1:
                self.norm_in[k].fit(x)
                self.norm_out[k].fit(d)


# ----------------------------------------------------------------------------
# The batched path training runs: the same layers gathered along one design's nodes,
# every node's own type's layer in one batched product (checked equal to node_by_node)
# ----------------------------------------------------------------------------
@dataclass(frozen=True)
class NodeIndex:
    """Index tensors of one design graph, made once (`node_index`), used at every step."""

    kinds: tuple            # module types present, in node order: ("body", "leg"?, "wheel"?)
    type_of: torch.Tensor   # (N,) position in `kinds` of each node's type
    limb_type: torch.Tensor  # (N - 1,) position in kinds[1:] of each limb's type
    ports: torch.Tensor     # (N - 1,) body port each limb is plugged into


@functools.lru_cache(maxsize=None)
def node_index(graph) -> NodeIndex:
    kinds = tuple(node_types(graph))
    type_of = torch.tensor([kinds.index(kind) for kind, _ in graph.nodes])
    return NodeIndex(kinds, type_of, type_of[1:] - 1, torch.tensor([p for _, p in graph.nodes[1:]]))


def pad_to(x, size: int, dim: int = -1, value: float = 0.0) -> torch.Tensor:
    """x with `value` appended along its last dimension (dim=-1) or its rows (dim=0) up to `size`."""
    extra = size - x.shape[dim]
    if extra == 0:
        return x
    return nn.functional.pad(x, (0, extra) if dim == -1 or x.dim() == 1 else (0, 0, 0, extra), value=value)


def per_node(tensors: list, type_index: torch.Tensor) -> torch.Tensor:
    """[one tensor per type] -> (nodes, ...): each node gets its type's tensor (a differentiable gather)."""
    return torch.stack(tensors)[type_index]


def per_node_linear(layers: list, type_index, weight=None, bias=None):
    """Weights (nodes, in, out) and biases (nodes, 1, out) for torch.baddbmm: each node its type's layer.

    weight(layer) / bias(layer) return the (out, in) / (out,) to stack (default: the layer's own),
    so types with different input or output sizes can be zero-padded to one shape.
    """
    w = per_node([weight(l) if weight else l.weight for l in layers], type_index).transpose(1, 2)
    if bias is None and layers[0].bias is None:
        return w, None
    return w, per_node([bias(l) if bias else l.bias for l in layers], type_index)[:, None]


@dataclass
class NodeLayers:
    """A modular network's layers gathered along one design's nodes (node 0 the body, then the limbs).

    Each per-type layer becomes a (nodes, in, out) stack, so one torch.baddbmm
    applies every node's own type's layer at once; node tensors are
    node-major, (nodes, robots, features).  Gathering is differentiable:
    gradients reach the per-type parameters.  Made once per roll-out or batch
    of windows, since the weights do not change within one.
    """

    encode: tuple            # W_enc (N, in, H), b_enc + port vector p (N, 1, H)
    own: tuple               # W_own (N, H, H), b_own (N, 1, H)
    up: torch.Tensor         # W_up (N - 1, H, H), limbs only
    down: torch.Tensor       # W_down (N - 1, H, H), limbs only
    head: tuple              # W_head (N or N - 1, H, out), b_head (., 1, out)
    gru: tuple | None        # W_ih (N, H, 3H), b_ih, W_hh (N, H, 3H), b_hh, for the policy's memory
    rounds: int


def gather_layers(nets: nn.ModuleDict, graph, rounds: int, encode_weight=None, head_weight=None,
                  head_bias=None, limb_heads: bool = False) -> NodeLayers:
    """Gather `nets`' per-type layers along the design's nodes (see `NodeLayers`).  encode_weight /
    head_weight / head_bias pad a type's layer to the common shape; limb_heads: only limbs have heads."""
    ix = node_index(graph)
    nodes = [nets[k] for k in ix.kinds]
    limbs = nodes[1:]
    w_enc, b_enc = per_node_linear([n.encode for n in nodes], ix.type_of, weight=encode_weight)
    ports = torch.cat([torch.zeros(1, w_enc.shape[-1]), nets.body.ports(ix.ports)])         # (N, H), body: 0
    heads = limbs if limb_heads else nodes
    gru = None
    if "gru" in nets.body:
        cells = [n.gru for n in nodes]
        gru = (*per_node_linear(cells, ix.type_of, lambda c: c.weight_ih, lambda c: c.bias_ih),
               *per_node_linear(cells, ix.type_of, lambda c: c.weight_hh, lambda c: c.bias_hh))
    return NodeLayers(encode=(w_enc, b_enc + ports[:, None]),
                 own=per_node_linear([n.own for n in nodes], ix.type_of),
                 up=per_node_linear([n.up for n in limbs], ix.limb_type)[0],
                 down=per_node_linear([n.down for n in limbs], ix.limb_type)[0],
                 head=per_node_linear([n.head for n in heads], ix.limb_type if limb_heads else ix.type_of,
                                      head_weight, head_bias),
                 gru=gru, rounds=rounds)


def encode_nodes(w: NodeLayers, x) -> torch.Tensor:
    """Step 1: z = tanh(W_enc x + p) for every node: x (N, n, in) -> z (N, n, H)."""
    return torch.tanh(torch.baddbmm(w.encode[1], x, w.encode[0]))


def propagate(w: NodeLayers, z) -> torch.Tensor:
    """Step 2: `rounds` rounds of limbs -> body, then body -> limbs, on the star design graph: (N, n, H)."""
    for _ in range(w.rounds):
        body, limbs = z.split([1, len(z) - 1])                                             # (1, n, H), (N - 1, n, H)
        own_body, own_limbs = torch.baddbmm(w.own[1], z, w.own[0]).split([1, len(z) - 1])
        inbox = torch.bmm(limbs, w.up).sum(0, keepdim=True)                                # (1, n, H)
        body = body + torch.tanh(own_body + inbox)                                         # (1, n, H)
        down = torch.bmm(body.expand(len(limbs), -1, -1), w.down)                          # (N - 1, n, H)
        z = torch.cat([body, limbs + torch.tanh(own_limbs + down)])                        # (N, n, H)
    return z


def update_memory(w: NodeLayers, z, h) -> torch.Tensor:
    """Step 3 (policy): every node's memory h <- GRUCell(z, h) (torch.nn.GRUCell's gates r, u, n): (N, n, H)."""
    w_ih, b_ih, w_hh, b_hh = w.gru
    H = h.shape[-1]
    gi_ru, gi_n = torch.baddbmm(b_ih, z, w_ih).split([2 * H, H], -1)                       # (N, n, 2H), (N, n, H)
    gh_ru, gh_n = torch.baddbmm(b_hh, h, w_hh).split([2 * H, H], -1)
    r, u = torch.sigmoid(gi_ru + gh_ru).chunk(2, -1)                                        # reset, update gates
    c = torch.tanh(gi_n + r * gh_n)                                                          # candidate
    return c + u * (h - c)                                                                   # (1 - u) c + u h


def read_out(w: NodeLayers, z) -> torch.Tensor:
    """Step 3: each node's output from its state: (N, n, H) -> (N, n, out)."""
    return torch.baddbmm(w.head[1], z, w.head[0])


def nodes_first(parts: dict, kinds, width: int) -> torch.Tensor:
    """{"body": (n, F_b), "leg": (n, L, F_l), "wheel": (n, W, F_w)} -> (N, n, width), zero-padded."""
    x = [parts["body"][:, None]] + [parts[k] for k in kinds[1:]]
    return torch.cat([pad_to(p, width) for p in x], 1).transpose(0, 1)


@functools.lru_cache(maxsize=None)
def flat_index(graph, widths: tuple, stride: int, limbs_only: bool = False) -> torch.Tensor:
    """Where each entry of sim2d's flat layout (body, legs, wheels; `widths` per type of TYPES) sits
    in a robot's node outputs laid out `stride` apart: an index into (n, nodes x stride)."""
    nodes = [k for k, _ in graph.nodes][1 if limbs_only else 0:]
    return torch.tensor([i * stride + j for i, k in enumerate(nodes) for j in range(widths[TYPES.index(k)])])


def to_flat(y, index) -> torch.Tensor:
    """Node-major outputs (N, n, F) -> (n, entries) in sim2d's flat layout, by a `flat_index`."""
    return y.transpose(0, 1).reshape(y.shape[1], -1)[:, index]


OBS_WIDTH = max(BODY_OBS_DIM, LEG_OBS_DIM, WHEEL_OBS_DIM)     # node observations, zero-padded to this
ACT_WIDTH = max(LEG_ACT_DIM, WHEEL_ACT_DIM)                   # limb actions, likewise


@functools.lru_cache(maxsize=None)
def node_obs_scale(graph) -> torch.Tensor:
    """(N, 1, OBS_WIDTH): OBS_SCALE of each node's type, zero-padded like `nodes_first`."""
    return torch.stack([pad_to(OBS_SCALE[k], OBS_WIDTH) for k, _ in graph.nodes])[:, None]


class PolicyOnDesign:
    """The policy on one design (see `NodeLayers`); its memory is node-major, (N, n, H)."""

    def __init__(self, policy: ModularPolicy, graph):
        ix, cfg = node_index(graph), policy.cfg
        self.kinds, self.log_std_range = ix.kinds, (cfg.log_std_min, cfg.log_std_max)

        def encode_weight(layer):                                  # [obs | h] -> [obs padded to OBS_WIDTH | h]
            k = layer.in_features - cfg.hidden
            return torch.cat([pad_to(layer.weight[:, :k], OBS_WIDTH), layer.weight[:, k:]], 1)

        def head_rows(x):                                          # [mean | raw] -> each padded to ACT_WIDTH
            m, r = x.chunk(2, 0)
            return torch.cat([pad_to(m, ACT_WIDTH, dim=0), pad_to(r, ACT_WIDTH, dim=0)])

        self.w = gather_layers(policy.nets, graph, cfg.rounds, encode_weight, lambda l: head_rows(l.weight),
                      lambda l: head_rows(l.bias), limb_heads=True)
        self.obs_scale = node_obs_scale(graph)                                              # (N, 1, O)
        joints = flat_index(graph, (0, LEG_ACT_DIM, WHEEL_ACT_DIM), 2 * ACT_WIDTH, limbs_only=True)  # (A,)
        self.action_index = torch.cat([joints, joints + ACT_WIDTH])                         # means, raw log-stds

    def step(self, obs: dict, h):
        """One control step: mean (n, A), log_std (n, A), next memory (N, n, H) from memory h (N, n, H)."""
        o = nodes_first(obs, self.kinds, OBS_WIDTH) * self.obs_scale                        # (N, n, O)
        z = propagate(self.w, encode_nodes(self.w, torch.cat([o, h], -1)))                  # (N, n, H)
        h = update_memory(self.w, z, h)                                                     # (N, n, H)
        mean, raw = to_flat(read_out(self.w, h[1:]), self.action_index).chunk(2, -1)       # (n, A) x 2
        lo, hi = self.log_std_range
        return mean, lo + (hi - lo) * torch.sigmoid(raw), h                                 # log_std in [lo, hi]

    def act(self, obs: dict, h, deterministic: bool = False):
        """`ModularPolicy.act` on node-major memory."""
        mean, log_std, h = self.step(obs, h)
        return sample_action(mean, log_std, deterministic), h


@functools.lru_cache(maxsize=None)
def model_input_index(graph) -> torch.Tensor:
    """(N, width): which columns of [s (S), clipped a (A), 0] feed each node, in
    `ModularModel.inputs`' order, zero-padded to the widest node (the last column is the 0)."""
    S, A, L, W = graph.state_dim, graph.action_dim, graph.n_legs, graph.n_wheels
    body = list(range(1, BODY_DIM))                                                         # drop x
    legs = [list(range(BODY_DIM + LEG_DIM * j, BODY_DIM + LEG_DIM * (j + 1)))
            + [S + LEG_ACT_DIM * j + i for i in range(LEG_ACT_DIM)] for j in range(L)]
    wheels = [[BODY_DIM + LEG_DIM * L + j, S + LEG_ACT_DIM * L + j] for j in range(W)]
    rows, zero = [body] + legs + wheels, S + A
    width = max(len(r) for r in rows)
    return torch.tensor([r + [zero] * (width - len(r)) for r in rows])


class ModelOnDesign:
    """The model on one design (see `NodeLayers`): f(s, a) -> s_next on flat states (n, S)."""

    def __init__(self, model: ModularModel, graph):
        self.index = model_input_index(graph)                                               # (N, I)
        width, out_width = self.index.shape[1], max(model.OUT_DIMS.values())
        self.w = gather_layers(model.nets, graph, model.cfg.rounds, lambda l: pad_to(l.weight, width),
                      lambda l: pad_to(l.weight, out_width, dim=0),
                      lambda l: pad_to(l.bias, out_width))
        kinds = [k for k, _ in graph.nodes]
        self.in_mean = torch.stack([pad_to(model.norm_in[k].mean, width) for k in kinds])         # pads: 0, std 1
        self.in_std = torch.stack([pad_to(model.norm_in[k].std, width, value=1.0) for k in kinds])  # (N, I)
        self.out_mean, self.out_std = model.change_stats(graph)                             # (S,) each
        self.out_index = flat_index(graph, tuple(model.OUT_DIMS[k] for k in TYPES), out_width)

    def delta_normalised(self, s, a) -> torch.Tensor:
        """The network proper: the normalised change of state (n, S)."""
        src = torch.cat([s, a.clamp(-1.0, 1.0), s.new_zeros(len(s), 1)], 1)                 # (n, S + A + 1)
        x = (src[:, self.index] - self.in_mean) / self.in_std                               # (n, N, I)
        z = propagate(self.w, encode_nodes(self.w, x.transpose(0, 1)))                      # (N, n, H)
        return to_flat(read_out(self.w, z), self.out_index)                                 # (n, S)

    def __call__(self, s, a) -> torch.Tensor:
        """s_t+1 = s_t + Delta(s_t, a_t): (n, S), differentiable in s and a."""
        return s + self.delta_normalised(s, a) * self.out_std + self.out_mean


# ----------------------------------------------------------------------------
# Entry point: parameter counts (speed: python tools/bench.py --networks)
# ----------------------------------------------------------------------------
def main():
    argparse.ArgumentParser(description=__doc__.split("\n")[0]).parse_args()
    policy, model = ModularPolicy(), ModularModel()
    for name, net in (("policy", policy), ("model", model)):
        per_type = "  ".join(f"{k}={count_parameters(net.nets[k])}" for k in TYPES)
        print(f"{name}: {count_parameters(net)} parameters  ({per_type})")
    for design in sim2d.NAMED_DESIGNS:
        g = sim2d.design_graph(design)
        print(f"{design:15s} {g.code}  nodes={1 + g.n_legs + g.n_wheels}  S={g.state_dim:2d}  "
              f"A={g.action_dim:2d}  policy={count_parameters(policy)}  model={count_parameters(model)}")


if __name__ == "__main__":
    main()
