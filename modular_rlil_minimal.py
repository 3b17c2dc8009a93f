"""Algorithm 1 of the paper (MBRL with IL for modular robots) as a chain of named functions.

Paper: Whitman & Choset, "Learning Modular Robot Locomotion from Demonstrations",
Sec. III and Algorithm 1.  Each function names the Algorithm 1 lines or the
equation it implements:

    pretrain_bc              line 1      behavioural cloning on T_demo, eqn. (IL_loss)
    collect_random_rollouts  line 2      random spline actions (Sec. III-B)
    train_model              line 5      modular model f~_phi on T_train (Sec. III-C)
    optimize_policy          lines 7-26  K steps of L = L_RL + lambda L_IL, buffer of
                                         initial states + hidden states, adaptive
                                         learning rate with validation revert
    collect_policy_rollouts  lines 28-29 policy data without and with correlated noise
    decay_il_weight          line 30
    algorithm1               the loop, with an evaluation in the simulator per iteration

CPU, a few minutes (the command line is train.py):
    python train.py --train leg_none_wheel --demos hexapod car
"""
from __future__ import annotations

import copy
import math
import time
from dataclasses import dataclass, field

import numpy as np
import torch

import demos as demo_lib
import sim2d
from gnn import GNNConfig, ModularModel, ModularPolicy


@dataclass
class Config:
    """Every knob of Algorithm 1.  Defaults: the 5-minute CPU budget of the README."""

    train: tuple[str, ...] = ("leg_none_wheel",)   # d_train; several designs sum their RL losses
    demos: tuple[str, ...] = ()      # D_demo; empty = plain RL (lambda = 0, no pre-training)
    iters: int = 5                   # outer iterations of Algorithm 1 (paper: 5)
    seed: int = 0                    # the one seed everything derives from
    # Line 2 / Sec. III-B: random spline actions
    random_episodes: int = 32        # episodes per training design (paper: not stated)
    episode_steps: int = 100         # control steps per collected episode (paper: 100)
    random_action_std: float = 1.0   # std of the spline knots (normalised action units)
    # Lines 28-29: data from the policy
    policy_episodes: int = 16        # per design and iteration, once without and once with noise
    policy_noise_std: float = 0.3    # knot std of the correlated noise (< random_action_std)
    # Demonstrations (Sec. III-D): the paper's 50 x 100
    demo_episodes: int = 50
    demo_steps: int = 100
    # Line 1: behavioural cloning
    bc_steps: int = 1000             # Adam steps of pre-training (0 to skip); 300 cloned the
                                     # hexapod gait to 4-11 m in 200 steps, 1000 to 8-11 m
    # Line 5: model learning
    model_steps: int = 1500          # Adam steps at the first iteration (then `finetune_steps`)
    finetune_steps: int = 500        # Adam steps in later iterations (fine-tuning)
    model_batch: int = 512           # transitions per design per step
    model_lr: float = 1e-3
    # Lines 7-26: policy optimisation
    policy_steps: int = 120          # K, gradient steps per iteration
    horizon: int = 20                # T, model roll-out length (truncated BPTT window)
    batch: int = 64                  # N_batch, initial states per step and design
    buffer_size: int = 256           # |B|, initial states with hidden states per design
    update_rate: int = 10            # every this many steps, refresh half of B (lines 23-25)
    policy_lr: float = 1e-3          # learning rate at the start of every policy phase (adapted, Sec. III-J)
    lr_drop: float = 0.5             # factor applied on every validation revert
    grad_clip: float = 10.0          # max gradient norm of a policy step (BPTT through T model steps)
    validate_every: int = 20         # steps between validation checks
    validation_multiple: int = 10    # validation set = this many batches of initial states
    il_weight: float = 10.0          # lambda at iteration 1 (eqn. RLIL_loss).  With 1.0 the RL term,
                                     # through a model that undervalues walking, wore the cloned
                                     # hexapod gait down faster (README, Results); 1-10
    il_decay: float = 0.5            # lambda <- il_decay * lambda after every iteration (line 30)
    il_batch: int = 32               # demo windows per design per step
    il_window: int = 8               # control steps per demo window (recurrent policy)
    entropy_weight: float = 0.01     # weight of the entropy penalty on demo observations
    # Evaluation (Sec. IV): distance in 200 control steps
    eval_episodes: int = 8
    eval_steps: int = 200
    gnn: GNNConfig = field(default_factory=GNNConfig)


# ----------------------------------------------------------------------------
# Data: transitions T_train per design
# ----------------------------------------------------------------------------
@dataclass
class Trajectories:
    """Episodes of one design: states (E, T+1, S) and applied actions (E, T, A), float32."""

    design: str
    states: torch.Tensor
    actions: torch.Tensor

    def transitions(self):
        """(s, a, s') flattened over episodes and time: (E*T, S), (E*T, A), (E*T, S)."""
        s, a = self.states, self.actions
        return s[:, :-1].reshape(-1, s.shape[-1]), a.reshape(-1, a.shape[-1]), s[:, 1:].reshape(-1, s.shape[-1])

    def __add__(self, other: "Trajectories") -> "Trajectories":      # T_train U T_new (line 29)
        return Trajectories(self.design, torch.cat([self.states, other.states]),
                            torch.cat([self.actions, other.actions]))


def run_episodes(design: str, act, n: int, steps: int, rng: np.random.Generator) -> Trajectories:
    """Run act(obs, state, t) -> (n, A) on n perturbed starts in the simulator."""
    world = sim2d.World(design, n=n, max_steps=steps)
    obs, info = world.reset(seed=int(rng.integers(2 ** 31)))
    states, actions = [info["state"]], []
    for t in range(steps):
        a = np.clip(act(obs, info["state"], t), -1.0, 1.0)
        obs, _, _, _, info = world.step(a)
        states.append(info["state"])
        actions.append(a)
    return Trajectories(world.graph.code, torch.tensor(np.stack(states, 1), dtype=torch.float32),
                        torch.tensor(np.stack(actions, 1), dtype=torch.float32))


def collect_random_rollouts(design: str, cfg: Config, rng: np.random.Generator) -> Trajectories:
    """Algorithm 1 line 2 (Sec. III-B): 10 N(0, std^2) knots per DoF joined by a spline over 100 steps."""
    graph = sim2d.design_graph(design)
    actions = sim2d.random_spline_actions(rng, cfg.random_episodes, graph.action_dim, cfg.episode_steps,
                                          std=cfg.random_action_std)
    return run_episodes(design, lambda obs, s, t: actions[:, t], cfg.random_episodes, cfg.episode_steps, rng)


class PolicyActor:
    """Runs the recurrent policy in the simulator: numpy obs in, numpy actions out."""

    def __init__(self, policy: ModularPolicy, design: str, n: int, noise: np.ndarray | None = None):
        self.policy, self.graph, self.noise = policy, sim2d.design_graph(design), noise
        self.hidden = policy.initial_hidden(n, self.graph)

    @torch.no_grad()
    def __call__(self, obs: dict, state=None, t: int = 0) -> np.ndarray:
        obs = {k: torch.as_tensor(v, dtype=torch.float32) for k, v in obs.items()}
        mean, self.hidden = self.policy.act(obs, self.graph, self.hidden, deterministic=True)
        a = mean.numpy().astype(float)
        return a if self.noise is None else a + self.noise[:, t]


def collect_policy_rollouts(policy: ModularPolicy, design: str, cfg: Config,
                            rng: np.random.Generator) -> Trajectories:
    """Algorithm 1 lines 28-29: the policy without noise, then with time-correlated noise
    (the spline noise of Sec. III-B with a smaller std)."""
    graph, n, steps = sim2d.design_graph(design), cfg.policy_episodes, cfg.episode_steps
    clean = run_episodes(design, PolicyActor(policy, design, n), n, steps, rng)
    noise = sim2d.random_spline_actions(rng, n, graph.action_dim, steps, std=cfg.policy_noise_std)
    noisy = run_episodes(design, PolicyActor(policy, design, n, noise), n, steps, rng)
    return clean + noisy


# ----------------------------------------------------------------------------
# Line 5: the model
# ----------------------------------------------------------------------------
def train_model(model: ModularModel, data: dict[str, Trajectories], cfg: Config, steps: int,
                rng: np.random.Generator) -> float:
    """Algorithm 1 line 5 (Sec. III-C): supervised regression of the state change on T_train.

    Each Adam step sums the loss of a mini-batch from every training design.
    Returns the mean loss (normalised MSE) over the last 10 % of the steps.
    """
    flat = {d: traj.transitions() for d, traj in data.items()}
    opt = torch.optim.Adam(model.parameters(), lr=cfg.model_lr)
    losses = []
    for _ in range(steps):
        loss = 0.0
        for design, (s, a, s_next) in flat.items():
            i = torch.from_numpy(rng.integers(len(s), size=cfg.model_batch))
            loss = loss + model.loss(s[i], a[i], s_next[i], sim2d.design_graph(design))
        opt.zero_grad()
        loss.backward()
        opt.step()
        losses.append(loss.item())
    return float(np.mean(losses[-max(1, steps // 10):]))


# ----------------------------------------------------------------------------
# The losses: eqn. (RL_loss), eqn. (IL_loss) and the entropy penalty
# ----------------------------------------------------------------------------
def rollout(policy: ModularPolicy, model: ModularModel, s0, h0, graph, horizon: int,
            deterministic: bool = False):
    """Algorithm 1 lines 10-15: a ~ pi(a | O(s~)), s~' = f~(s~, a), R += r(s~, a, s~').

    s0: (B, S) initial states, h0: (B, nodes, H) policy hidden states.  Returns
    the summed reward R (B,), the final state and hidden state.  Actions are
    reparameterised samples, so dR/dtheta flows through every model step.
    The model clips actions to [-1, 1] like the simulator; the reward's effort
    term sees them unclipped, which keeps a gradient that pulls saturated
    commands back into range.
    """
    s, h, total = s0, h0, torch.zeros(len(s0))
    for _ in range(horizon):
        noise = None if deterministic else sim2d.obs_noise_like(s, graph)
        a, h = policy.act(sim2d.observe(s, graph, noise), graph, h, deterministic=deterministic)
        s_next = model(s, a, graph)                                     # (B, S)
        total = total + sim2d.reward(s, a, s_next, graph)               # (B,)
        s = s_next
    return total, s, h


def il_loss(policy: ModularPolicy, demo_data: dict, cfg: Config, rng: np.random.Generator):
    """eqn. (IL_loss): L_IL = - sum_d sum_(o,a) log pi(a | o, d), and the mean entropy of pi on o.

    Per demo design, a batch of windows of `il_window` consecutive (o, a) pairs
    is run through the recurrent policy from a zero hidden state; the loss is
    the mean over pairs (the sum divided by the batch size, a constant that
    lambda absorbs), summed over designs.
    """
    loss, entropy = 0.0, 0.0
    for design, demo in demo_data.items():
        episodes, steps = demo.actions.shape[:2]
        e = rng.integers(episodes, size=cfg.il_batch)
        t0 = rng.integers(steps - cfg.il_window + 1, size=cfg.il_batch)
        t = t0[:, None] + np.arange(cfg.il_window)                          # (batch, window)
        obs = {k: torch.as_tensor(v[e[:, None], t], dtype=torch.float32) for k, v in demo.obs.items()}
        actions = torch.as_tensor(demo.actions[e[:, None], t], dtype=torch.float32)
        log_prob, ent = policy.sequence_log_prob(obs, actions, sim2d.design_graph(design))
        loss = loss - log_prob.mean()
        entropy = entropy + ent.mean()
    return loss, entropy


def pretrain_bc(policy: ModularPolicy, demo_data: dict, cfg: Config, rng: np.random.Generator) -> float:
    """Algorithm 1 line 1: behavioural cloning, minimise L_IL over all demo designs."""
    opt = torch.optim.Adam(policy.parameters(), lr=cfg.policy_lr)
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
    """B: initial states (n, S) with policy hidden states (n, nodes, H) for one design."""

    states: torch.Tensor
    hidden: torch.Tensor

    def sample(self, n: int, rng: np.random.Generator):
        i = torch.from_numpy(rng.integers(len(self.states), size=n))
        return self.states[i], self.hidden[i]


def sample_sim_states(data: Trajectories, n: int, rng: np.random.Generator) -> torch.Tensor:
    """(n, S) states visited in the simulator (T_train), the 'random initial states'."""
    s = data.states.reshape(-1, data.states.shape[-1])
    return s[torch.from_numpy(rng.integers(len(s), size=n))]


def init_buffer(policy, data: Trajectories, cfg: Config, rng) -> Buffer:
    """Algorithm 1 line 7: random initial states, zero hidden states."""
    graph = sim2d.design_graph(data.design)
    return Buffer(sample_sim_states(data, cfg.buffer_size, rng), policy.initial_hidden(cfg.buffer_size, graph))


@torch.no_grad()
def refresh_buffer(buffer: Buffer, policy, model, data: Trajectories, cfg: Config, rng) -> None:
    """Algorithm 1 lines 23-25: run the policy T/2 steps in the model from new random
    states and overwrite the second half of B with the states and hidden states reached."""
    graph, half = sim2d.design_graph(data.design), cfg.buffer_size // 2
    s0 = sample_sim_states(data, cfg.buffer_size - half, rng)
    _, s, h = rollout(policy, model, s0, policy.initial_hidden(len(s0), graph), graph, cfg.horizon // 2)
    buffer.states[half:], buffer.hidden[half:] = s, h


@torch.no_grad()
def validation_reward(policy, model, val_states: dict, cfg: Config) -> float:
    """Sec. III-J: net reward of T deterministic model steps from a fixed, large set of states."""
    total = 0.0
    for design, s0 in val_states.items():
        graph = sim2d.design_graph(design)
        R, _, _ = rollout(policy, model, s0, policy.initial_hidden(len(s0), graph), graph, cfg.horizon,
                          deterministic=True)
        total += R.mean().item()
    return total


def optimize_policy(policy: ModularPolicy, model: ModularModel, data: dict[str, Trajectories],
                    demo_data: dict, il_weight: float, cfg: Config, rng: np.random.Generator) -> dict:
    """Algorithm 1 lines 7-26: K steps of L = L_RL + lambda (L_IL + entropy penalty).

    The learning rate adapts (Sec. III-J "Implementation details"): the phase
    starts at `policy_lr` and computes the validation reward; every
    `validate_every` steps it is computed again, and if it is lower than at the
    phase's start the parameters revert to the last check and the rate drops by
    `lr_drop`.  A non-finite loss or gradient is treated the same way, so the
    policy never holds a NaN.  Returns the metrics and the final rate.
    """
    for p in model.parameters():                      # the model is frozen in this phase
        p.requires_grad_(False)
    buffers = {d: init_buffer(policy, traj, cfg, rng) for d, traj in data.items()}
    val_states = {d: sample_sim_states(traj, cfg.validation_multiple * cfg.batch, rng) for d, traj in data.items()}
    lr = cfg.policy_lr
    opt = torch.optim.Adam(policy.parameters(), lr=lr)
    initial = last = validation_reward(policy, model, val_states, cfg)      # the phase's reference
    saved = (copy.deepcopy(policy.state_dict()), copy.deepcopy(opt.state_dict()))
    reverts, rl_values, il_values = 0, [], []

    def revert():
        nonlocal lr, reverts
        policy.load_state_dict(saved[0])
        opt.load_state_dict(saved[1])
        lr *= cfg.lr_drop
        for group in opt.param_groups:
            group["lr"] = lr
        reverts += 1

    for k in range(1, cfg.policy_steps + 1):
        loss_rl = 0.0
        for design, buffer in buffers.items():                         # lines 9-16, summed over d_train
            s0, h0 = buffer.sample(cfg.batch, rng)
            R, _, _ = rollout(policy, model, s0, h0, sim2d.design_graph(design), cfg.horizon)
            loss_rl = loss_rl - R.mean()                                # eqn. (RL_loss)
        loss = loss_rl
        if il_weight > 0 and demo_data:                                # lines 17-20
            loss_il, entropy = il_loss(policy, demo_data, cfg, rng)
            loss = loss + il_weight * (loss_il + cfg.entropy_weight * entropy)   # eqn. (RLIL_loss)
            il_values.append(loss_il.item())
        opt.zero_grad()
        loss.backward()                                                # line 21
        grad_norm = torch.nn.utils.clip_grad_norm_(policy.parameters(), cfg.grad_clip)
        if not (torch.isfinite(loss) and torch.isfinite(grad_norm)):
            revert()
            continue
        opt.step()
        rl_values.append(loss_rl.item())
        if k % cfg.update_rate == 0:                                   # lines 22-25
            for design, buffer in buffers.items():
                refresh_buffer(buffer, policy, model, data[design], cfg, rng)
        if k % cfg.validate_every == 0:                                # adaptive learning rate
            value = validation_reward(policy, model, val_states, cfg)
            if value < initial or not math.isfinite(value):
                revert()
            else:
                last = value
                saved = (copy.deepcopy(policy.state_dict()), copy.deepcopy(opt.state_dict()))
    for p in model.parameters():
        p.requires_grad_(True)
    return {"rl_loss": float(np.mean(rl_values[-10:])) if rl_values else float("nan"),
            "il_loss": float(np.mean(il_values[-10:])) if il_values else float("nan"),
            "validation_reward": last, "reverts": reverts, "lr": lr}


def decay_il_weight(il_weight: float, cfg: Config) -> float:
    """Algorithm 1 line 30: lambda decays geometrically."""
    return il_weight * cfg.il_decay


@torch.no_grad()
def model_bias(policy: ModularPolicy, model: ModularModel, design: str, sim_states: np.ndarray,
               cfg: Config) -> tuple[float, float]:
    """How far the model flatters the policy: progress (m) in the first T steps from the
    evaluation starts, predicted by rolling the policy out in the model, and measured in the
    simulator (sim_states (steps+1, n, S) from `evaluate_policy`).  Means over starts.

    The two differ by the model's bias along the policy's own path (Sec. III-H): well
    above the simulator's figure, the policy is exploiting model errors; well below,
    the model undervalues what the policy does, and the RL term pulls away from it.
    """
    graph, T = sim2d.design_graph(design), cfg.horizon
    s0 = torch.as_tensor(sim_states[0], dtype=torch.float32)                       # (n, S)
    _, s_T, _ = rollout(policy, model, s0, policy.initial_hidden(len(s0), graph), graph, T, deterministic=True)
    return float((s_T[:, 0] - s0[:, 0]).mean()), float((sim_states[T, :, 0] - sim_states[0, :, 0]).mean())


def evaluate_policy(policy: ModularPolicy, design: str, cfg: Config, seed: int) -> dict:
    """Sec. IV's metric: distance (m) in `eval_steps` control steps from perturbed starts, mean action.

    Returns sim2d.evaluate's dict: distance_m (n,), flipped (n,), states (steps+1, n, S).
    """
    return sim2d.evaluate(design, PolicyActor(policy, design, cfg.eval_episodes),
                          n=cfg.eval_episodes, steps=cfg.eval_steps, seed=seed)


# ----------------------------------------------------------------------------
# The whole algorithm, resumable between iterations
# ----------------------------------------------------------------------------
@dataclass
class RunState:
    """Everything Algorithm 1 carries from one iteration to the next (what a resume needs)."""

    cfg: Config
    policy: ModularPolicy
    model: ModularModel
    data: dict                       # T_train: design code -> Trajectories
    il_weight: float
    iteration: int = 0               # last finished iteration (0: after line 2 and iteration-0 evaluation)
    metrics: list = field(default_factory=list)
    rng: np.random.Generator | None = None

    def rng_state(self) -> dict:
        return {"numpy": self.rng.bit_generator.state, "torch": torch.get_rng_state()}

    def set_rng_state(self, state: dict) -> None:
        self.rng = np.random.default_rng()
        self.rng.bit_generator.state = state["numpy"]
        torch.set_rng_state(state["torch"])


class ProgressLog:
    """Prints one line per phase, prefixed with the seconds since the log was made."""

    def __init__(self):
        self.t0 = time.perf_counter()

    def __call__(self, message: str) -> None:
        print(f"[{time.perf_counter() - self.t0:6.1f} s] {message}", flush=True)


def seed_everything(seed: int) -> np.random.Generator:
    """The one place randomness is seeded: torch's global generator and the numpy generator."""
    torch.manual_seed(seed)
    return np.random.default_rng(seed)


def load_demos(cfg: Config, cache_dir=demo_lib.DEFAULT_CACHE_DIR) -> dict:
    """T_demo: one dataset per demo design (cached on disk by demos.py)."""
    out = {}
    for design in cfg.demos:
        data = demo_lib.load_or_make_demos(design, episodes=cfg.demo_episodes, steps=cfg.demo_steps,
                                           seed=cfg.seed, cache_dir=cache_dir)
        out[sim2d.parse_design(design)] = data
    return out


def eval_seed(cfg: Config) -> int:
    """Evaluation starts are the same at every iteration (and differ from training data)."""
    return 1_000_003 + cfg.seed


def start(cfg: Config, demo_data: dict, log=print) -> RunState:
    """Lines 1-2, then the iteration-0 evaluation."""
    rng = seed_everything(cfg.seed)
    policy, model = ModularPolicy(cfg.gnn), ModularModel(cfg.gnn)
    t0 = time.perf_counter()
    if demo_data and cfg.bc_steps:
        bc = pretrain_bc(policy, demo_data, cfg, rng)
        log(f"line 1   behavioural cloning on {', '.join(demo_data)}: IL loss {bc:.3f}")
    data = {}
    for design in cfg.train:
        code = sim2d.parse_design(design)
        data[code] = collect_random_rollouts(code, cfg, rng)
    log(f"line 2   random spline data: {sum(len(d.actions) for d in data.values())} episodes")
    state = RunState(cfg, policy, model, data, il_weight=cfg.il_weight if demo_data else 0.0, rng=rng)
    state.metrics.append(iteration_metrics(state, 0, float("nan"), time.perf_counter() - t0))
    return state


def iteration_metrics(state: RunState, i: int, model_loss: float, seconds: float, extra: dict | None = None) -> dict:
    """Evaluate every training design in the simulator and make the metrics row of iteration i.

    From iteration 1 on (when there is a fitted model) the row also holds `model_bias`'s
    pair, averaged over training designs: model_progress_m and sim_progress_m.
    """
    results = {d: evaluate_policy(state.policy, d, state.cfg, eval_seed(state.cfg)) for d in state.data}
    dist = np.concatenate([r["distance_m"] for r in results.values()])
    row = {"iteration": i, "distance_m": float(dist.mean()), "distance_min_m": float(dist.min()),
           "distance_max_m": float(dist.max()), "il_weight": state.il_weight, "model_loss": model_loss,
           "seconds": seconds}
    if i > 0:
        bias = [model_bias(state.policy, state.model, d, r["states"], state.cfg) for d, r in results.items()]
        row["model_progress_m"], row["sim_progress_m"] = (float(np.mean(v)) for v in zip(*bias))
    row.update(extra or {})
    return {k: None if isinstance(v, float) and not math.isfinite(v) else v for k, v in row.items()}   # JSON null


def iterate(state: RunState, demo_data: dict, log=print) -> dict:
    """One pass of Algorithm 1's loop body (lines 4-30) and its evaluation."""
    cfg, rng, i = state.cfg, state.rng, state.iteration + 1
    t0 = time.perf_counter()
    if i == 1:
        batches = [(sim2d.design_graph(d), *traj.transitions()) for d, traj in state.data.items()]
        state.model.fit_normalization(batches)
    model_loss = train_model(state.model, state.data, cfg, cfg.model_steps if i == 1 else cfg.finetune_steps, rng)
    log(f"iter {i}  line 5   model fitted: loss {model_loss:.4f}")
    opt = optimize_policy(state.policy, state.model, state.data, demo_data, state.il_weight, cfg, rng)
    log(f"iter {i}  lines 7-26 policy: RL loss {opt['rl_loss']:.3f}, IL loss {opt['il_loss']:.3f}, "
        f"{opt['reverts']} reverts, lr {opt['lr']:.1e}")
    for design in state.data:
        state.data[design] = state.data[design] + collect_policy_rollouts(state.policy, design, cfg, rng)
    row_extra = {"rl_loss": opt["rl_loss"], "il_loss": opt["il_loss"], "reverts": opt["reverts"], "lr": opt["lr"]}
    row = iteration_metrics(state, i, model_loss, 0.0, row_extra)
    state.il_weight = decay_il_weight(state.il_weight, cfg)
    state.iteration = i
    row["seconds"] = time.perf_counter() - t0
    state.metrics.append(row)
    log(f"iter {i}  evaluation: {row['distance_m']:.2f} m (min {row['distance_min_m']:.2f}, "
        f"max {row['distance_max_m']:.2f}) in {cfg.eval_steps} steps; first {cfg.horizon} steps: "
        f"model {row['model_progress_m']:.2f} m, simulator {row['sim_progress_m']:.2f} m")
    return row


def algorithm1(cfg: Config, log=print, cache_dir=demo_lib.DEFAULT_CACHE_DIR) -> RunState:
    """Algorithm 1 end to end, in memory (train.py runs the same steps with a checkpoint per iteration)."""
    demo_data = load_demos(cfg, cache_dir)            # T_demo
    state = start(cfg, demo_data, log)                # lines 1-2
    while state.iteration < cfg.iters:                # lines 3-31
        iterate(state, demo_data, log)
    return state
