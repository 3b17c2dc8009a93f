"""Algorithm 1 of the paper (MBRL with IL for modular robots), read top to bottom.

Paper: Whitman & Choset, "Learning Modular Robot Locomotion from Demonstrations",
Sec. III and Algorithm 1.  The losses and phases are named functions; the
algorithm itself is the one loop in `algorithm1`, its lines marked `# line N`
in Algorithm 1's order:

    pretrain_bc              line 1      behavioural cloning on T_demo, eqn. (IL_loss)
    collect_random_rollouts  line 2      random spline actions (Sec. III-B)
    train_model              line 5      modular model f~_phi on T_train (Sec. III-C)
    optimize_policy          lines 7-26  K steps of L = L_RL + lambda L_IL:
      init_buffer / refresh_buffer       lines 7, 22-25: initial states with hidden states
      rl_loss, rollout                   lines 9-16, eqn. (RL_loss)
      il_loss                            lines 17-19, eqn. (IL_loss), + entropy penalty (Sec. III-J)
      rlil_loss                          line 19, eqn. (RLIL_loss)
      AdaptiveLearningRate               Sec. III-J: validation reward, revert, lower rate
    add_policy_rollouts      lines 27-29 policy data without and with correlated noise (collect_policy_rollouts)
    decay_il_weight          line 30
    evaluate_iteration       not in Algorithm 1: Sec. IV's distance in 200 steps, per iteration

Not in the paper, each behind a switch and kept together in the last section of
this file, both on by default (docs/results.md gives their measurements): the
first model also sees the clone's roll-outs (`--clone-data`,
`add_clone_rollouts`) and an improvement check that keeps the previous policy
when the new one does worse in the simulator (`--keep-better`,
`improvement_check`).  `--clone-data off --keep-better off` is the paper's
Algorithm 1.  One more, off by default and on in `--preset walk`: `--random-waves`
(line 2's actions as sine waves, `sim2d.random_wave_actions`).  Under screen, off by default:
`--phase-tries P` (P policy phases an iteration, the best in the simulator kept, `best_of_phases`).  Mechanisms that
were measured and did not help are not in the code; docs/history/ has their results.

The command line is train.py:
    python train.py --train leg_none_wheel --demos hexapod car
    python train.py --train car --preset tiny          # class demo
"""
from __future__ import annotations

import copy
import dataclasses
import math
import time
from dataclasses import dataclass, field

import numpy as np
import torch

import demos as demo_lib
import sim2d
from gnn import GNNConfig, ModularModel, ModularPolicy


# ----------------------------------------------------------------------------
# Config: every knob of Algorithm 1 (train.py makes each field a flag; the
# docstring under a field is its help text: what it is and its usual range)
# ----------------------------------------------------------------------------
@dataclass
class Config:
    """Every knob of Algorithm 1.  Defaults: the README's main command."""

    train: tuple[str, ...] = ("leg_none_wheel",)
    """d_train: design(s) trained; several sum their RL losses"""
    demos: tuple[str, ...] = ()
    """D_demo: demonstration designs; none = plain RL (lambda = 0, no pre-training)"""
    iters: int = 5
    """outer iterations of Algorithm 1 (paper: 5)"""
    seed: int = 0
    """the one seed everything derives from"""
    threads: int = 1
    """torch CPU threads; a run's digits depend on it (float sums round differently); 1 is fastest for
    these small tensors (docs/gnn.md)"""
    # Line 2 / Sec. III-B: random spline actions
    random_episodes: int = 32
    """random-action episodes per training design (paper: not stated); 8-64"""
    episode_steps: int = 100
    """control steps per collected episode (paper: 100)"""
    random_action_std: float = 1.0
    """std of the spline knots, in normalised action units; 0.5-1"""
    # Lines 27-29: data from the policy
    policy_episodes: int = 16
    """policy episodes per design and iteration, once without and once with noise"""
    policy_noise_std: float = 0.3
    """knot std of the policy data's correlated noise; below random_action_std"""
    # Demonstrations (Sec. III-D): the paper's 50 x 100
    demo_episodes: int = 50
    """demonstration episodes per demo design (paper: 50)"""
    demo_steps: int = 100
    """control steps per demonstration episode (paper: 100)"""
    demo_noise: float = 0.15
    """std of smooth noise on the demonstrators' executed, not recorded, actions, so T_demo shows
    recoveries (DART); 0 = the paper; 0-0.3"""
    # Line 1: behavioural cloning
    bc_steps: int = 1000
    """Adam steps of pre-training; 0 skips line 1; 300-3000"""
    # Line 5: model learning
    model_steps: int = 1500
    """model Adam steps at the first iteration; 500-5000"""
    finetune_steps: int = 500
    """model Adam steps in later iterations (fine-tuning); 0-2000"""
    model_batch: int = 512
    """transitions per design per model step; 128-2048"""
    model_lr: float = 1e-3
    """model learning rate; 1e-4 to 3e-3"""
    # Lines 7-26: policy optimisation
    policy_steps: int = 120
    """K, policy gradient steps per iteration; 50-1000"""
    horizon: int = 20
    """T, model roll-out length (truncated BPTT window); 5-50, at most episode_steps and eval_steps"""
    batch: int = 64
    """N_batch, initial states per policy step and design; at most buffer_size"""
    buffer_size: int = 256
    """|B|, initial states with hidden states per design"""
    update_rate: int = 10
    """every this many steps, refresh half of B (lines 22-25)"""
    policy_lr: float = 1e-3
    """learning rate at the start of every policy phase (adapted, Sec. III-J)"""
    lr_drop: float = 0.5
    """factor on the learning rate at every validation revert; 0-1"""
    grad_clip: float = 10.0
    """max gradient norm of a policy step (BPTT through T model steps)"""
    validate_every: int = 20
    """policy steps between validation checks"""
    validation_multiple: int = 10
    """validation set = this many batches of initial states (paper: 10)"""
    il_weight: float = 10.0
    """lambda at iteration 1 (eqn. RLIL_loss); 1-10"""
    il_decay: float = 0.5
    """lambda <- il_decay * lambda after every iteration (line 30); 0-1"""
    il_batch: int = 32
    """demo windows per design per step"""
    il_window: int = 8
    """control steps per demo window (the policy is recurrent); at most demo_steps"""
    entropy_weight: float = 0.01
    """weight of the entropy penalty on demo observations (Sec. III-J); 0-0.1"""
    # Evaluation (Sec. IV): distance in 200 control steps
    eval_episodes: int = 8
    """perturbed starts per evaluation"""
    eval_steps: int = 200
    """control steps per evaluation (paper: 200 = 16.7 s)"""
    # Not in the paper (the last section of this file); off = the paper
    clone_data: bool = True
    """the first model also fits the cloned policy's roll-outs, collected after line 1 as lines 28-29
    collect (no effect without demos); off = the paper"""
    keep_better: bool = True
    """after lines 28-29, keep the previous policy when the new one's noiseless roll-outs return less
    than the kept one's, minus improvement_margin; off = the paper"""
    improvement_margin: float = 0.0
    """with keep_better: return (about metres per episode) a new policy may lose and still be kept; 0-2"""
    phase_tries: int = 1
    """policy phases (lines 7-26) per iteration, each from the same policy with its own draws; the try
    whose noiseless line-28 roll-outs return most in the simulator is kept, and only its roll-outs join
    T_train (`best_of_phases`, not in the paper); 1 = the paper; 1-4"""
    random_waves: bool = False
    """line 2's random actions are sine waves (sim2d.random_wave_actions: one random period per
    episode, a random amplitude and phase per joint) instead of splines, so the joints swing instead
    of resting at a limit; off = the paper"""
    gnn: GNNConfig = field(default_factory=GNNConfig)


# Named budgets.  "tiny" is the tests' budget and a class demo
# (`python train.py --train car --preset tiny`): the car learns to drive in it.
# "walk" is the budget at which plain RL learns to walk the hexapod (Figure 3's panel (a),
# docs/results.md): 16x the data per iteration, line 2's actions as sine waves, a log-std
# floor of -1.0 for the policy's noise, K = 480 policy steps on batches of 16 initial states
# (the same 7,680 starts a phase as K = 120 at 64: part 21 of the diagnosis), 15 iterations;
# 9-18 minutes a run on one core.
PRESETS = {
    "default": {},
    "tiny": dict(iters=2, threads=1, random_episodes=8, episode_steps=40, policy_episodes=4,
                 demo_episodes=8, demo_steps=40, bc_steps=100, model_steps=300, finetune_steps=100,
                 model_batch=256, policy_steps=30, horizon=10, batch=16, buffer_size=32, update_rate=5,
                 validate_every=10, validation_multiple=2, il_batch=8, il_window=4, eval_episodes=4,
                 eval_steps=100, gnn=GNNConfig(hidden=32)),
    "walk": dict(iters=15, random_episodes=512, policy_episodes=256, random_waves=True,
                 policy_steps=480, batch=16, gnn=GNNConfig(log_std_min=-1.0)),
}


def from_preset(cls, presets: dict, name: str, **overrides):
    """`cls` (a config dataclass) with a named budget of `presets`, some fields overridden."""
    if name not in presets:
        raise ValueError(f"unknown preset {name!r}: use one of {', '.join(presets)}")
    return cls(**{**presets[name], **overrides})


def preset(name: str = "default", **overrides) -> Config:
    """The Config of a named budget, with some fields overridden."""
    return from_preset(Config, PRESETS, name, **overrides)


MAX_SEED = 2 ** 63 - 1        # seeds are 0..MAX_SEED (numpy takes any, torch.manual_seed 64 bits)


def check_ranges(cfg, at_least: dict) -> None:
    """A one-line ValueError naming the first numeric field of `cfg` or `cfg.gnn` out of range:
    every number finite, the seed at most MAX_SEED, a field named in `at_least` at least that,
    log-std bounds any finite number, any other field positive."""
    numeric = [(f.name, getattr(cfg, f.name)) for f in dataclasses.fields(cfg)
               if f.name not in ("train", "demos", "gnn")]
    numeric += [(f.name, getattr(cfg.gnn, f.name)) for f in dataclasses.fields(cfg.gnn)]
    for name, value in numeric:
        if isinstance(value, bool):
            continue
        if not math.isfinite(value):
            raise ValueError(f"{name} must be a finite number, got {value}")
        if name == "seed" and not 0 <= value <= MAX_SEED:
            raise ValueError(f"seed must be from 0 to {MAX_SEED} (2^63 - 1), got {value}")
        if name.startswith("log_std"):
            continue
        if name in at_least:
            ok, accepted = value >= at_least[name], f"at least {at_least[name]}"
        else:
            ok, accepted = value > 0, "positive"
        if not ok:
            raise ValueError(f"{name} must be {accepted}, got {value}")
    if cfg.gnn.log_std_min >= cfg.gnn.log_std_max:
        raise ValueError(f"log_std_min ({cfg.gnn.log_std_min}) must be below log_std_max ({cfg.gnn.log_std_max})")


def design_codes(field_name: str, designs) -> tuple[str, ...]:
    """Names or codes -> six-letter codes, each design once (a one-line ValueError otherwise)."""
    codes = tuple(sim2d.parse_design(d) for d in designs)
    for code in set(codes):
        if codes.count(code) > 1:
            raise ValueError(f"{field_name}: {sim2d.design_name(code)} is named twice; name each design once")
    return codes


AT_LEAST = {   # lower bounds of the numeric fields; the rest must be positive
    "seed": 0, "bc_steps": 0, "finetune_steps": 0, "random_action_std": 0.0, "policy_noise_std": 0.0,
    "il_weight": 0.0, "il_decay": 0.0, "entropy_weight": 0.0, "demo_noise": 0.0, "horizon": 2,
    "buffer_size": 2, "rounds": 0, "improvement_margin": 0.0}


def validate_config(cfg: Config) -> Config:
    """`cfg` with its designs as six-letter codes, or a one-line ValueError naming the first
    field that is out of range and what is accepted."""
    if not cfg.train:
        raise ValueError("train: name at least one design to train")
    cfg = dataclasses.replace(cfg, train=design_codes("train", cfg.train), demos=design_codes("demos", cfg.demos))
    for design in cfg.demos:
        demo_lib.check_demonstrable(sim2d.design_graph(design))
    check_ranges(cfg, AT_LEAST)
    if cfg.lr_drop > 1 or cfg.il_decay > 1:
        raise ValueError(f"lr_drop and il_decay must be at most 1, got {cfg.lr_drop} and {cfg.il_decay}")
    if cfg.horizon > min(cfg.episode_steps, cfg.eval_steps):
        raise ValueError(f"horizon ({cfg.horizon}) must not exceed episode_steps ({cfg.episode_steps}) "
                         f"or eval_steps ({cfg.eval_steps})")
    if cfg.batch > cfg.buffer_size:
        raise ValueError(f"batch ({cfg.batch}) must not exceed buffer_size ({cfg.buffer_size}): a batch draws from B")
    if cfg.il_window > cfg.demo_steps:
        raise ValueError(f"il_window ({cfg.il_window}) must not exceed demo_steps ({cfg.demo_steps})")
    return cfg


# ----------------------------------------------------------------------------
# Data: T_train, transitions per design, collected in the simulator
# ----------------------------------------------------------------------------
@dataclass
class Trajectories:
    """Episodes of one design: states (E, T+1, S) and applied actions (E, T, A), float32."""

    design: str
    states: torch.Tensor
    actions: torch.Tensor

    @classmethod
    def from_episodes(cls, run: sim2d.Episodes) -> "Trajectories":
        return cls(run.design, torch.tensor(run.states, dtype=torch.float32),
                   torch.tensor(run.actions, dtype=torch.float32))

    def transitions(self):
        """(s, a, s') flattened over episodes and time: (E*T, S), (E*T, A), (E*T, S)."""
        s, a = self.states, self.actions
        return s[:, :-1].reshape(-1, s.shape[-1]), a.reshape(-1, a.shape[-1]), s[:, 1:].reshape(-1, s.shape[-1])

    def __add__(self, other: "Trajectories") -> "Trajectories":      # T_train U T_new (line 29)
        return Trajectories(self.design, torch.cat([self.states, other.states]),
                            torch.cat([self.actions, other.actions]))


def new_seed(rng: np.random.Generator) -> int:
    """A simulator seed drawn from the run's generator."""
    return int(rng.integers(2 ** 31))


def collect_random_rollouts(design: str, cfg: Config, rng: np.random.Generator) -> Trajectories:
    """Algorithm 1 line 2 (Sec. III-B): 10 N(0, std^2) knots per DoF joined by a spline over an
    episode (the paper's 100 steps: cfg.episode_steps); with cfg.random_waves (not the paper, off by
    default) sine waves instead (sim2d.random_wave_actions)."""
    graph = sim2d.design_graph(design)
    if cfg.random_waves:
        actions = sim2d.random_wave_actions(rng, cfg.random_episodes, graph.action_dim, cfg.episode_steps)
    else:
        actions = sim2d.random_spline_actions(rng, cfg.random_episodes, graph.action_dim, cfg.episode_steps,
                                              std=cfg.random_action_std)              # (E, T, A)
    return Trajectories.from_episodes(sim2d.simulate(graph, lambda obs, s, t: actions[:, t], cfg.random_episodes,
                                                     cfg.episode_steps, seed=new_seed(rng)))


class PolicyActor:
    """The recurrent policy as a simulator controller: act(obs, state, t) -> (n, A) numpy actions.

    The policy's mean action, plus noise[:, t] when a noise array (n, T, A) is given.
    """

    def __init__(self, policy: ModularPolicy, design: str, n: int, noise: np.ndarray | None = None):
        graph, self.noise = sim2d.design_graph(design), noise
        with torch.no_grad():
            self.policy = policy.on_design(graph)                              # the weights do not change in an episode
        self.hidden = policy.initial_hidden(n, graph)                     # (nodes, n, H)

    @torch.no_grad()
    def __call__(self, obs: dict, state, t: int) -> np.ndarray:
        obs = {k: torch.as_tensor(v, dtype=torch.float32) for k, v in obs.items()}
        mean, self.hidden = self.policy.act(obs, self.hidden, deterministic=True)
        a = mean.numpy().astype(float)
        return a if self.noise is None else a + self.noise[:, t]


def collect_policy_rollouts(policy: ModularPolicy, design: str, cfg: Config,
                            rng: np.random.Generator) -> Trajectories:
    """Algorithm 1 line 28 (Sec. III-H): the policy without noise, then with time-correlated
    noise (the spline noise of Sec. III-B with the smaller std `policy_noise_std`)."""
    graph, n, steps = sim2d.design_graph(design), cfg.policy_episodes, cfg.episode_steps
    clean = sim2d.simulate(graph, PolicyActor(policy, design, n), n, steps, seed=new_seed(rng))
    noise = sim2d.random_spline_actions(rng, n, graph.action_dim, steps, std=cfg.policy_noise_std)  # (n, T, A)
    noisy = sim2d.simulate(graph, PolicyActor(policy, design, n, noise), n, steps, seed=new_seed(rng))
    return Trajectories.from_episodes(clean) + Trajectories.from_episodes(noisy)


def add_policy_rollouts(policy: ModularPolicy, data: dict[str, Trajectories], cfg: Config,
                        rng: np.random.Generator) -> dict[str, Trajectories]:
    """Algorithm 1 lines 28-29: T_train <- T_train U T_new for every training design; returns T_new."""
    return join_rollouts(data, {d: collect_policy_rollouts(policy, d, cfg, rng) for d in data})   # line 28


def join_rollouts(data: dict[str, Trajectories], new_data: dict[str, Trajectories]) -> dict[str, Trajectories]:
    """Algorithm 1 line 29: T_train <- T_train U T_new, design by design; returns T_new."""
    for design, traj in new_data.items():
        data[design] = data[design] + traj                                         # line 29
    return new_data


# ----------------------------------------------------------------------------
# Line 5: the model f~_phi
# ----------------------------------------------------------------------------
def model_loss(model: ModularModel, design: str, transitions, n: int, rng: np.random.Generator) -> torch.Tensor:
    """Sec. III-C: one-step regression of the state change on n random transitions of one design.
    transitions: (s, a, s') of T_train, `Trajectories.transitions()`, made once per phase."""
    s, a, s_next = transitions
    i = torch.from_numpy(rng.integers(len(s), size=n))
    return model.loss(s[i], a[i], s_next[i], sim2d.design_graph(design))


def train_model(model: ModularModel, data: dict[str, Trajectories], cfg: Config, rng: np.random.Generator,
                first: bool) -> float:
    """Algorithm 1 line 5 (Sec. III-C): supervised regression of the state change on T_train.

    At the first iteration the input and output normalisation is fitted to
    T_train and the model takes `model_steps` Adam steps; later iterations
    fine-tune it for `finetune_steps`.  Each step sums the loss of a mini-batch
    per training design.  Returns the mean loss (normalised MSE) over the last
    10 % of the steps (NaN if no steps).
    """
    flat = {d: traj.transitions() for d, traj in data.items()}             # (E*T, S), (E*T, A), (E*T, S)
    if first:
        model.fit_normalization([(sim2d.design_graph(d), *f) for d, f in flat.items()])
    steps = cfg.model_steps if first else cfg.finetune_steps
    opt = torch.optim.Adam(model.parameters(), lr=cfg.model_lr, foreach=True)   # foreach: one multi-tensor
    # update of all parameters instead of a loop over them; the same numbers, less per-step overhead
    losses = []
    for _ in range(steps):
        loss = 0.0
        for design in data:
            loss = loss + model_loss(model, design, flat[design], cfg.model_batch, rng)
        opt.zero_grad()
        loss.backward()
        opt.step()
        losses.append(loss.item())
    return float(np.mean(losses[-max(1, steps // 10):])) if losses else float("nan")


# ----------------------------------------------------------------------------
# The losses: eqn. (RL_loss), eqn. (IL_loss) with the entropy penalty, eqn. (RLIL_loss)
# ----------------------------------------------------------------------------
def rollout(policy: ModularPolicy, model, s0, h0, graph, horizon: int, deterministic: bool = False):
    """Algorithm 1 lines 10-15: a ~ pi(a | O(s~)), s~' = f~(s~, a), R = sum over the T steps of r(s~, a, s~').

    s0: (B, S) initial states, h0: (nodes, B, H) policy hidden states.  Returns
    the summed reward R (B,), the final state and hidden state.  Actions are
    reparameterised samples, so dR/dtheta flows through every model step.
    The model clips actions to [-1, 1] like the simulator; the reward's effort
    term sees them unclipped, which keeps a gradient that pulls saturated
    commands back into range.
    """
    pi, f = policy.on_design(graph), model.on_design(graph)           # weights gathered along the design's nodes once
    states, actions, h = [s0], [], h0
    for _ in range(horizon):
        s = states[-1]
        noise = None if deterministic else sim2d.obs_noise_like(s, graph)
        a, h = pi.act(sim2d.observe(s, graph, noise), h, deterministic=deterministic)   # (B, A), (nodes, B, H)
        states.append(f(s, a))                                                  # (B, S)
        actions.append(a)
    s = torch.stack(states)                                                     # (T + 1, B, S)
    total = sim2d.reward(s[:-1], torch.stack(actions), s[1:], graph).sum(0)     # (B,)
    return total, states[-1], h


def rl_loss(policy: ModularPolicy, model, buffers: dict, cfg: Config, rng) -> torch.Tensor:
    """Algorithm 1 lines 9-16, eqn. (RL_loss): L_RL = -R, the batch mean of the T-step model
    return from initial states and hidden states sampled from B, summed over d_train."""
    loss = 0.0
    for design, buffer in buffers.items():
        s0, h0 = buffer.sample(cfg.batch, rng)                                          # line 9
        R, _, _ = rollout(policy, model, s0, h0, sim2d.design_graph(design), cfg.horizon)   # lines 10-15
        loss = loss - R.mean()                                                          # line 16
    return loss


def demo_windows(design: str, demo: demo_lib.DemoData, cfg: Config, rng: np.random.Generator):
    """A batch of cfg.il_batch windows of cfg.il_window consecutive (o, a) pairs of one design's
    T^i, each from a random episode and first step: the observations {"body": (n, W, 3), ...},
    the actions (n, W, A) and the design graph."""
    episodes, steps = demo.actions.shape[:2]
    e = rng.integers(episodes, size=cfg.il_batch)                          # an episode per window
    t0 = rng.integers(steps - cfg.il_window + 1, size=cfg.il_batch)        # its first step
    t = t0[:, None] + np.arange(cfg.il_window)                             # (batch, window)
    obs = {k: torch.as_tensor(v[e[:, None], t], dtype=torch.float32) for k, v in demo.obs.items()}
    actions = torch.as_tensor(demo.actions[e[:, None], t], dtype=torch.float32)
    return obs, actions, sim2d.design_graph(design)


def il_loss(policy: ModularPolicy, demo_data: dict, cfg: Config, rng: np.random.Generator):
    """eqn. (IL_loss): L_IL = - sum_d sum_(o,a) log pi(a | o, d), and the mean entropy of pi on o.

    Per demo design, a batch of windows (`demo_windows`) is run through the recurrent policy
    from a zero hidden state; the loss is the mean over pairs (the sum divided by the batch
    size, a constant that lambda absorbs), summed over designs.
    """
    loss, entropy = 0.0, 0.0
    for design, demo in demo_data.items():
        log_prob, ent = policy.sequence_log_prob(*demo_windows(design, demo, cfg, rng))
        loss = loss - log_prob.mean()
        entropy = entropy + ent.mean()
    return loss, entropy


def rlil_loss(loss_rl, loss_il, il_weight: float):
    """eqn. (RLIL_loss): L = L_RL + lambda L_IL.  Line 19 passes L_IL + w_H H as loss_il: the
    entropy penalty on demo observations (Sec. III-J) sits inside lambda's bracket, so it decays
    with lambda."""
    return loss_rl + il_weight * loss_il


def pretrain_bc(policy: ModularPolicy, demo_data: dict, cfg: Config, rng: np.random.Generator) -> float:
    """Algorithm 1 line 1: behavioural cloning, minimise L_IL over all demo designs.
    Returns the mean IL loss over the last 10 % of the steps."""
    opt = torch.optim.Adam(policy.parameters(), lr=cfg.policy_lr, foreach=True)
    losses = []
    for _ in range(cfg.bc_steps):
        loss, _ = il_loss(policy, demo_data, cfg, rng)
        opt.zero_grad()
        loss.backward()
        opt.step()
        losses.append(loss.item())
    return float(np.mean(losses[-max(1, cfg.bc_steps // 10):])) if losses else float("nan")


# ----------------------------------------------------------------------------
# Lines 7-26: policy optimisation with the buffer and the adaptive learning rate
# ----------------------------------------------------------------------------
@dataclass
class Buffer:
    """B for one design: initial states (n, S) with policy hidden states (nodes, n, H)."""

    states: torch.Tensor
    hidden: torch.Tensor

    def sample(self, n: int, rng: np.random.Generator):
        i = torch.from_numpy(rng.integers(len(self.states), size=n))
        return self.states[i], self.hidden[:, i]                                # (n, S), (nodes, n, H)


def sample_sim_states(traj: Trajectories, n: int, rng: np.random.Generator) -> torch.Tensor:
    """(n, S) states one design visited in the simulator (its T_train), the 'random initial states'."""
    s = traj.states.reshape(-1, traj.states.shape[-1])
    return s[torch.from_numpy(rng.integers(len(s), size=n))]


def init_buffer(policy, traj: Trajectories, cfg: Config, rng) -> Buffer:
    """Algorithm 1 line 7: random initial states of one design's T_train, zero hidden states."""
    graph = sim2d.design_graph(traj.design)
    return Buffer(sample_sim_states(traj, cfg.buffer_size, rng), policy.initial_hidden(cfg.buffer_size, graph))


@torch.no_grad()
def refresh_buffer(buffer: Buffer, policy, model, traj: Trajectories, cfg: Config, rng) -> None:
    """Algorithm 1 lines 23-24: run the policy T/2 steps in the model from new random
    states and overwrite the second half of B with the states and hidden states reached."""
    graph, half = sim2d.design_graph(traj.design), cfg.buffer_size // 2
    s0 = sample_sim_states(traj, cfg.buffer_size - half, rng)
    _, s, h = rollout(policy, model, s0, policy.initial_hidden(len(s0), graph), graph, cfg.horizon // 2)
    buffer.states[half:], buffer.hidden[:, half:] = s, h


@torch.no_grad()
def validation_reward(policy, model, val_states: dict, cfg: Config) -> float:
    """Sec. III-J: net reward of T deterministic model steps from a fixed, large set of states,
    summed over designs."""
    total = 0.0
    for design, s0 in val_states.items():
        graph = sim2d.design_graph(design)
        R, _, _ = rollout(policy, model, s0, policy.initial_hidden(len(s0), graph), graph, cfg.horizon,
                          deterministic=True)
        total += R.mean().item()
    return total


class AdaptiveLearningRate:
    """Sec. III-J's rule: if the validation reward falls below its value at the phase's start,
    revert the policy (and Adam) to the last check and multiply the learning rate by `lr_drop`.

    `check(value)` is called every `validate_every` steps; a check that passes
    becomes the new point to revert to.  `revert()` alone handles a step whose
    loss or gradient is not finite.
    """

    def __init__(self, policy, opt, start_value: float, lr_drop: float):
        self.policy, self.opt, self.lr_drop = policy, opt, lr_drop
        self.start = self.last = start_value            # the phase's reference, the last passed check
        self.lr, self.reverts = opt.param_groups[0]["lr"], 0
        self.snapshot()

    def snapshot(self) -> None:
        self.saved = (copy.deepcopy(self.policy.state_dict()), copy.deepcopy(self.opt.state_dict()))

    def revert(self) -> None:
        self.policy.load_state_dict(self.saved[0])
        self.opt.load_state_dict(self.saved[1])
        self.lr *= self.lr_drop
        for group in self.opt.param_groups:
            group["lr"] = self.lr
        self.reverts += 1

    def check(self, value: float) -> None:
        if value < self.start or not math.isfinite(value):
            self.revert()
        else:
            self.last = value
            self.snapshot()


def gradient_step(opt, loss, policy, grad_clip: float) -> bool:
    """Algorithm 1 line 21: one clipped gradient-descent step on dL/dtheta.
    Returns False, without stepping, when the loss or the gradient is not finite."""
    opt.zero_grad()
    loss.backward()
    grad_norm = torch.nn.utils.clip_grad_norm_(policy.parameters(), grad_clip)
    if not (torch.isfinite(loss) and torch.isfinite(grad_norm)):
        return False
    opt.step()
    return True


def optimize_policy(policy: ModularPolicy, model, data: dict[str, Trajectories],
                    demo_data: dict, il_weight: float, cfg: Config, rng: np.random.Generator) -> dict:
    """Algorithm 1 lines 7-26: K steps of L = L_RL + lambda (L_IL + entropy penalty), the model frozen.

    Returns the phase's metrics: RL and IL loss (means of the last 10 steps;
    il_loss None without IL), the last passed validation reward, reverts and
    the final learning rate.
    """
    model.requires_grad_(False)                                                   # frozen in this phase
    buffers = {d: init_buffer(policy, traj, cfg, rng) for d, traj in data.items()}                # line 7
    val_states = {d: sample_sim_states(traj, cfg.validation_multiple * cfg.batch, rng) for d, traj in data.items()}
    opt = torch.optim.Adam(policy.parameters(), lr=cfg.policy_lr, foreach=True)
    lr_rule = AdaptiveLearningRate(policy, opt, validation_reward(policy, model, val_states, cfg), cfg.lr_drop)
    rl_values, il_values = [], []
    for k in range(1, cfg.policy_steps + 1):                                                       # line 8
        loss_rl = rl_loss(policy, model, buffers, cfg, rng)                                        # lines 9-16
        loss = loss_rl
        if il_weight > 0 and demo_data:                                                            # line 17
            loss_il, entropy = il_loss(policy, demo_data, cfg, rng)                                # line 18
            loss = rlil_loss(loss_rl, loss_il + cfg.entropy_weight * entropy, il_weight)          # line 19
            il_values.append(loss_il.item())
        if not gradient_step(opt, loss, policy, cfg.grad_clip):                                    # line 21
            lr_rule.revert()                                  # a non-finite loss or gradient: never step on it
            continue
        rl_values.append(loss_rl.item())
        if k % cfg.update_rate == 0:                                                               # line 22
            for design, buffer in buffers.items():
                refresh_buffer(buffer, policy, model, data[design], cfg, rng)                      # lines 23-24
        if k % cfg.validate_every == 0:                                                            # Sec. III-J
            lr_rule.check(validation_reward(policy, model, val_states, cfg))
    model.requires_grad_(True)
    return {"rl_loss": float(np.mean(rl_values[-10:])) if rl_values else float("nan"),
            "il_loss": float(np.mean(il_values[-10:])) if il_values else None,
            "validation_reward": lr_rule.last, "reverts": lr_rule.reverts, "lr": lr_rule.lr}


def decay_il_weight(il_weight: float, cfg: Config) -> float:
    """Algorithm 1 line 30: lambda decays geometrically."""
    return il_weight * cfg.il_decay


# ----------------------------------------------------------------------------
# Evaluation (not part of Algorithm 1): Sec. IV's metric and the model's bias
# ----------------------------------------------------------------------------
def evaluate_policy(policy: ModularPolicy, design: str, cfg: Config, seed: int) -> sim2d.Episodes:
    """Sec. IV's metric: distance (m) in `eval_steps` control steps from perturbed starts, mean action."""
    return sim2d.simulate(design, PolicyActor(policy, design, cfg.eval_episodes), n=cfg.eval_episodes,
                          steps=cfg.eval_steps, seed=seed)


@torch.no_grad()
def model_bias(policy: ModularPolicy, model, design: str, run: sim2d.Episodes, cfg: Config) -> dict:
    """How far the model flatters the policy, from the evaluation starts, over the first T steps:

    model_progress_m: progress (m) predicted by rolling the policy out in the model
      (deterministic);
    sim_progress_m: progress measured in the simulator over the same steps;
    model_path_error_m: |x~_T - x_T| when the model replays the simulator's own
      actions open-loop: the model's error along the policy's simulated path.
    Means over starts.  model_progress well above sim_progress is the policy
    exploiting model errors (Sec. III-H); well below, the model undervalues what
    the policy does, and the RL term pulls away from it.
    """
    graph, T = sim2d.design_graph(design), cfg.horizon
    states = torch.as_tensor(run.states, dtype=torch.float32)                     # (n, steps + 1, S)
    actions = torch.as_tensor(run.actions, dtype=torch.float32)                   # (n, steps, A)
    s0 = states[:, 0]
    _, s_T, _ = rollout(policy, model, s0, policy.initial_hidden(len(s0), graph), graph, T, deterministic=True)
    s, f = s0, model.on_design(graph)
    for t in range(T):                                          # the simulator's actions, open loop
        s = f(s, actions[:, t])
    return {"model_progress_m": float((s_T[:, 0] - s0[:, 0]).mean()),
            "sim_progress_m": float((states[:, T, 0] - s0[:, 0]).mean()),
            "model_path_error_m": float((s[:, 0] - states[:, T, 0]).abs().mean())}


def sim_steps(cfg: Config, i: int) -> int:
    """Simulator steps Algorithm 1 has taken by the end of iteration i (for comparison with PPO):
    the demonstrations (counted once, at iteration 0, even when loaded from the cache), the
    random roll-outs of line 2, the clean and noisy policy roll-outs of lines 28-29 (and of
    the clone, with `clone_data`).  Evaluation in the simulator (every row's distance, `model_bias`) is not counted."""
    demos = len(cfg.demos) * cfg.demo_episodes * cfg.demo_steps
    random = len(cfg.train) * cfg.random_episodes * cfg.episode_steps
    policy = len(cfg.train) * 2 * cfg.policy_episodes * cfg.episode_steps          # one collection
    clone = policy if uses_clone_data(cfg) else 0                                    # not in the paper
    return demos + random + clone + i * cfg.phase_tries * policy                    # every try's collection


def eval_seed(cfg: Config) -> int:
    """Evaluation starts are the same at every iteration (and differ from training data)."""
    return 1_000_003 + cfg.seed


def evaluate_iteration(policy, model, designs: list[str], cfg: Config, i: int) -> dict:
    """The metrics row of iteration i: distance in the simulator over every training design
    (mean, min, max), how many starts flipped (|pitch| > sim2d.FLIP_PITCH at some step: the
    distance still counts what a robot drives on its back), and from iteration 1 on
    `model_bias`'s figures, averaged over designs."""
    results = {d: evaluate_policy(policy, d, cfg, eval_seed(cfg)) for d in designs}
    dist = np.concatenate([r.distance_m for r in results.values()])
    row = {"iteration": i, "distance_m": float(dist.mean()), "distance_min_m": float(dist.min()),
           "distance_max_m": float(dist.max()), "flipped": int(sum(r.flipped.sum() for r in results.values()))}
    if i > 0:
        bias = [model_bias(policy, model, d, r, cfg) for d, r in results.items()]
        row.update({k: float(np.mean([b[k] for b in bias])) for k in bias[0]})
    return row


# ----------------------------------------------------------------------------
# Everything a run carries between iterations, and the one seeding point
# ----------------------------------------------------------------------------
@dataclass
class Run:
    """What Algorithm 1 carries from one iteration to the next: enough to resume a run."""

    cfg: Config
    policy: ModularPolicy
    model: ModularModel              # f~_phi
    data: dict                       # T_train: design code -> Trajectories
    il_weight: float                 # lambda for the next iteration
    rng: np.random.Generator
    iteration: int = 0               # last finished iteration (0: lines 1-2 and their evaluation)
    metrics: list = field(default_factory=list)   # one row per finished iteration, 0 included
    kept_return: float | None = None  # `keep_better`: the kept policy's return on its noiseless roll-outs

    def rng_state(self) -> dict:
        return {"numpy": self.rng.bit_generator.state, "torch": torch.get_rng_state()}

    @staticmethod
    def restore_rngs(state: dict) -> np.random.Generator:
        """Both generators of `rng_state`: sets torch's global one, returns the numpy one."""
        rng = np.random.default_rng()
        rng.bit_generator.state = state["numpy"]
        torch.set_rng_state(state["torch"])
        return rng


def seed_everything(seed: int) -> np.random.Generator:
    """The one place randomness is seeded: torch's global generator and the numpy generator."""
    torch.manual_seed(seed)
    return np.random.default_rng(seed)


def load_demos(cfg: Config, cache_dir=demo_lib.DEFAULT_CACHE_DIR) -> dict:
    """T_demo: one dataset per demo design (cached on disk by demos.py)."""
    out = {}
    for design in cfg.demos:
        data = demo_lib.load_or_make_demos(design, episodes=cfg.demo_episodes, steps=cfg.demo_steps,
                                           seed=cfg.seed, cache_dir=cache_dir,
                                           cfg=demo_lib.DemoConfig(execution_noise=cfg.demo_noise))
        out[sim2d.parse_design(design)] = data
    return out


class ProgressLog:
    """Prints one line per phase, prefixed with the seconds since the log was made."""

    def __init__(self):
        self.t0 = time.perf_counter()

    def __call__(self, message: str) -> None:
        print(f"[{time.perf_counter() - self.t0:6.1f} s] {message}", flush=True)


def flips(row: dict, starts: int) -> str:
    """", 3 of 8 starts flipped" for the progress line when an evaluated robot flipped, else ""."""
    return f", {row['flipped']} of {starts} starts flipped" if row.get("flipped") else ""


def record(run: Run, row: dict, log) -> None:
    """Append a metrics row; a non-finite number is logged and stored as None (JSON null)."""
    bad = [k for k, v in row.items() if isinstance(v, float) and not math.isfinite(v)]
    if bad:
        log(f"WARNING iteration {row['iteration']}: non-finite {', '.join(bad)} (stored as null)")
    run.metrics.append({k: None if k in bad else v for k, v in row.items()})


# ----------------------------------------------------------------------------
# Algorithm 1
# ----------------------------------------------------------------------------
def algorithm1(cfg: Config, demo_data: dict, run: Run | None = None, log=print, on_iteration=None) -> Run:
    """Algorithm 1 (MBRL with IL for modular robots), from line 1, or continuing `run`.

    demo_data: T_demo from `load_demos` (empty for plain RL).  After the
    iteration-0 evaluation and after every iteration, `on_iteration(run)` is
    called (train.py saves checkpoints and plots there).  Returns the Run.
    """
    torch.set_num_threads(cfg.threads)
    designs = [sim2d.parse_design(d) for d in cfg.train]                                          # d_train
    if run is None:
        t0 = time.perf_counter()
        rng = seed_everything(cfg.seed)
        policy, model = ModularPolicy(cfg.gnn), ModularModel(cfg.gnn)
        if demo_data and cfg.bc_steps:                                                             # line 1
            log(f"line 1   behavioural cloning on {', '.join(demo_data)}: IL loss "
                f"{pretrain_bc(policy, demo_data, cfg, rng):.3f}")
        data = {d: collect_random_rollouts(d, cfg, rng) for d in designs}                         # line 2
        log(f"line 2   random {'sine-wave' if cfg.random_waves else 'spline'} data: "
            f"{sum(len(d.actions) for d in data.values())} episodes")
        run = Run(cfg, policy, model, data, il_weight=cfg.il_weight if demo_data else 0.0, rng=rng)
        if uses_clone_data(cfg):                                                            # not in the paper
            run.kept_return = add_clone_rollouts(policy, data, cfg, rng)
            log(f"clone    roll-outs of the cloned policy added to T_train: return {run.kept_return:.2f}")
        row = evaluate_iteration(policy, model, designs, cfg, 0)
        record(run, {**row, "il_weight": run.il_weight, "sim_steps": sim_steps(cfg, 0),
                     "seconds": time.perf_counter() - t0}, log)
        log(f"iteration 0: {row['distance_m']:.2f} m in {cfg.eval_steps} steps"
            f"{flips(row, cfg.eval_episodes * len(designs))}")
        if on_iteration:
            on_iteration(run)

    policy, model, data, rng = run.policy, run.model, run.data, run.rng
    for i in range(run.iteration + 1, cfg.iters + 1):                                              # line 3
        t0, il_weight = time.perf_counter(), run.il_weight
        previous = copy.deepcopy(policy.state_dict()) if cfg.keep_better else None                # not in the paper
        # -- lines 4-5: model learning phase --
        fit_loss = train_model(model, data, cfg, rng, first=(i == 1))                              # line 5
        # -- lines 6-26: policy optimisation phase --
        if cfg.phase_tries > 1:                                                                    # not in the paper
            phase, new_data = best_of_phases(policy, model, data, demo_data, il_weight, cfg, rng)  # lines 7-29, tried
        else:
            phase = optimize_policy(policy, model, data, demo_data, il_weight, cfg, rng)           # lines 7-26
            # -- lines 27-29: data collection --
            new_data = add_policy_rollouts(policy, data, cfg, rng)                                 # lines 28-29
        if cfg.keep_better:                                                                        # not in the paper
            phase.update(improvement_check(policy, previous, new_data, run, cfg))
        run.il_weight = decay_il_weight(il_weight, cfg)                                            # line 30
        run.iteration = i
        # -- evaluation in the simulator (Sec. IV), not part of Algorithm 1 --
        row = evaluate_iteration(policy, model, designs, cfg, i)
        record(run, {**row, "il_weight": il_weight, "model_loss": fit_loss, **phase,
                     "sim_steps": sim_steps(cfg, i), "seconds": time.perf_counter() - t0}, log)
        log(f"iter {i}  model loss {fit_loss:.4f}; policy: RL loss {phase['rl_loss']:.3f}, "
            f"{phase['reverts']} reverts, lr {phase['lr']:.1e}; {row['distance_m']:.2f} m "
            f"(min {row['distance_min_m']:.2f}, max {row['distance_max_m']:.2f}) in {cfg.eval_steps} steps"
            f"{flips(row, cfg.eval_episodes * len(designs))}; "
            f"first {cfg.horizon} steps: model {row['model_progress_m']:.2f} m, "
            f"simulator {row['sim_progress_m']:.2f} m, model replaying the simulator's actions "
            f"off by {row['model_path_error_m']:.2f} m"
            + ("; kept the previous policy" if phase.get("kept_new") is False else ""))
        if on_iteration:
            on_iteration(run)
    return run


# ----------------------------------------------------------------------------
# Not in the paper: switches against model error (docs/results.md): clone_data and
# keep_better, both on by default; phase_tries, off (1) by default
# ----------------------------------------------------------------------------
def uses_clone_data(cfg: Config) -> bool:
    """`clone_data` acts only where line 1 made a clone to run."""
    return cfg.clone_data and bool(cfg.demos) and cfg.bc_steps > 0


def add_clone_rollouts(policy: ModularPolicy, data: dict[str, Trajectories], cfg: Config,
                       rng: np.random.Generator) -> float:
    """The first model sees the clone: after lines 1-2, run the pre-trained policy on d_train as
    lines 28-29 do (noiseless, then with noise) and add the roll-outs to T_train, so the model of
    iteration 1 is fitted where the cloned gait goes, not only on random flails (the data
    aggregation of DAgger, Ross et al. 2011, and of MBRL with on-policy data, Nagabandi et al.
    2018).  Costs one data collection.  Returns the clone's return for `improvement_check`."""
    return policy_return(add_policy_rollouts(policy, data, cfg, rng), cfg)


def policy_return(new_data: dict[str, Trajectories], cfg: Config) -> float:
    """The policy's real return: the summed reward of its noiseless episodes (the first
    `policy_episodes` of a `collect_policy_rollouts` result), mean over episodes, summed over designs."""
    total = 0.0
    for design, traj in new_data.items():
        s, a = traj.states[:cfg.policy_episodes], traj.actions[:cfg.policy_episodes]     # (n, T + 1, S), (n, T, A)
        total += float(sim2d.reward(s[:, :-1], a, s[:, 1:], sim2d.design_graph(design)).sum(1).mean())
    return total


def improvement_check(policy: ModularPolicy, previous: dict, new_data: dict[str, Trajectories],
                      run: Run, cfg: Config) -> dict:
    """Keep the new policy only if its real return (`policy_return`, on line 28's noiseless
    roll-outs, which the algorithm collects anyway) is at least the kept policy's minus
    `improvement_margin`; otherwise load the previous policy back.  The new data stay in T_train,
    so the next model learns where it was wrong.  The acceptance test of TRPO's line search
    (Schulman et al. 2015) and ME-TRPO's policy validation (Kurutach et al. 2018), measured in
    the simulator.  Returns the row's figures: the new policy's return and whether it was kept."""
    value = policy_return(new_data, cfg)
    keep = run.kept_return is None or value >= run.kept_return - cfg.improvement_margin
    if keep:
        run.kept_return = value
    else:
        policy.load_state_dict(previous)
    return {"policy_return": value, "kept_new": keep}


def best_of_phases(policy: ModularPolicy, model, data: dict[str, Trajectories], demo_data: dict,
                   il_weight: float, cfg: Config, rng: np.random.Generator) -> tuple[dict, dict]:
    """Lines 7-29 with `phase_tries` tries: each try runs the policy phase from the same policy with
    its own draws, on the same T_train, and collects line 28's roll-outs in the simulator; the try
    whose noiseless roll-outs return most (`policy_return`) is kept, and only its roll-outs join
    T_train (line 29).  Before take-off a phase is a lottery (docs/history/2026-12-plain-rl-diagnosis.md,
    parts 29-31); tries buy more tickets per iteration, paid in phases and simulator steps.  Returns
    the kept try's phase metrics, with every try's return, and its new data."""
    start, tries = copy.deepcopy(policy.state_dict()), []
    for _ in range(cfg.phase_tries):
        policy.load_state_dict(start)
        phase = optimize_policy(policy, model, data, demo_data, il_weight, cfg, rng)          # lines 7-26
        new_data = {d: collect_policy_rollouts(policy, d, cfg, rng) for d in data}             # line 28
        tries.append((policy_return(new_data, cfg), copy.deepcopy(policy.state_dict()), phase, new_data))
    _, state, phase, new_data = max(tries, key=lambda t: t[0])                                 # the first of equals
    policy.load_state_dict(state)
    return {**phase, "try_returns": [t[0] for t in tries]}, join_rollouts(data, new_data)     # line 29
