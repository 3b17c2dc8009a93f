"""Modular graph neural networks: the policy pi_theta(a | o, d) and the model f~_phi(s, a, d)
(and, for the PPO baseline of ppo_minimal.py, a critic V_psi(o, d)).

Paper (Whitman & Choset, "Learning Modular Robot Locomotion from
Demonstrations"): Sec. II-B "Modular policies" (one network per module type,
message passing over the design graph), Sec. III-C "Train approximate dynamics
model" (the same modular structure, predicting the change of state) and
Sec. III-J "Implementation details" (the policy is recurrent over time).

    python gnn.py            # parameter counts per module type and per design (CPU, 3 s)
    python gnn.py --bench    # + speed of policy updates through model roll-outs, of model fitting, and of
                             # the default run's policy, BC and model steps (CPU, 30 s)
    python gnn.py --profile policy    # operators of the default run's policy step, by self CPU time

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

A batch holds many robots of one design, so each step above is one tensor op
per module type on (robots, nodes of that type, features): no loop over robots.
Module types a design lacks get no ops at all.
"""
from __future__ import annotations

import argparse
import functools
import math
import time
from dataclasses import dataclass

import numpy as np
import torch
import torch.nn as nn

import sim2d
from sim2d import (BODY_DIM, BODY_OBS_DIM, LEG_ACT_DIM, LEG_DIM, LEG_OBS_DIM,
                   WHEEL_ACT_DIM, WHEEL_DIM, WHEEL_OBS_DIM)


@dataclass
class GNNConfig:
    hidden: int = 64            # width of every per-type layer, node state and memory; 32-256
    rounds: int = 2             # message-passing rounds per step; 1-4 (1 lets each limb hear all others)
    log_std_min: float = -2.5   # policy log-std lower bound (std 0.08 in normalised action units)
    log_std_max: float = 0.0    # policy log-std upper bound (std 1, half the action range)
    contact_features: bool = False   # model inputs gain foot height and velocity, wheel height (sim2d.contact_features)


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


def gaussian_kl(mean_p, log_std_p, mean_q, log_std_q) -> torch.Tensor:
    """KL(p || q) of two diagonal Gaussians, summed over the last (action) dim: (...,).

    Per dim: log std_q - log std_p + (std_p^2 + (mean_p - mean_q)^2) / (2 std_q^2) - 1/2.
    """
    var_q = torch.exp(2 * log_std_q)
    return (log_std_q - log_std_p + (torch.exp(2 * log_std_p) + (mean_p - mean_q) ** 2) / (2 * var_q)
            - 0.5).sum(-1)


def node_types(graph) -> list[str]:
    """The module types a design has, in node order: "body" first, then "leg" and/or "wheel"."""
    return ["body"] + [k for k, n in (("leg", graph.n_legs), ("wheel", graph.n_wheels)) if n]


def split_nodes(x, graph) -> dict:
    """Per-node (n, 1 + L + W, F) -> {"body": (n, 1, F), "leg": (n, L, F), "wheel": (n, W, F)}."""
    nl = graph.n_legs
    return {"body": x[:, :1], "leg": x[:, 1:1 + nl], "wheel": x[:, 1 + nl:]}


def node_state(s, graph) -> dict:
    """Flat state (n, S) -> {"body": (n, 1, 6), "leg": (n, L, 4), "wheel": (n, W, 1)}."""
    return {**sim2d.split_state(s, graph), "body": s[:, None, :BODY_DIM]}


def join_nodes(parts: list) -> torch.Tensor:
    """[(n, N_k, F_k) per type, in node order] -> flat (n, sum_k N_k F_k), sim2d's layout."""
    return torch.cat([p.flatten(1) for p in parts], 1)


def count_parameters(module: nn.Module) -> int:
    return sum(p.numel() for p in module.parameters())


# ----------------------------------------------------------------------------
# Per-type networks and message passing on the design graph
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


@functools.lru_cache(maxsize=None)
def port_index(graph, kind: str) -> torch.Tensor:
    """(N_k,) body port of each `kind` node, made once per design graph (it is used every step)."""
    return torch.tensor(graph.leg_ports if kind == "leg" else graph.wheel_ports)


def encode(nets: nn.ModuleDict, x: dict, graph) -> dict:
    """Step 1: z = tanh(W_enc x + p) for every node, (n, N_k, H) per type."""
    z = {"body": torch.tanh(nets.body.encode(x["body"]))}                                # (n, 1, H)
    for k in node_types(graph)[1:]:
        p = nets.body.ports(port_index(graph, k))                                        # (N_k, H)
        z[k] = torch.tanh(nets[k].encode(x[k]) + p)                                      # (n, N_k, H)
    return z


def propagate(nets: nn.ModuleDict, z: dict, rounds: int) -> dict:
    """Step 2: `rounds` rounds of limbs -> body, then body -> limbs, on the star design graph."""
    limbs = [k for k in z if k != "body"]
    for _ in range(rounds):
        messages = [nets[k].up(z[k]).sum(1, keepdim=True) for k in limbs]                # (n, 1, H) per type
        inbox = functools.reduce(torch.add, messages)                                    # (n, 1, H)
        z["body"] = z["body"] + torch.tanh(nets.body.own(z["body"]) + inbox)             # (n, 1, H)
        for k in limbs:
            z[k] = z[k] + torch.tanh(nets[k].own(z[k]) + nets[k].down(z["body"]))        # (n, N_k, H)
    return z


# ----------------------------------------------------------------------------
# The modular policy pi_theta(a | o, d), recurrent over time
# ----------------------------------------------------------------------------
class ModularPolicy(nn.Module):
    """pi_theta(a | o, d): a Gaussian over each joint's normalised velocity command.

    Every node keeps a memory h, updated by its type's GRUCell after message
    passing.  The memory is an explicit tensor (n, 1 + L + W, hidden): reset
    with `initial_hidden`, read from what `forward`/`act` return, set by
    passing it in (detach it between batches for truncated BPTT).  A node's
    input is its scaled observation and its memory, so messages carry memory.
    The log-std is state-dependent: a second output per joint, squashed into
    [log_std_min, log_std_max] by a sigmoid (about mid-way at initialisation).
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
        """h_0 = 0: (n, 1 + n_legs + n_wheels, hidden), node 0 the body, then the legs, then the wheels."""
        return torch.zeros(n, 1 + graph.n_legs + graph.n_wheels, self.cfg.hidden)

    def forward(self, obs: dict, graph, hidden):
        """One control step from `observe`'s dict of tensors: mean (n, A), log_std (n, A), next hidden."""
        kinds, h = node_types(graph), split_nodes(hidden, graph)
        o = {"body": obs["body"][:, None], "leg": obs["leg"], "wheel": obs["wheel"]}        # (n, N_k, O_k)
        x = {k: torch.cat([o[k] * OBS_SCALE[k], h[k]], -1) for k in kinds}                 # (n, N_k, O_k + H)
        z = propagate(self.nets, encode(self.nets, x, graph), self.cfg.rounds)
        h = {k: self.nets[k].gru(z[k].flatten(0, 1), h[k].flatten(0, 1)).view_as(z[k])
             for k in kinds}                                                                # (n, N_k, H)
        heads = [self.nets[k].head(h[k]).chunk(2, -1) for k in kinds[1:]]                   # (n, N_k, A_k) x 2
        mean = join_nodes([m for m, _ in heads])                                            # (n, A)
        raw = join_nodes([r for _, r in heads])                                             # (n, A)
        lo, hi = self.cfg.log_std_min, self.cfg.log_std_max
        log_std = lo + (hi - lo) * torch.sigmoid(raw)                                       # (n, A) in [lo, hi]
        return mean, log_std, torch.cat([h[k] for k in kinds], 1)                           # (n, 1 + L + W, H)

    def act(self, obs: dict, graph, hidden, deterministic: bool = False):
        """a_t ~ pi_theta(. | o_<=t), reparameterised (or the mean), and the next hidden.

        Not clipped: the world clips actions to [-1, 1], and so does the model.
        """
        mean, log_std, hidden = self(obs, graph, hidden)
        if deterministic:
            return mean, hidden
        return mean + torch.exp(log_std) * torch.randn_like(mean), hidden                   # (n, A)

    def sequence_log_prob(self, obs_seq: dict, actions_seq, graph, hidden=None):
        """Returns (log pi(a_t | o_<=t), entropy of pi(. | o_<=t)), each (n, T), running the recurrence.

        obs_seq: `observe`'s dict with a time axis, values (n, T, ...); actions_seq: (n, T, A);
        hidden: h_0 (zeros if None).  Feeds eqn. (IL_loss) (Sec. III-E) and the entropy
        penalty on demonstration observations (Sec. III-J).
        """
        n, T = actions_seq.shape[:2]
        hidden = self.initial_hidden(n, graph) if hidden is None else hidden
        log_probs, entropies = [], []
        for t in range(T):
            mean, log_std, hidden = self({k: v[:, t] for k, v in obs_seq.items()}, graph, hidden)
            log_probs.append(gaussian_log_prob(mean, log_std, actions_seq[:, t]))          # (n,)
            entropies.append(gaussian_entropy(log_std))                                     # (n,)
        return torch.stack(log_probs, 1), torch.stack(entropies, 1)                         # (n, T) x 2


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

    def forward(self, obs: dict, graph) -> torch.Tensor:
        """`observe`'s dict of tensors (n, ...) -> V (n,)."""
        kinds = node_types(graph)
        o = {"body": obs["body"][:, None], "leg": obs["leg"], "wheel": obs["wheel"]}        # (n, N_k, O_k)
        z = propagate(self.nets, encode(self.nets, {k: o[k] * OBS_SCALE[k] for k in kinds}, graph),
                      self.cfg.rounds)
        return torch.cat([self.nets[k].head(z[k]) for k in kinds], 1).mean((1, 2))         # (n,)


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
    world clips them.  With `contact_features` a leg also reads its foot's
    height above the ground and velocity, and a wheel its lowest point's
    height (sim2d.contact_features, differentiable forward kinematics).  Node outputs: body [dx, dy, dpitch, dvx, dvy,
    dpitch_rate], leg 4 joint changes, wheel 1.  Inputs and outputs are
    normalised per type with statistics from `fit_normalization`.
    """

    OUT_DIMS = {"body": BODY_DIM, "leg": LEG_DIM, "wheel": WHEEL_DIM}

    def __init__(self, cfg: GNNConfig = GNNConfig()):
        super().__init__()
        self.cfg = cfg
        extra = {"body": 0, "leg": 3, "wheel": 1} if cfg.contact_features else {"body": 0, "leg": 0, "wheel": 0}
        self.in_dims = {"body": BODY_DIM - 1 + extra["body"], "leg": LEG_DIM + LEG_ACT_DIM + extra["leg"],
                        "wheel": WHEEL_DIM + WHEEL_ACT_DIM + extra["wheel"]}
        self.nets = nn.ModuleDict({k: type_net(k, self.in_dims[k], self.OUT_DIMS[k], cfg.hidden,
                                               recurrent=False) for k in TYPES})
        self.norm_in = nn.ModuleDict({k: Normalizer(d) for k, d in self.in_dims.items()})
        self.norm_out = nn.ModuleDict({k: Normalizer(d) for k, d in self.OUT_DIMS.items()})

    def inputs(self, s, a, graph) -> dict:
        """Raw node inputs: {"body": (n, 1, 5), "leg": (n, L, 6 or 9), "wheel": (n, W, 2 or 3)}."""
        ps, pa = node_state(s, graph), sim2d.split_action(a.clamp(-1.0, 1.0), graph)
        x = {"body": ps["body"][..., 1:],                                                   # drop x
             "leg": torch.cat([ps["leg"], pa["leg"]], -1),
             "wheel": torch.cat([ps["wheel"], pa["wheel"]], -1)}
        if self.cfg.contact_features:
            contact = sim2d.contact_features(s, graph)                                      # (n, L, 3), (n, W, 1)
            x = {**x, "leg": torch.cat([x["leg"], contact["leg"]], -1),
                 "wheel": torch.cat([x["wheel"], contact["wheel"]], -1)}
        return x

    def delta_normalised(self, s, a, graph) -> dict:
        """The network proper: normalised change of state per type, (n, N_k, out_k)."""
        kinds, x = node_types(graph), self.inputs(s, a, graph)
        x = {k: (x[k] - self.norm_in[k].mean) / self.norm_in[k].std for k in kinds}
        z = propagate(self.nets, encode(self.nets, x, graph), self.cfg.rounds)
        return {k: self.nets[k].head(z[k]) for k in kinds}

    def forward(self, s, a, graph) -> torch.Tensor:
        """s_t+1 = s_t + Delta(s_t, a_t): (n, S), differentiable in s and a."""
        d = self.delta_normalised(s, a, graph)
        delta = [d[k] * self.norm_out[k].std + self.norm_out[k].mean for k in d]            # (n, N_k, out_k)
        return s + join_nodes(delta)                                                        # (n, S)

    def state_error(self, s_pred, s_true, graph) -> torch.Tensor:
        """Mean squared error of predicted against true states, each entry divided by the fitted
        std of its change: for a one-step prediction the same number as `loss`."""
        err = node_state(s_pred - s_true, graph)
        return sum((err[k] / self.norm_out[k].std).pow(2).sum() for k in err) / s_true.numel()

    def loss(self, s, a, s_next, graph) -> torch.Tensor:
        """Mean squared error of the normalised change of state, averaged over the n x S state entries."""
        d, true = self.delta_normalised(s, a, graph), node_state(s_next - s, graph)
        target = {k: (true[k] - self.norm_out[k].mean) / self.norm_out[k].std for k in d}   # (n, N_k, out_k)
        return sum((d[k] - target[k]).pow(2).sum() for k in d) / s.numel()

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
# Roll-outs, benchmark and entry point
# ----------------------------------------------------------------------------
def random_transitions(design: str, n_robots: int, steps: int, seed: int, episodes: bool = False):
    """Sim transitions (s, a, s_next), (n_robots * steps, .) float32, random spline actions (Sec. III-B);
    with `episodes`, the episodes instead: states (n_robots, steps + 1, S), actions (n_robots, steps, A)."""
    graph = sim2d.design_graph(design)
    actions = sim2d.random_spline_actions(np.random.default_rng(seed), n_robots, graph.action_dim, steps)
    run = sim2d.simulate(graph, lambda obs, s, t: actions[:, t], n=n_robots, steps=steps, seed=seed)
    states = torch.as_tensor(run.states, dtype=torch.float32)                            # (n, T + 1, S)
    if episodes:
        return states, torch.as_tensor(run.actions, dtype=torch.float32)
    return (states[:, :-1].flatten(0, 1), torch.as_tensor(run.actions, dtype=torch.float32).flatten(0, 1),
            states[:, 1:].flatten(0, 1))


def best_seconds_per_call(fn, calls: int, repeats: int) -> float:
    """Seconds per call of fn(): one warm-up call, then the best of `repeats` timings of `calls` calls."""
    fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(calls):
            fn()
        times.append((time.perf_counter() - t0) / calls)
    return min(times)


def bench(design: str = "hexapod", batch: int = 256, horizon: int = 20, model_batch: int = 512,
          repeats: int = 5, cfg: GNNConfig = GNNConfig()) -> dict:
    """Best-of-`repeats` speed of a policy update through model roll-outs, and of a model update."""
    from modular_rlil_minimal import rollout    # Algorithm 1 lines 10-15, the code the training runs
    torch.manual_seed(0)
    graph = sim2d.design_graph(design)
    states, actions, next_states = random_transitions(design, n_robots=32, steps=100, seed=0)
    policy, model = ModularPolicy(cfg), ModularModel(cfg)
    model.fit_normalization([(graph, states, actions, next_states)])
    policy_opt = torch.optim.Adam(policy.parameters(), lr=1e-3, foreach=True)
    model_opt = torch.optim.Adam(model.parameters(), lr=1e-3, foreach=True)

    def policy_update():                        # eqn. (RL_loss) through the frozen model, Sec. III-F
        s0 = states[torch.randint(len(states), (batch,))]
        R, _, _ = rollout(policy, model, s0, policy.initial_hidden(batch, graph), graph, horizon)
        loss = -R.mean()
        policy_opt.zero_grad()
        loss.backward()
        policy_opt.step()

    def model_update():
        i = torch.randint(len(states), (model_batch,))
        loss = model.loss(states[i], actions[i], next_states[i], graph)
        model_opt.zero_grad()
        loss.backward()
        model_opt.step()

    def seconds_per_call(fn, calls):
        return best_seconds_per_call(fn, calls, repeats)

    model.requires_grad_(False)                 # frozen while the policy trains; gradients flow through it
    t_rollout = seconds_per_call(policy_update, 2)
    model.requires_grad_(True)
    t_fit = seconds_per_call(model_update, 20)
    return {"rollout_s": t_rollout, "rollout_robot_steps_per_s": batch * horizon / t_rollout,
            "model_fit_s": t_fit, "model_fit_transitions_per_s": model_batch / t_fit}


def default_run_steps(cfg=None) -> dict:
    """The default run's three kinds of step as functions (train.py's defaults):

    policy step: L_RL over 64 leg_none_wheel robots x T = 20 steps through the frozen
      model, plus lambda L_IL over 2 demo designs (hexapod, car) x 32 windows x 8 steps,
      backward, clipped Adam step (Algorithm 1 lines 9-21; 120 per iteration);
    BC step: L_IL alone, backward, Adam (line 1; 1000 before the loop);
    model step: one-step loss on 512 leg_none_wheel transitions, backward, Adam (line 5).
    Demonstrations are random observations and actions of the demo designs' shapes:
    the cost does not depend on the values.
    """
    import demos as demo_lib
    import modular_rlil_minimal as rlil
    cfg = cfg or rlil.Config(train=("lnwwnl",), demos=("llllll", "wnwwnw"))
    rng, graph = np.random.default_rng(0), sim2d.design_graph(cfg.train[0])
    torch.manual_seed(0)
    data = rlil.Trajectories(graph.code, *random_transitions(graph.code, 16, 50, seed=0, episodes=True))
    policy, model = ModularPolicy(cfg.gnn), rlil.Ensemble(cfg)
    flat = data.transitions()
    model.members[0].fit_normalization([(graph, *flat)])

    def random_demo(design):                   # (E, T, ...) random obs and actions of the design's shapes
        g, (E, T) = sim2d.design_graph(design), (cfg.demo_episodes, cfg.demo_steps)
        s = rng.standard_normal((E, T, g.state_dim)).astype(np.float32)
        a = rng.uniform(-1, 1, (E, T, g.action_dim)).astype(np.float32)
        return demo_lib.DemoData(g.code, sim2d.observe(s, g), a, s, np.zeros(E), np.zeros(E, bool))

    demo_data = {d: random_demo(d) for d in cfg.demos}
    buffers = {graph.code: rlil.init_buffer(policy, data, cfg, rng)}
    policy_opt = torch.optim.Adam(policy.parameters(), lr=1e-4, foreach=True)
    model_opt = torch.optim.Adam(model.parameters(), lr=1e-4, foreach=True)

    def policy_step():
        model.requires_grad_(False)
        loss_rl = rlil.rl_loss(policy, model, buffers, cfg, rng)
        loss_il, entropy = rlil.il_loss(policy, demo_data, cfg, rng)
        loss = rlil.rlil_loss(loss_rl, loss_il + cfg.entropy_weight * entropy, cfg.il_weight)
        rlil.gradient_step(policy_opt, loss, policy, cfg.grad_clip)
        model.requires_grad_(True)

    def bc_step():
        loss, _ = rlil.il_loss(policy, demo_data, cfg, rng)
        policy_opt.zero_grad()
        loss.backward()
        policy_opt.step()

    def model_step():
        loss = rlil.model_loss(model.members[0], data, flat, cfg.model_batch, 1, rng)
        model_opt.zero_grad()
        loss.backward()
        model_opt.step()

    return {"policy": policy_step, "bc": bc_step, "model": model_step}


def bench_default_run(repeats: int = 3) -> dict:
    """Best-of-`repeats` seconds per call of `default_run_steps`, and the policy step's robot-steps/s."""
    import modular_rlil_minimal as rlil
    cfg, steps = rlil.Config(), default_run_steps()

    def seconds_per_call(fn, calls):
        return best_seconds_per_call(fn, calls, repeats)

    t_policy = seconds_per_call(steps["policy"], 3)
    return {"policy_step_s": t_policy, "policy_robot_steps_per_s": cfg.batch * cfg.horizon / t_policy,
            "bc_step_s": seconds_per_call(steps["bc"], 10), "model_step_s": seconds_per_call(steps["model"], 20)}


def profile_default_run(step: str = "policy", calls: int = 3, rows: int = 25) -> str:
    """torch.profiler's table of the operators of `calls` default-run steps, by self CPU time."""
    from torch.profiler import ProfilerActivity, profile
    fn = default_run_steps()[step]
    fn()                                                                                    # warm-up
    with profile(activities=[ProfilerActivity.CPU]) as prof:
        for _ in range(calls):
            fn()
    return prof.key_averages().table(sort_by="self_cpu_time_total", row_limit=rows)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--bench", action="store_true", help="time hexapod roll-outs and model fitting, "
                        "and the default run's policy, BC and model steps")
    parser.add_argument("--profile", choices=("policy", "bc", "model"),
                        help="print torch.profiler's operator table of 3 default-run steps of this kind")
    parser.add_argument("--threads", type=int, default=1, help="torch CPU threads")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    policy, model = ModularPolicy(), ModularModel()
    for name, net in (("policy", policy), ("model", model)):
        per_type = "  ".join(f"{k}={count_parameters(net.nets[k])}" for k in TYPES)
        print(f"{name}: {count_parameters(net)} parameters  ({per_type})")
    for design in sim2d.NAMED_DESIGNS:
        g = sim2d.design_graph(design)
        print(f"{design:15s} {g.code}  nodes={1 + g.n_legs + g.n_wheels}  S={g.state_dim:2d}  "
              f"A={g.action_dim:2d}  policy={count_parameters(policy)}  model={count_parameters(model)}")
    if args.bench:
        r = bench()
        print(f"hexapod, best of 5, {args.threads} threads: policy update (T=20 roll-out of 256 robots, "
              f"backward, Adam) {1e3 * r['rollout_s']:.0f} ms; model update (512 transitions) "
              f"{1e3 * r['model_fit_s']:.1f} ms")
        print(f"rollout_robot_steps_per_s={r['rollout_robot_steps_per_s']:.1f} "
              f"model_fit_transitions_per_s={r['model_fit_transitions_per_s']:.1f}")
        d = bench_default_run()
        print(f"default run (train.py's defaults), best of 3, {args.threads} threads: policy step "
              f"(64 leg_none_wheel robots x T=20 through the model + IL on 2 x 32 windows x 8 steps) "
              f"{1e3 * d['policy_step_s']:.0f} ms; BC step {1e3 * d['bc_step_s']:.1f} ms; "
              f"model step {1e3 * d['model_step_s']:.1f} ms")
        print(f"default_policy_robot_steps_per_s={d['policy_robot_steps_per_s']:.1f}")
    if args.profile:
        print(profile_default_run(args.profile))


if __name__ == "__main__":
    main()
