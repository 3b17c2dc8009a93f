"""Grade one exercise of the lesson (docs/lesson.md): the student's function against the project's own.

Each exercise in lesson/exercises/ is one file with a stub to fill in.  This
grader imports that file, runs its function and the project's own function on
the same fixed, seeded inputs (tiny sizes: well under a second each), and
prints "pass", or in two lines what differs and a hint.  Where a typical
mistake is cheap to recognise (a sign, a missing term, an off-by-one in the
horizon), the grader computes that wrong answer too and names it.

    python lesson/grade.py ex1                     # grades lesson/exercises/ex1_reward.py
    python lesson/grade.py ex3 --file answer.py    # any file with the same function(s)
    python lesson/grade.py ex3 --solution          # the project's own function: must pass
    python lesson/grade.py ex3 --traceback         # on an exception in your code, Python's traceback
    python lesson/exercises/ex3_rl_loss.py         # the same as `grade.py ex3`

Exit status: 0 pass, 1 a wrong answer (or not written yet), 2 bad usage.
"""
from __future__ import annotations

import contextlib
import csv
import importlib.util
import json
import math
import sys
import tempfile
import types
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:                  # run as a script: the stage files are one folder up
    sys.path.insert(0, str(ROOT))

import numpy as np                                                                # noqa: E402
import torch                                                                      # noqa: E402

import demos as demo_lib                                                          # noqa: E402
import gnn                                                                        # noqa: E402
import modular_rlil_minimal as rlil                                               # noqa: E402
import sim2d                                                                      # noqa: E402
from experiments import stats                                                     # noqa: E402

EXERCISES_DIR = ROOT / "lesson" / "exercises"


# ----------------------------------------------------------------------------
# Small helpers: a wrong answer, calling the student's code, comparing numbers
# ----------------------------------------------------------------------------
class Wrong(Exception):
    """A wrong answer: what differs (one line) and a hint (one line)."""

    def __init__(self, what: str, hint: str = ""):
        super().__init__(what)
        self.what, self.hint = what, hint


class NotWritten(Exception):
    """The student's function still raises NotImplementedError."""


@dataclass
class Variant:
    """A typical wrong answer, computed on the same inputs: if the student's result equals
    `value`, the grader says `what` and `hint` instead of "differs"."""

    value: object
    what: str
    hint: str


TRACEBACK = False          # --traceback: let an exception in the student's code through


def call(answer, name: str, *args, **kw):
    """answer.name(*args, **kw); NotImplementedError -> NotWritten, any other exception -> Wrong."""
    fn = getattr(answer, name, None)
    if fn is None:
        raise Wrong(f"the answer has no {name}", f"keep the stub's name and signature: {name}(...)")
    try:
        return fn(*args, **kw)
    except NotImplementedError:
        raise NotWritten(name) from None
    except Exception as e:
        if TRACEBACK:
            raise
        first = (str(e).splitlines() or [""])[0][:160]
        raise Wrong(f"{name} raised {type(e).__name__}: {first}",
                    "add --traceback to the grade command to see where") from None


def as_tensor(x, what: str) -> torch.Tensor:
    """A student's number(s) as a float64 tensor (torch, numpy or a Python float), or Wrong."""
    if isinstance(x, torch.Tensor):
        return x.detach().double()
    try:
        return torch.as_tensor(np.asarray(x, dtype=float))
    except (TypeError, ValueError):
        raise Wrong(f"{what} is a {type(x).__name__}, not numbers", "return a torch tensor") from None


def close(a: torch.Tensor, b: torch.Tensor, tol: float) -> bool:
    return a.shape == b.shape and bool(torch.allclose(a, b, rtol=tol, atol=tol, equal_nan=True))


def check_value(got, expected, what: str, hint: str, variants=(), tol: float = 1e-5,
                shape_hint: str = "") -> None:
    """Wrong unless `got` equals `expected` (within tol); names the first variant it equals."""
    got, expected = as_tensor(got, what), as_tensor(expected, what)
    if got.shape != expected.shape:
        raise Wrong(f"{what} has shape {tuple(got.shape)}, expected {tuple(expected.shape)}", shape_hint or hint)
    if close(got, expected, tol):
        return
    for v in variants:
        if close(got, as_tensor(v.value, what), tol):
            raise Wrong(v.what, v.hint)
    if close(got, -expected, tol):
        raise Wrong(f"sign: {what} is minus the project's", hint)
    raise Wrong(f"{what} differs from the project's by up to {float((got - expected).abs().max()):.3g}", hint)


@contextlib.contextmanager
def seeded(seed: int):
    """A context in which torch's global generator starts from `seed`; its state is restored after."""
    with torch.random.fork_rng():
        torch.manual_seed(seed)
        yield


# ----------------------------------------------------------------------------
# ex1: the reward of a transition, sim2d.reward
# ----------------------------------------------------------------------------
def reward_cases():
    """(s, a, s_next, graph) on three designs: legs and wheels, wheels only, and a time axis
    (T, n, S) as rollout passes it; actions partly beyond [-1, 1]; float64."""
    g, cases = torch.Generator().manual_seed(0), []
    for design, lead in (("leg_none_wheel", (5,)), ("car", (5,)), ("hexapod", (3, 4))):
        graph = sim2d.design_graph(design)
        base = torch.as_tensor(sim2d.nominal_state(graph))
        s = base + 0.3 * torch.randn(*lead, graph.state_dim, generator=g, dtype=torch.float64)
        s_next = s + 0.1 * torch.randn(*lead, graph.state_dim, generator=g, dtype=torch.float64)
        s_next[..., 0] += 0.08                                        # about 1 m/s forward
        a = 1.5 * torch.randn(*lead, graph.action_dim, generator=g, dtype=torch.float64)
        cases.append((s, a, s_next, graph))
    return cases


def reward_variants(s, a, s_next, graph) -> list[Variant]:
    """The reward's typical mistakes, each computed from the terms."""
    def pitch(x, square=True):
        return sim2d.W_PITCH * (x[..., 2] ** 2 if square else x[..., 2].abs())

    def pose(x):
        if not graph.n_legs:
            return torch.zeros(x.shape[:-1], dtype=x.dtype)
        legs = sim2d.split_state(x, graph)["leg"]
        return sim2d.W_POSE * ((legs[..., 0] - sim2d.HIP_NOMINAL) ** 2
                               + (legs[..., 1] - sim2d.KNEE_NOMINAL) ** 2).mean(-1) / 2

    progress = s_next[..., 0] - s[..., 0]
    effort, p, q = sim2d.W_EFFORT * (a ** 2).mean(-1), pitch(s_next), pose(s_next)
    pen = p + effort + q
    out = [Variant(progress, "only the forward progress: the penalties are missing",
                   "subtract W_PITCH pitch'^2, W_EFFORT mean(a^2) and, with legs, the W_POSE term"),
           Variant(-progress - pen, "the progress has the wrong sign",
                   "progress = x' - x = s_next[..., 0] - s[..., 0]: forward is +x"),
           Variant(progress + pen, "the penalties are added, not subtracted", "r = progress - penalties"),
           Variant(progress - effort - q, "missing the pitch penalty",
                   "W_PITCH * pitch'^2, with the pitch after the step, s_next[..., 2]"),
           Variant(progress - p - q, "missing the effort penalty",
                   "W_EFFORT * the mean over the action's entries of a^2"),
           Variant(progress - pitch(s) - effort - q, "the pitch penalty uses s, the state before the step",
                   "use s_next[..., 2], the pitch the action led to"),
           Variant(progress - pitch(s_next, square=False) - effort - q, "the pitch penalty uses |pitch|",
                   "square it: W_PITCH * pitch'^2"),
           Variant(progress - p - sim2d.W_EFFORT * (a ** 2).sum(-1) - q,
                   "the effort penalty sums a^2 over the action's entries",
                   "take the mean, (a ** 2).mean(-1): the weight then does not grow with the number of joints"),
           Variant(progress - p - sim2d.W_EFFORT * (a.clamp(-1, 1) ** 2).mean(-1) - q,
                   "the effort penalty sees clipped actions",
                   "use a as given, unclipped: the gradient then pulls saturated commands back (rollout's docstring)")]
    if graph.n_legs:
        out += [Variant(progress - p - effort, "missing the pose penalty",
                        "W_POSE * mean over legs of ((hip - HIP_NOMINAL)^2 + (knee - KNEE_NOMINAL)^2) / 2, of s_next"),
                Variant(progress - p - effort - pose(s), "the pose penalty uses s, the state before the step",
                        "use the leg angles of s_next"),
                Variant(progress - p - effort - 2 * q, "the pose penalty is twice the project's",
                        "divide by 2: it is the mean over both joint angles of every leg")]
    else:
        out.append(Variant(torch.full_like(progress, math.nan), "NaN on a design without legs",
                           "a mean over zero legs is NaN: add the pose term only if graph.n_legs"))
    return out


def check_ex1(answer) -> None:
    hint = "r = (x' - x) - W_PITCH pitch'^2 - W_EFFORT mean(a^2) - W_POSE pose term (sim2d.reward's docstring)"
    for s, a, s_next, graph in reward_cases():
        got = call(answer, "reward", s, a, s_next, graph)
        what = f"the reward on {graph.name} {tuple(s.shape[:-1])}"
        check_value(got, sim2d.reward(s, a, s_next, graph), what, hint, reward_variants(s, a, s_next, graph), tol=1e-8,
                    shape_hint="one reward per robot, shape s.shape[:-1]: index the last axis (s[..., 0]) and "
                               "take means over it (.mean(-1))")
    s, a, s_next, graph = (x.numpy() if isinstance(x, torch.Tensor) else x for x in reward_cases()[0])
    try:
        got = call(answer, "reward", s, a, s_next, graph)
    except Wrong as e:
        raise Wrong(f"works on torch tensors but not on numpy arrays ({e.what.split(':')[0]})",
                    "the simulator's data are numpy arrays (policy_return): use ** and .mean(-1)") from None
    check_value(got, sim2d.reward(s, a, s_next, graph), "the reward on numpy arrays", hint, tol=1e-8)


# ----------------------------------------------------------------------------
# ex2: one message-passing step, node by node, gnn.node_by_node
# ----------------------------------------------------------------------------
def node_by_node_variant(nets, graph, x, h, rounds, mistake: str = ""):
    """gnn.node_by_node with one typical mistake switched on (none: the same numbers)."""
    kinds = [kind for kind, _ in graph.nodes]
    enc = (lambda v: v) if mistake == "no_tanh" else torch.tanh
    z = [enc(nets[kind].encode(xi) + (nets.body.ports.weight[port] if port is not None and mistake != "no_port" else 0))
         for (kind, port), xi in zip(graph.nodes, x)]
    n_rounds = rounds + {"rounds+1": 1, "rounds-1": -1}.get(mistake, 0)
    for _ in range(n_rounds):
        messages = [nets[kind].up(zi) for kind, zi in zip(kinds[1:], z[1:])]
        inbox = sum(messages) / (len(messages) if mistake == "mean" else 1)
        body = (0 if mistake == "no_body_residual" else z[0]) + torch.tanh(nets.body.own(z[0]) + inbox)
        heard = z[0] if mistake == "old_body" else body
        z = [body] + [(0 if mistake == "no_limb_residual" else zi)
                      + torch.tanh(nets[kind].own(zi) + nets[kind].down(heard)) for kind, zi in zip(kinds[1:], z[1:])]
    new_h = h
    if h is not None and mistake != "no_gru":
        if mistake == "gru_swapped":
            new_h = [nets[kind].gru(hi, zi) for kind, zi, hi in zip(kinds, z, h)]
        else:
            new_h = [nets[kind].gru(zi, hi) for kind, zi, hi in zip(kinds, z, h)]
        if mistake != "read_z":
            z = new_h
        if mistake == "old_h":
            new_h = h
    return [nets[kind].head(zi) if "head" in nets[kind] else None for kind, zi in zip(kinds, z)], new_h


NODE_MISTAKES = {
    "no_port": ("1. encode: the limbs' port vectors p are missing",
                "z = tanh(W_enc x + p), p = nets.body.ports.weight[port] for a limb, 0 for the body"),
    "no_tanh": ("1. encode: z = W_enc x + p without the tanh", "z = tanh(W_enc x + p)"),
    "mean": ("2. the body averages its limbs' messages", "sum them: inbox = sum over limbs of nets[kind].up(z_limb)"),
    "no_body_residual": ("2. the body's update replaces z_body", "z_body <- z_body + tanh(W_own z_body + inbox)"),
    "no_limb_residual": ("2. a limb's update replaces z_limb", "z_limb <- z_limb + tanh(W_own z_limb + W_down z_body)"),
    "old_body": ("2. the limbs hear the body's state from before this round's update",
                 "update the body first, then each limb with W_down of the new z_body"),
    "rounds+1": ("2. off by one round: rounds + 1 rounds of message passing", "for _ in range(rounds)"),
    "rounds-1": ("2. off by one round: rounds - 1 rounds of message passing", "for _ in range(rounds)"),
    "no_gru": ("3. the memory is not updated", "with h given: h <- nets[kind].gru(z, h) per node; the heads read it"),
    "gru_swapped": ("3. GRUCell's arguments are swapped", "nets[kind].gru(input z, hidden h)"),
    "read_z": ("3. read out from z, not from the new memory h", "z = h = [GRU(z, h) per node], then heads on h"),
    "old_h": ("3. returns the old memories", "return the new h, GRU(z, h), as the second result"),
}


def node_cases():
    """(nets, graph, x, h, rounds): the policy's nets on leg_none_wheel (memory, 2 rounds) and on
    the car (3 rounds), the model's on the hexapod (no memory, 1 round); hidden 8, 3 robots."""
    torch.manual_seed(0)
    cfg = gnn.GNNConfig(hidden=8)
    policy, model, cases = gnn.ModularPolicy(cfg), gnn.ModularModel(cfg), []
    for nets, design, memory, rounds in ((policy.nets, "leg_none_wheel", True, 2), (policy.nets, "car", True, 3),
                                         (model.nets, "hexapod", False, 1)):
        graph = sim2d.design_graph(design)
        x = [torch.randn(3, nets[kind].encode.in_features) for kind, _ in graph.nodes]
        h = [0.5 * torch.randn(3, cfg.hidden) for _ in graph.nodes] if memory else None
        cases.append((nets, graph, x, h, rounds))
    return cases


def flatten_step(result, expected, where: str) -> torch.Tensor:
    """The student's (outputs, memories) as one vector, after checking its structure against `expected`."""
    if not (isinstance(result, (tuple, list)) and len(result) == 2):
        raise Wrong(f"{where}: returns a {type(result).__name__}, expected (outputs, memories)",
                    "return the list of head outputs and the list of new memories (None without memory)")
    (outs, h), (want_outs, want_h) = result, expected
    if len(outs) != len(want_outs):
        raise Wrong(f"{where}: {len(outs)} outputs for {len(want_outs)} nodes", "one output per node, in node order")
    parts = []
    for k, (o, w) in enumerate(zip(outs, want_outs)):
        if w is None:
            if o is not None:
                raise Wrong(f"{where}: node {k} has an output; it has no head", "None for a node without a head")
            continue
        o = as_tensor(o, f"node {k}'s output")
        if o.shape != w.shape:
            raise Wrong(f"{where}: node {k}'s output has shape {tuple(o.shape)}, expected {tuple(w.shape)}",
                        "each node's head output is (n, out)")
        parts.append(o.reshape(-1))
    if want_h is None:
        if h is not None:
            raise Wrong(f"{where}: returns memories, but h was None", "without memory, return (outputs, None)")
    else:
        if h is None or len(h) != len(want_h):
            raise Wrong(f"{where}: the memories are missing", "return the new h of every node, GRU(z, h)")
        parts += [as_tensor(hi, "a memory").reshape(-1) for hi in h]
    return torch.cat(parts)


def flat_step(outs, h) -> torch.Tensor:
    return torch.cat([o.reshape(-1).double() for o in outs if o is not None]
                     + [hi.reshape(-1).double() for hi in (h or [])])


def check_ex2(answer) -> None:
    hint = "follow gnn.py's docstring steps 1-3 (encode with p; rounds of up, body, down; GRU, heads)"
    with torch.no_grad():
        for nets, graph, x, h, rounds in node_cases():
            where = f"{graph.name}, rounds={rounds}, {'with' if h else 'without'} memory"
            expected = gnn.node_by_node(nets, graph, x, h, rounds)
            answer_h = None if h is None else list(h)
            got = flatten_step(call(answer, "node_by_node", nets, graph, list(x), answer_h, rounds), expected, where)
            variants = [Variant(flat_step(*node_by_node_variant(nets, graph, x, h, rounds, m)), f"{where}: {what}", vh)
                        for m, (what, vh) in NODE_MISTAKES.items() if (h is not None or m not in
                                                                       ("no_gru", "gru_swapped", "read_z", "old_h"))]
            check_value(got, flat_step(*expected), f"{where}: the outputs", hint, variants, tol=1e-4)


# ----------------------------------------------------------------------------
# ex3: L_RL through a T-step model roll-out, rlil.rollout and line 16 of rl_loss
# ----------------------------------------------------------------------------
def project_rl_loss_of_batch(policy, model, s0, h0, graph, horizon, deterministic=False):
    """The project's own: `rollout` (lines 10-15) and line 16 of `rl_loss` for one batch."""
    R, s, h = rlil.rollout(policy, model, s0, h0, graph, horizon, deterministic=deterministic)
    return -R.mean(), s, h


def rollout_variant(policy, model, s0, h0, graph, T, deterministic, mistake: str = ""):
    """rlil.rollout with one typical mistake: (R (B,), s_T, h_T)."""
    pi, f = policy.on_design(graph), model.on_design(graph)
    s, h, R = s0, torch.zeros_like(h0) if mistake == "zero_h" else h0, 0.0
    for _ in range(T + {"T+1": 1, "T-1": -1}.get(mistake, 0)):
        noisy = not deterministic and mistake != "no_obs_noise"
        noise = sim2d.obs_noise_like(s, graph) if noisy else None
        a, h = pi.act(sim2d.observe(s, graph, noise), h, deterministic=deterministic or mistake == "mean_action")
        s_next = f(s, a)
        r = sim2d.reward(s_next, a, s, graph) if mistake == "swapped" else sim2d.reward(s, a, s_next, graph)
        R = r if mistake == "last_only" else R + r
        if mistake != "no_advance":
            s = s_next
    return R, (s_next if mistake == "no_advance" else s), h


RL_MISTAKES = {
    "T-1": ("off by one step: T - 1 model steps", "T steps, Algorithm 1 line 12: for t = 1 ... T"),
    "T+1": ("off by one step: T + 1 model steps", "T steps, Algorithm 1 line 12: for t = 1 ... T"),
    "zero_h": ("the roll-out starts from zero hidden states, not h0",
               "set the policy's memory to h0, the buffer's hidden states (line 9: 'and set hidden state')"),
    "no_advance": ("the state is not advanced: every step starts from s0", "s~ <- f~(s~, a) after every step"),
    "swapped": ("the reward's arguments are swapped", "r(s~_t, a_t, s~_t+1): sim2d.reward(s, a, s_next, graph)"),
    "last_only": ("R holds the last step's reward only", "R = R + r every step (line 14)"),
    "no_obs_noise": ("without observation noise: o = O(s~) is noiseless when sampling",
                     "o ~ O(s~): sim2d.observe(s, graph, sim2d.obs_noise_like(s, graph)) unless deterministic"),
    "mean_action": ("actions are the policy's mean when sampling", "a ~ pi: pi.act(obs, h, deterministic)"),
}


def rl_inputs():
    """A small policy and model (hidden 8) on leg_none_wheel, 5 initial states, non-zero h0, T = 4."""
    torch.manual_seed(0)
    graph, cfg = sim2d.design_graph("leg_none_wheel"), gnn.GNNConfig(hidden=8)
    policy, model = gnn.ModularPolicy(cfg), gnn.ModularModel(cfg)
    s0 = torch.as_tensor(sim2d.sample_initial_states(graph, 5, np.random.default_rng(0)), dtype=torch.float32)
    a = torch.randn(5, graph.action_dim)
    model.fit_normalization([(graph, s0, a, s0 + 0.2 * torch.randn_like(s0))])    # changes of 0.2: R of order 1
    model.requires_grad_(False)                                    # frozen, as in the policy phase
    h0 = 0.5 * torch.randn(1 + graph.n_legs + graph.n_wheels, 5, cfg.hidden).tanh()
    return policy, model, s0, h0, graph, 4


def check_ex3(answer) -> None:
    policy, model, s0, h0, graph, T = rl_inputs()
    hint = "L_RL = -R, R = sum over T model steps of r(s~, a, s~'), the batch mean (Algorithm 1 lines 10-16)"
    for deterministic in (True, False):
        mode = f"deterministic={deterministic}"
        with seeded(1):
            got = call(answer, "rl_loss_of_batch", policy, model, s0, h0, graph, T, deterministic=deterministic)
        with seeded(1):
            want = project_rl_loss_of_batch(policy, model, s0, h0, graph, T, deterministic)
        if not (isinstance(got, (tuple, list)) and len(got) == 3):
            raise Wrong(f"{mode}: returns a {type(got).__name__}, expected (L_RL, s_T, h_T)",
                        "return the loss, the final state and the final hidden state")
        variants = []
        for m, (what, vh) in RL_MISTAKES.items():
            if deterministic and m in ("no_obs_noise", "mean_action"):
                continue
            with seeded(1):
                R, s_T, _ = rollout_variant(policy, model, s0, h0, graph, T, deterministic, m)
            variants.append(Variant(-R.mean(), f"{mode}: {what}", vh))
        with seeded(1):
            R, _, _ = rollout_variant(policy, model, s0, h0, graph, T, deterministic)
        variants += [Variant(R.mean(), f"{mode}: sign: L_RL = +R", "L_RL = -R (line 16): minimise it, maximise R"),
                     Variant(-R.sum(), f"{mode}: L_RL sums over the batch", "take the batch mean: -R.mean()")]
        check_value(got[0], want[0], f"{mode}: L_RL", hint, variants, tol=1e-5,
                    shape_hint="L_RL is one number: the batch mean of -R")
        check_value(got[1], want[1], f"{mode}: s_T, the final state", "return the state after the T-th model step",
                    [Variant(s0, f"{mode}: s_T is s0", "return the state after the T-th model step")], tol=1e-4)
        check_value(got[2], want[2], f"{mode}: h_T, the final hidden state", "return the policy's memory after step T",
                    [Variant(h0, f"{mode}: h_T is h0", "return the memory pi.act gave at the last step")], tol=1e-4)
    # dL/dtheta must flow through every step (the deterministic case, no draws)
    grads = []
    for fn in (lambda: call(answer, "rl_loss_of_batch", policy, model, s0, h0, graph, T, deterministic=True),
               lambda: project_rl_loss_of_batch(policy, model, s0, h0, graph, T, True)):
        policy.zero_grad()
        loss = fn()[0]
        if not (isinstance(loss, torch.Tensor) and loss.requires_grad):
            raise Wrong("L_RL carries no gradient",
                        "no .item(), .detach() or torch.no_grad(): the policy learns from dL_RL/dtheta")
        loss.backward()
        grads.append(torch.cat([(p.grad if p.grad is not None else torch.zeros_like(p)).reshape(-1)
                                for p in policy.parameters()]))
    if not close(grads[0].double(), grads[1].double(), 1e-4):
        raise Wrong("L_RL is right but dL_RL/dtheta is not: part of the roll-out is detached",
                    "the gradient must flow through every action and model step: no .detach() in the loop")


# ----------------------------------------------------------------------------
# ex4: L_IL with the entropy penalty (rlil.il_loss) and L_RLIL (rlil.rlil_loss)
# ----------------------------------------------------------------------------
def fake_demos(design: str, seed: int, episodes: int = 3, steps: int = 6) -> demo_lib.DemoData:
    """Random (o, a) pairs shaped like T^i of one design: no simulator, made in microseconds."""
    graph, rng = sim2d.design_graph(design), np.random.default_rng(seed)
    states = sim2d.nominal_state(graph) + 0.1 * rng.standard_normal((episodes, steps + 1, graph.state_dim))
    obs = sim2d.observe(states[:, :-1], graph, sim2d.obs_noise_like(states[:, :-1], graph, rng))
    return demo_lib.DemoData(graph.code, obs, rng.uniform(-1, 1, (episodes, steps, graph.action_dim)), states,
                             states[:, -1, 0] - states[:, 0, 0], np.zeros(episodes, bool))


def il_inputs():
    torch.manual_seed(0)
    cfg = rlil.preset("tiny", il_batch=4, il_window=3, gnn=gnn.GNNConfig(hidden=8))
    demo_data = {d.design: d for d in (fake_demos("hexapod", 1), fake_demos("car", 2))}
    return rlil.ModularPolicy(cfg.gnn), demo_data, cfg


def il_terms(policy, demo_data, cfg, seed: int, memory: bool = True):
    """Per design, log pi (n, W) and the entropy (n, W) on the windows il_loss draws with `seed`."""
    rng, out = np.random.default_rng(seed), []
    for design, demo in demo_data.items():
        obs, actions, graph = rlil.demo_windows(design, demo, cfg, rng)
        if memory:
            out.append(policy.sequence_log_prob(obs, actions, graph))
            continue
        h0, lp, ent = policy.initial_hidden(cfg.il_batch, graph), [], []
        for k in range(cfg.il_window):                        # every step from a zero memory
            mean, log_std, _ = policy({key: v[:, k] for key, v in obs.items()}, graph, h0)
            lp.append(gnn.gaussian_log_prob(mean, log_std, actions[:, k]))
            ent.append(gnn.gaussian_entropy(log_std))
        out.append((torch.stack(lp, 1), torch.stack(ent, 1)))
    return out


def combined_variants(l_rl, l_il, H, lam, beta) -> list[Variant]:
    return [Variant(l_rl + lam * l_il, "missing entropy penalty",
                    "the project trains on L_RL + lambda (L_IL + entropy_weight * H) (optimize_policy, line 19)"),
            Variant(l_rl + lam * (l_il - beta * H), "the entropy is rewarded, not penalised",
                    "+ entropy_weight * H: the paper 'penalize[s] the entropy' so the policy is 'certain'"),
            Variant(l_rl + lam * l_il + beta * H, "the entropy penalty sits outside lambda's bracket",
                    "the project adds it to L_IL, inside lambda (L_IL + entropy_weight * H), so it decays with lambda"),
            Variant(lam * l_rl + l_il + beta * H, "lambda weighs L_RL", "lambda weighs L_IL: L_RL + lambda (...)"),
            Variant(lam * l_rl + (l_il + beta * H), "lambda weighs L_RL", "lambda weighs L_IL: L_RL + lambda (...)"),
            Variant(-l_rl + lam * (l_il + beta * H), "L_RL enters with the wrong sign", "L = L_RL + lambda (...)"),
            Variant(lam * (l_il + beta * H), "L_RL is missing", "L = L_RL + lambda (L_IL + entropy_weight * H)"),
            Variant(l_rl + lam * (l_il + H), "the entropy weight is missing", "entropy_weight * H")]


def check_ex4(answer) -> None:
    policy, demo_data, cfg = il_inputs()
    hint = "per design: loss - log_prob.mean() and entropy + ent.mean(), with policy.sequence_log_prob on the windows"
    got = call(answer, "il_loss", policy, demo_data, cfg, np.random.default_rng(7))
    want = rlil.il_loss(policy, demo_data, cfg, np.random.default_rng(7))
    if not (isinstance(got, (tuple, list)) and len(got) == 2):
        raise Wrong(f"il_loss returns a {type(got).__name__}, expected (L_IL, entropy)", "return both")
    (lp1, e1), (lp2, e2) = il_terms(policy, demo_data, cfg, 7)
    (nm1, _), (nm2, _) = il_terms(policy, demo_data, cfg, 7, memory=False)
    with torch.no_grad():
        check_value(got[0], want[0], "L_IL", hint, [
            Variant(lp1.mean() + lp2.mean(), "sign: L_IL = +log-likelihood", "L_IL = -sum log pi(a | o, d)"),
            Variant(-lp1.sum() - lp2.sum(), "L_IL sums over the pairs, as the paper's equation writes",
                    "the project takes the mean over the pairs (the sum / their number, a constant lambda absorbs)"),
            Variant(-lp1.sum(1).mean() - lp2.sum(1).mean(), "L_IL sums over each window's steps",
                    "take the mean over all pairs of a design (log_prob.mean())"),
            Variant(-(lp1.mean() + lp2.mean()) / 2, "L_IL averages over the designs",
                    "eqn. (IL_loss) sums over d in D_demo: add each design's term"),
            Variant(-lp2.mean(), "L_IL counts the last design only", "accumulate: loss = loss - log_prob.mean()"),
            Variant(-nm1.mean() - nm2.mean(), "every step starts from a zero memory",
                    "the policy is recurrent: run each window through it, carrying h (sequence_log_prob)")], tol=1e-4)
        check_value(got[1], want[1], "the entropy", hint, [
            Variant(-(e1.mean() + e2.mean()), "the entropy has the wrong sign", "entropy = entropy + ent.mean()"),
            Variant(e1.sum() + e2.sum(), "the entropy sums over the pairs", "take the mean over pairs, like L_IL"),
            Variant((e1.mean() + e2.mean()) / 2, "the entropy averages over designs", "sum over designs, like L_IL"),
            Variant(e2.mean(), "the entropy counts the last design only", "accumulate over designs")], tol=1e-4)
    for name, value in (("L_IL", got[0]), ("the entropy", got[1])):
        if not (isinstance(value, torch.Tensor) and value.requires_grad):
            raise Wrong(f"{name} carries no gradient",
                        "no .item(), .detach() or torch.no_grad(): both terms train the policy")
    cases = [(-1.3, 2.7, -0.8, 10.0, 0.01), (0.4, 1.9, 1.2, 2.5, 0.1)]
    for l_rl, l_il, H, lam, beta in cases:
        args = [torch.tensor(v) for v in (l_rl, l_il, H)] + [lam, beta]
        got = call(answer, "rlil_loss", *args)
        want = rlil.rlil_loss(args[0], args[1] + beta * args[2], lam)
        check_value(got, want, f"L_RLIL (L_RL={l_rl}, L_IL={l_il}, H={H}, lambda={lam}, entropy_weight={beta})",
                    "L = L_RL + lambda (L_IL + entropy_weight * H)", combined_variants(*args), tol=1e-6)


def project_il():
    """The project's own: `il_loss`, and `rlil_loss` as optimize_policy calls it (line 19)."""
    def combined(loss_rl, loss_il, entropy, il_weight, entropy_weight):
        return rlil.rlil_loss(loss_rl, loss_il + entropy_weight * entropy, il_weight)
    return types.SimpleNamespace(il_loss=rlil.il_loss, rlil_loss=combined)


# ----------------------------------------------------------------------------
# ex5: the adaptive learning rate with validation revert, rlil.AdaptiveLearningRate
# ----------------------------------------------------------------------------
START, LR, LR_DROP = 1.0, 0.1, 0.5
EVENTS = [("check", 1.5), ("check", 0.5), ("check", 1.2), ("check", math.nan), ("revert", None)]


def lr_trace(cls) -> tuple[list[dict], dict]:
    """Run the class through EVENTS on a tiny policy, two Adam steps before each event; after each,
    record reverts, parameters, rates, Adam's state and `last`.  Also returns reference points."""
    torch.manual_seed(0)
    policy, x = torch.nn.Linear(3, 2), torch.randn(4, 3)
    opt = torch.optim.Adam(policy.parameters(), lr=LR)

    def params():
        return torch.cat([p.detach().reshape(-1) for p in policy.parameters()]).clone()

    def adam():
        st = opt.state_dict()["state"]
        return torch.cat([torch.cat([torch.as_tensor(v["step"]).reshape(1).float(), v["exp_avg"].reshape(-1),
                                     v["exp_avg_sq"].reshape(-1)]) for v in st.values()]) if st else torch.zeros(0)

    start = params()
    rule = call(types.SimpleNamespace(AdaptiveLearningRate=cls), "AdaptiveLearningRate", policy, opt, START, LR_DROP)
    trace, before = [], []
    for kind, value in EVENTS:
        for _ in range(2):
            opt.zero_grad()
            policy(x).pow(2).sum().backward()
            opt.step()
        before.append(params())
        call(rule, kind, *([] if value is None else [value]))
        trace.append({"reverts": getattr(rule, "reverts", None), "params": params(), "lr": getattr(rule, "lr", None),
                      "opt_lr": opt.param_groups[0]["lr"], "adam": adam(), "last": getattr(rule, "last", None)})
    return trace, {"start": start, "before": before}


def event_name(k: int) -> str:
    kind, value = EVENTS[k]
    return f"{kind}({value})" if value is not None else f"{kind}()"


def lr_message(k: int, field: str, got: dict, want: dict, points: dict) -> Wrong:
    """What a difference in `field` after event k most likely means."""
    ev, kind, value = event_name(k), *EVENTS[k]
    if field == "reverts":
        if kind == "revert":
            return Wrong(f"after {ev}: reverts is {got['reverts']}, expected {want['reverts']}", "self.reverts += 1")
        if value == 1.5:
            return Wrong(f"{ev} reverted, but 1.5 is above the phase's start ({START})",
                         "revert only when the value is below the start value, or not finite")
        if value == 0.5:
            return Wrong(f"{ev} did not revert (or did not count it): 0.5 is below the phase's start ({START})",
                         "'If the current validation reward is lower than the initial validation reward, ... revert'")
        if value == 1.2:
            return Wrong(f"{ev} reverted: 1.2 is below the last check (1.5) but not below the phase's start ({START})",
                         "compare with the start value, self.start: the paper's 'initial validation reward'")
        return Wrong(f"{ev} did not revert: a NaN validation reward must revert too",
                     "revert when value < self.start or not math.isfinite(value)")
    if field == "params":
        if close(got["params"], points["start"], 1e-7):
            return Wrong(f"after {ev}: the policy went back to the phase's start, not to the last passed check",
                         "take a new snapshot at every passed check: self.last = value; self.snapshot()")
        if close(got["params"], points["before"][k], 1e-7):
            return Wrong(f"after {ev}: the policy's parameters were not restored",
                         "self.policy.load_state_dict(self.saved[0])")
        return Wrong(f"after {ev}: the policy's parameters differ from the project's",
                     "a revert loads the last snapshot; a passed check takes a new one")
    if field == "lr":
        if got["lr"] == want["lr"] / LR_DROP:
            return Wrong(f"after {ev}: the learning rate did not drop", "self.lr *= self.lr_drop on every revert")
        if got["lr"] == LR * LR_DROP:
            return Wrong(f"after {ev}: lr is lr_drop times the first rate, {got['lr']}; expected {want['lr']}",
                         "every revert multiplies the current rate: self.lr *= self.lr_drop")
        return Wrong(f"after {ev}: lr is {got['lr']}, expected {want['lr']}", "self.lr *= self.lr_drop on every revert")
    if field == "opt_lr":
        return Wrong(f"after {ev}: self.lr is right but Adam steps at {got['opt_lr']}, expected {want['opt_lr']}",
                     "set group['lr'] = self.lr for every group in self.opt.param_groups (after loading Adam's state)")
    if field == "adam":
        return Wrong(f"after {ev}: Adam's state (step count, moments) was not restored",
                     "self.opt.load_state_dict(self.saved[1]): the moments belong to the parameters you went back to")
    return Wrong(f"after {ev}: last is {got['last']}, expected {want['last']}",
                 "a passed check sets self.last = value (the revert keeps it)")


def check_ex5(answer) -> None:
    cls = getattr(answer, "AdaptiveLearningRate", None)
    if cls is None:
        raise Wrong("the answer has no AdaptiveLearningRate", "keep the stub's class name")
    got, points = lr_trace(cls)
    want, _ = lr_trace(rlil.AdaptiveLearningRate)
    for k, (g, w) in enumerate(zip(got, want)):
        for field in ("reverts", "params", "lr", "opt_lr", "adam", "last"):
            same = (close(g[field], w[field], 1e-7) if isinstance(w[field], torch.Tensor)
                    else g[field] == w[field] or (isinstance(w[field], float) and g[field] is not None
                                                  and math.isclose(g[field], w[field], rel_tol=1e-9)))
            if not same:
                raise lr_message(k, field, g, w, points)


# ----------------------------------------------------------------------------
# ex6: the experiment, the area under the curve of two runs
# ----------------------------------------------------------------------------
def read_iterations(run) -> list[dict]:
    """The metrics rows of a run directory (or of its metrics.json): one dict per iteration, 0 first."""
    path = Path(run)
    return json.loads((path / "metrics.json" if path.is_dir() else path).read_text())["iterations"]


def project_auc_difference(rl_run, rlil_run) -> float:
    """The project's own: experiments/stats.area_under_curve of each run, RL+IL - RL."""
    def auc(run):
        curve = {row["iteration"]: row["distance_m"] for row in read_iterations(run)}
        return stats.area_under_curve(curve, max(curve))
    return auc(rlil_run) - auc(rl_run)


AUC_CASES = [([0.5, 6.0, 9.0, 9.5], [8.0, 8.5, 9.0, 9.2]), ([2.42, 9.83, 9.83], [8.52, 9.21, 9.47])]


def check_ex6(answer) -> None:
    hint = "mean distance_m over iterations 1..N of each run, then RL+IL - RL (experiments/stats.area_under_curve)"
    with tempfile.TemporaryDirectory() as tmp:
        for k, (rl, rlil_curve) in enumerate(AUC_CASES):
            paths = []
            for name, curve in (("rl", rl), ("rlil", rlil_curve)):
                run = Path(tmp) / f"case{k}-{name}"
                run.mkdir()
                rows = [{"iteration": i, "distance_m": d, "distance_min_m": d - 0.1, "seconds": 1.0}
                        for i, d in enumerate(curve)]
                (run / "metrics.json").write_text(json.dumps({"config": {"iters": len(curve) - 1}, "iterations": rows}))
                paths.append(run if k == 0 else run / "metrics.json")       # a run directory, then a file
            a, b = np.array(rl), np.array(rlil_curve)
            check_value(call(answer, "auc_difference", *paths), project_auc_difference(*paths),
                        f"auc_difference on curves RL {rl}, RL+IL {rlil_curve}", hint, [
                            Variant(b.mean() - a.mean(), "iteration 0 is counted",
                                    "iteration 0 is before any RL+IL step (lines 1-2 only): use iterations 1..N"),
                            Variant(b[:-1].mean() - a[:-1].mean(), "off by one: iterations 0..N-1",
                                    "use iterations 1..N, the last one included"),
                            Variant(b[1:].sum() - a[1:].sum(), "a sum over iterations, not the mean",
                                    "the area here is the mean over iterations 1..N, in metres"),
                            Variant(b[-1] - a[-1], "the last iteration only", "average over iterations 1..N"),
                            Variant(a[1:].mean() - b[1:].mean(), "sign: RL - RL+IL", "RL+IL - RL, > 0: demos helped")],
                        tol=1e-9, shape_hint="return one number")


CLASS_DEMO_CSV = ROOT / "results" / "class_demo.csv"


def committed_curves(path: Path = CLASS_DEMO_CSV) -> dict:
    """{(method, seed): {iteration: distance_m}} of the committed class-demo runs: the car at the
    tiny budget, RL and RL+IL with the car's own demos, seeds 0-4
    (`python train.py --figure3 --preset tiny --panels b --seeds 5`)."""
    curves = {}
    with open(path) as f:
        for row in csv.DictReader(f):
            curves.setdefault((row["method"], int(row["seed"])), {})[int(row["iteration"])] = float(row["distance_m"])
    return curves


def committed_auc_differences(path: Path = CLASS_DEMO_CSV) -> dict:
    """{seed: RL+IL - RL of the area under the curve} in the committed class-demo runs."""
    curves = committed_curves(path)
    iters = max(max(c) for c in curves.values())
    auc = {key: stats.area_under_curve(curve, iters) for key, curve in curves.items()}
    return {seed: auc["RL+IL", seed] - auc["RL", seed] for seed in sorted({seed for _, seed in curves})}


def experiment_report(auc_difference, prediction: str, rl_run: str, rlil_run: str) -> int:
    """ex6's `__main__` with two runs: the prediction, both curves, the student's number and the
    committed one.  Returns the exit status (2 if a run has no metrics.json)."""
    rows = {}
    for name, run in (("RL", rl_run), ("RL+IL", rlil_run)):
        try:
            rows[name] = read_iterations(run)
        except (OSError, ValueError, KeyError) as e:
            print(f"ex6: error: no metrics in {run} ({type(e).__name__}); run the two train.py commands first",
                  file=sys.stderr)
            return 2
    print(f"your prediction: {prediction or '(none written: set PREDICTION before you look)'}")
    for name, run in (("RL", rl_run), ("RL+IL", rlil_run)):
        print(f"{name:6s} {run}: " + " ".join(f"{r['distance_m']:.2f}" for r in rows[name]) + " m per iteration")
    try:
        mine = float(auc_difference(rl_run, rlil_run))
    except NotImplementedError:
        print("auc_difference: not written yet (python lesson/grade.py ex6 grades it)")
        return 1
    committed = committed_auc_differences()
    print(f"your auc_difference, RL+IL - RL (mean m over iterations 1-{len(rows['RL']) - 1}): {mine:.2f}")
    print("committed, results/class_demo.csv, the same two commands, seeds "
          f"{min(committed)}-{max(committed)}: " + " ".join(f"{v:.2f}" for v in committed.values())
          + f" (seed 0: {committed[0]:.2f})")
    return 0


# ----------------------------------------------------------------------------
# The exercises, and the command line
# ----------------------------------------------------------------------------
@dataclass
class Exercise:
    file: str                 # in lesson/exercises/
    names: str                # what the student writes
    check: object             # check(answer) raises Wrong or NotWritten
    solution: object          # () -> the project's own function(s), as a namespace


EXERCISES = {
    "ex1": Exercise("ex1_reward.py", "reward", check_ex1, lambda: types.SimpleNamespace(reward=sim2d.reward)),
    "ex2": Exercise("ex2_message_passing.py", "node_by_node", check_ex2,
                    lambda: types.SimpleNamespace(node_by_node=gnn.node_by_node)),
    "ex3": Exercise("ex3_rl_loss.py", "rl_loss_of_batch", check_ex3,
                    lambda: types.SimpleNamespace(rl_loss_of_batch=project_rl_loss_of_batch)),
    "ex4": Exercise("ex4_il_loss.py", "il_loss and rlil_loss", check_ex4, project_il),
    "ex5": Exercise("ex5_adaptive_lr.py", "AdaptiveLearningRate", check_ex5,
                    lambda: types.SimpleNamespace(AdaptiveLearningRate=rlil.AdaptiveLearningRate)),
    "ex6": Exercise("ex6_experiment.py", "auc_difference", check_ex6,
                    lambda: types.SimpleNamespace(auc_difference=project_auc_difference)),
}


def exercise_key(name: str) -> str | None:
    """'ex3', '3', 'ex3_rl_loss' or 'ex3_rl_loss.py' -> 'ex3'; None if unknown."""
    stem = Path(name).name.removesuffix(".py")
    for key, ex in EXERCISES.items():
        if stem in (key, key[2:], ex.file.removesuffix(".py")):
            return key
    return None


def shown(path: Path) -> str:
    """A path as the student would type it: relative to the current folder where it can be."""
    try:
        return str(path.resolve().relative_to(Path.cwd()))
    except ValueError:
        return str(path)


def load_answer(path: Path, key: str):
    """Import the student's file as a module (Wrong if it does not import)."""
    spec = importlib.util.spec_from_file_location(f"lesson_answer_{key}", path)
    module = importlib.util.module_from_spec(spec)
    try:
        spec.loader.exec_module(module)
    except Exception as e:
        if TRACEBACK:
            raise
        where = f" (line {e.lineno})" if isinstance(e, SyntaxError) else ""
        first = (str(e).splitlines() or [""])[0][:120]
        raise Wrong(f"{shown(path)} does not import: {type(e).__name__}: {first}{where}",
                    "add --traceback to the grade command to see where") from None
    return module


def grade(key: str, answer, label: str) -> tuple[int, list[str]]:
    """(exit status, lines to print) of grading `answer` for exercise `key`."""
    ex = EXERCISES[key]
    try:
        torch.set_num_threads(1)                # tiny tensors: one thread is fastest (conftest.py)
        with seeded(0):
            ex.check(answer)
    except NotWritten as e:
        return 1, [f"not written yet: {e} still raises NotImplementedError",
                   f"hint: fill in the YOUR CODE HERE part of {label}"]
    except Wrong as e:
        return 1, [f"fail: {e.what}"] + ([f"hint: {e.hint}"] if e.hint else [])
    lines = ["pass"]
    if key == "ex6" and hasattr(answer, "PREDICTION") and not str(answer.PREDICTION).strip():
        lines.append("note: write your prediction in PREDICTION too (docs/lesson.md, part 6)")
    return 0, lines


def main(argv=None) -> int:
    global TRACEBACK
    parser = sim2d.CliParser(prog="lesson/grade.py", description=__doc__.split("\n")[0])
    parser.add_argument("exercise", nargs="?", help=f"one of {', '.join(EXERCISES)}")
    which = parser.add_mutually_exclusive_group()
    which.add_argument("--file", help="grade this file instead of lesson/exercises/<exercise>.py")
    which.add_argument("--solution", action="store_true", help="grade the project's own function (passes)")
    parser.add_argument("--traceback", action="store_true", help="let an exception in the answer show its traceback")
    try:
        args = parser.parse_args(argv)
    except SystemExit as e:
        return e.code
    key = exercise_key(args.exercise) if args.exercise else None
    if key is None:
        said = f"unknown exercise {args.exercise!r}" if args.exercise else "name an exercise"
        print(f"lesson/grade.py: error: {said}: use one of {', '.join(EXERCISES)}", file=sys.stderr)
        return 2
    TRACEBACK = args.traceback
    try:
        if args.solution:
            answer, label = EXERCISES[key].solution(), "the project's own function"
        else:
            path = Path(args.file) if args.file else EXERCISES_DIR / EXERCISES[key].file
            if not path.is_file():
                print(f"lesson/grade.py: error: no such file: {path}", file=sys.stderr)
                return 2
            answer, label = load_answer(path, key), shown(path)
        status, lines = grade(key, answer, label)
    except Wrong as e:
        status, lines = 1, [f"fail: {e.what}", f"hint: {e.hint}"]
    finally:
        TRACEBACK = False
    print("\n".join(lines))
    return status


if __name__ == "__main__":
    sys.exit(main())
