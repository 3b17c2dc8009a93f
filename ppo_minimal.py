"""PPO on the modular policy: the model-free baseline the paper does not show.

Schulman et al. 2017, "Proximal Policy Optimization Algorithms" (arXiv:1707.06347):
the clipped surrogate objective (eqn. 7), its sum with a value loss and an
entropy bonus (eqn. 9), generalised advantage estimation (eqns. 11-12), and
the paper's Algorithm 1 ("PPO, Actor-Critic Style"), whose lines are marked
`# PPO line N` in `ppo`.  Everything else is Whitman & Choset's setting: the
same policy network as Algorithm 1 of modular_rlil_minimal.py
(`gnn.ModularPolicy`), a modular critic (`gnn.ModularValue`), the same world
(`sim2d.simulate`, the one simulation loop) and the same evaluation
(`modular_rlil_minimal.evaluate_policy`: distance in 200 control steps from
the same 8 perturbed starts), so numbers compare one to one.

    collect_episodes   PPO lines 2-3: N robots run pi_theta_old for one episode of T steps each
    ReturnScale        rewards divided by the running std of the discounted return (CleanRL)
    gae                PPO line 4, eqns. 11-12: advantages A_t, bootstrapped at the time limit
    ppo_loss           eqn. 9 built on eqn. 7: -L^CLIP + c1 L^VF - c2 S
    ppo_update         PPO line 6: K epochs of minibatch Adam steps on ppo_loss
    ppo                the loop, evaluating every `eval_every` simulator steps

With --demos, PPO+IL after DAPG (Rajeswaran et al. 2018, "Learning Complex Dexterous
Manipulation with Deep Reinforcement Learning and Demonstrations", Sec. 4), built from
Algorithm 1's own pieces (modular_rlil_minimal: load_demos, pretrain_bc, il_loss, rlil_loss):

    behavioural_cloning  DAPG's pre-training = Algorithm 1 line 1, before iteration 0's evaluation
    ppo_il_loss          eqn. 9 + lambda (L_IL + entropy penalty), Algorithm 1 line 19's form
    il_weight_at         lambda = il_weight il_decay^(i-1) in PPO iteration i (line 30, per iteration)

The policy's memory: `Memoryless` runs gnn.ModularPolicy with its GRU memory
reset to h = 0 before every step, in training and in evaluation, so every
sample's log-probability is one batched forward pass.  Handling the memory as
CleanRL's LSTM PPO does (re-running each robot's sequence in order for every
minibatch) costs 20-40x more per minibatch on a CPU (`python tools/bench.py
--ppo`; docs/ppo.md).

CPU, one thread (the command line is train.py):
    python train.py --train hexapod --method ppo                  # 2 M simulator steps (docs/ppo.md)
    python train.py --train car --method ppo --preset tiny        # the car learns to drive
    python train.py --train leg_none_wheel --method ppo --demos hexapod car   # PPO+IL
    python tools/bench.py --ppo                                   # one iteration's collection and update, timed
"""
from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field

import numpy as np
import torch

import demos as demo_lib
import sim2d
from gnn import (GNNConfig, ModularPolicy, ModularValue, PolicyOnDesign, gaussian_entropy, gaussian_log_prob,
                 sample_action)
from modular_rlil_minimal import (Config, check_ranges, design_codes, eval_seed, evaluate_policy, from_preset,
                                  il_loss, load_demos, new_seed, pretrain_bc, record, rlil_loss, seed_everything)


# ----------------------------------------------------------------------------
# Config: every knob of PPO (train.py makes each field a flag; the docstring
# under a field is its help text).  Defaults: CleanRL's ppo_continuous_action.py
# (Huang et al. 2022) unless the docstring says otherwise.
# ----------------------------------------------------------------------------
@dataclass
class PPOConfig:
    """Every knob of the PPO baseline.  Defaults: 2 M simulator steps of the hexapod."""

    train: tuple[str, ...] = ("hexapod",)
    """the one design trained"""
    seed: int = 0
    """the one seed everything derives from"""
    threads: int = 1
    """torch CPU threads; results depend on it (float sums round differently)"""
    env_steps: int = 2_000_000
    """simulator steps (robot control steps) of training, evaluation excluded"""
    robots: int = 16
    """N, robots run side by side (PPO's "actors"); 8-64"""
    episode_steps: int = 200
    """T, steps per episode; one episode per robot per iteration, so N T samples per iteration (CleanRL:
    2048); 200 = the evaluation's length"""
    gamma: float = 0.99
    """discount gamma; 0.99 = a horizon of about 100 steps (8 s)"""
    gae_lambda: float = 0.95
    """GAE's lambda (eqn. 11); 0.9-1"""
    clip_coef: float = 0.2
    """epsilon of the clipped surrogate (eqn. 7); 0.1-0.3"""
    epochs: int = 10
    """K, passes over each iteration's samples"""
    minibatches: int = 16
    """minibatches per epoch, of M = N T / minibatches samples each (CleanRL: 32)"""
    lr: float = 3e-4
    """Adam learning rate of policy and value network"""
    anneal_lr: bool = True
    """decay the learning rate linearly to 0 over the run"""
    vf_coef: float = 0.5
    """c1, weight of the value loss (eqn. 9)"""
    ent_coef: float = 0.0
    """c2, weight of the entropy bonus (eqn. 9)"""
    max_grad_norm: float = 0.5
    """gradient-norm clip of every Adam step"""
    norm_adv: bool = True
    """normalise advantages per minibatch"""
    init_std: float = 0.6
    """the policy's std at the start (its log-std heads' bias; gnn's initialisation gives 0.29); 0.3-1
    (docs/ppo.md, Tuning)"""
    eval_every: int = 50_000
    """simulator steps between evaluations (rounded to whole iterations)"""
    # Demonstrations (PPO+IL, after DAPG, Rajeswaran et al. 2018): Algorithm 1's T_demo, line 1 and eqn. (IL_loss)
    demos: tuple[str, ...] = ()
    """D_demo: demonstration designs; none = plain PPO (no pre-training, lambda = 0)"""
    demo_episodes: int = 50
    """demonstration episodes per demo design (paper: 50)"""
    demo_steps: int = 100
    """control steps per demonstration episode (paper: 100)"""
    demo_noise: float = 0.15
    """std of smooth noise on the demonstrators' executed, not recorded, actions, so T_demo shows
    recoveries (DART); 0 = the paper; 0-0.3"""
    bc_steps: int = 1000
    """Adam steps of behavioural cloning before PPO (Algorithm 1's line 1, at its policy_lr 1e-3); 0
    skips it; 300-3000"""
    il_weight: float = 1.0
    """lambda at PPO iteration 1 (L = L_PPO + lambda (L_IL + entropy_weight S_demo)); 0.1-10"""
    il_decay: float = 0.99
    """lambda <- il_decay * lambda after every PPO iteration; 0.99 halves it every 69 iterations, 11 %
    of the default run's 625 (tiny: 0.7, every 2 of 20); 0-1"""
    il_batch: int = 32
    """demo windows per design per minibatch step"""
    il_window: int = 8
    """control steps per demo window (consecutive pairs: the memoryless policy sees each alone); at most
    demo_steps"""
    entropy_weight: float = 0.01
    """weight of the entropy penalty on demo observations (Sec. III-J); 0-0.1"""
    # Evaluation (Sec. IV of Whitman & Choset): distance in 200 control steps, as for Algorithm 1
    eval_episodes: int = 8
    """perturbed starts per evaluation"""
    eval_steps: int = 200
    """control steps per evaluation (paper: 200 = 16.7 s)"""
    gnn: GNNConfig = field(default_factory=GNNConfig)


PRESETS = {   # "tiny": the tests' budget, a class demo in which the car learns to drive
    "default": {},
    "tiny": dict(env_steps=16_000, robots=8, episode_steps=100, minibatches=4, eval_every=8_000,
                 eval_episodes=4, eval_steps=100, lr=1e-3, demo_episodes=8, demo_steps=40, bc_steps=100,
                 il_decay=0.7, il_batch=8, il_window=4, gnn=GNNConfig(hidden=32)),
}


def preset(name: str = "default", **overrides) -> PPOConfig:
    """The PPOConfig of a named budget, with some fields overridden."""
    return from_preset(PPOConfig, PRESETS, name, **overrides)


AT_LEAST = {"seed": 0, "ent_coef": 0.0, "vf_coef": 0.0, "rounds": 0, "bc_steps": 0, "demo_noise": 0.0,
            "il_weight": 0.0, "il_decay": 0.0, "entropy_weight": 0.0}   # the rest must be positive


def validate_config(cfg: PPOConfig) -> PPOConfig:
    """`cfg` with its designs as six-letter codes, or a one-line ValueError naming the bad field."""
    if len(cfg.train) != 1:
        raise ValueError(f"train: PPO trains one design, got {len(cfg.train)}")
    cfg = dataclasses.replace(cfg, train=(sim2d.parse_design(cfg.train[0]),), demos=design_codes("demos", cfg.demos))
    for design in cfg.demos:
        demo_lib.check_demonstrable(sim2d.design_graph(design))
    check_ranges(cfg, AT_LEAST)
    if cfg.gamma > 1 or cfg.gae_lambda > 1 or cfg.il_decay > 1:
        raise ValueError(f"gamma, gae_lambda and il_decay must be at most 1, got {cfg.gamma}, {cfg.gae_lambda} "
                         f"and {cfg.il_decay}")
    if cfg.il_window > cfg.demo_steps:
        raise ValueError(f"il_window ({cfg.il_window}) must not exceed demo_steps ({cfg.demo_steps})")
    if cfg.minibatches > cfg.robots * cfg.episode_steps:
        raise ValueError(f"minibatches ({cfg.minibatches}) must not exceed robots x episode_steps")
    return cfg


def iterations(cfg: PPOConfig) -> int:
    """PPO iterations of the run: env_steps / (N T), rounded up."""
    return math.ceil(cfg.env_steps / (cfg.robots * cfg.episode_steps))


# ----------------------------------------------------------------------------
# The policy without memory, and the data of one iteration
# ----------------------------------------------------------------------------
class Memoryless(torch.nn.Module):
    """pi_theta(a | o_t): gnn.ModularPolicy with its memory reset to h = 0 before every step.

    Has the policy's `initial_hidden`, `act` and `on_design`, so modular_rlil_minimal's
    PolicyActor and evaluate_policy run it unchanged; `distribution` gives the
    Gaussian (mean, log_std), each (n, A), of a batch of observations.
    """

    def __init__(self, policy: ModularPolicy):
        super().__init__()
        self.policy = policy

    def initial_hidden(self, n: int, graph) -> torch.Tensor:
        return self.policy.initial_hidden(n, graph)

    def distribution(self, obs: dict, graph):
        mean, log_std, _ = self.policy(obs, graph, self.policy.initial_hidden(len(obs["body"]), graph))
        return mean, log_std                                                         # (n, A) x 2

    def act(self, obs: dict, graph, hidden, deterministic: bool = False):
        mean, log_std = self.distribution(obs, graph)
        return sample_action(mean, log_std, deterministic), hidden                   # the memory stays 0

    def sequence_log_prob(self, obs_seq: dict, actions_seq, graph):
        """gnn.ModularPolicy.sequence_log_prob without the memory, so modular_rlil_minimal.il_loss
        imitates the policy as PPO runs it: (log pi(a_t | o_t), entropy), each (n, T), from
        obs_seq values (n, T, ...) and actions_seq (n, T, A)."""
        n, T = actions_seq.shape[:2]
        mean, log_std = self.distribution({k: v.flatten(0, 1) for k, v in obs_seq.items()}, graph)   # (n T, A)
        log_prob = gaussian_log_prob(mean, log_std, actions_seq.flatten(0, 1))
        return log_prob.view(n, T), gaussian_entropy(log_std).view(n, T)

    def on_design(self, graph) -> "MemorylessOnDesign":
        return MemorylessOnDesign(self.policy.on_design(graph))


class MemorylessOnDesign:
    """`Memoryless` on one design (gnn.PolicyOnDesign), as PolicyActor runs it."""

    def __init__(self, policy: PolicyOnDesign):
        self.policy = policy

    def act(self, obs: dict, hidden, deterministic: bool = False):
        mean, log_std, _ = self.policy.step(obs, torch.zeros_like(hidden))
        return sample_action(mean, log_std, deterministic), hidden                   # the memory stays 0


class SamplingActor:
    """pi_theta_old as a controller for sim2d.simulate: samples a_t ~ pi(. | o_t) and records
    a_t (unclipped: the world clips) and log pi(a_t | o_t)."""

    def __init__(self, policy: Memoryless, graph):
        self.policy, self.graph, self.actions, self.log_probs = policy, graph, [], []

    @torch.no_grad()
    def __call__(self, obs: dict, state, t: int) -> np.ndarray:
        obs = {k: torch.as_tensor(v, dtype=torch.float32) for k, v in obs.items()}
        mean, log_std = self.policy.distribution(obs, self.graph)
        a = mean + torch.exp(log_std) * torch.randn_like(mean)                       # (N, A)
        self.actions.append(a)
        self.log_probs.append(gaussian_log_prob(mean, log_std, a))                   # (N,)
        return a.numpy().astype(float)


@dataclass
class Batch:
    """One iteration's samples from N robots x T steps; tensors (N, T, ...) float32 unless said."""

    obs: dict                   # o_t per module, as the policy saw them
    actions: torch.Tensor       # (N, T, A) a_t as sampled (the world applied them clipped)
    log_probs: torch.Tensor     # (N, T) log pi_theta_old(a_t | o_t)
    rewards: torch.Tensor       # (N, T) r(s_t, a_t, s_t+1), sim2d.reward
    values: torch.Tensor        # (N, T) V(o_t)
    last_value: torch.Tensor    # (N,) V(o_T): the bootstrap at the time limit
    terminal: torch.Tensor      # (N, T) 1.0 where the robot flipped at step t (a true end: no bootstrap)
    valid: torch.Tensor         # (N, T) bool, False after a flip (those steps are simulated, not trained on)
    distance_m: np.ndarray      # (N,) x_T - x_0 of the training episodes (sampled actions)


@torch.no_grad()
def collect_episodes(policy: Memoryless, value: ModularValue, cfg: PPOConfig, rng: np.random.Generator) -> Batch:
    """PPO lines 2-3: N robots run pi_theta_old for one episode of T steps each, from p(s).

    Every episode ends at the time limit T, which is not the end of the task:
    GAE bootstraps with V(o_T) there (Pardo et al. 2018).  A robot that flips
    (|pitch| > 90 deg, the world's `terminated`) ends its episode at that step;
    its later steps are still simulated (all robots share the episode) but
    left out of training.
    """
    graph = sim2d.design_graph(cfg.train[0])
    actor = SamplingActor(policy, graph)
    run = sim2d.simulate(graph, actor, n=cfg.robots, steps=cfg.episode_steps, seed=new_seed(rng))
    s, s_next = run.states[:, :-1], run.states[:, 1:]                                   # (N, T, S) x 2
    flip = sim2d.is_flipped(s_next)                                                     # (N, T)
    ended = np.cumsum(flip, 1) > 0                                                      # at or after the flip
    valid = np.concatenate([np.ones((cfg.robots, 1), bool), ~ended[:, :-1]], 1)         # (N, T)
    obs = {k: torch.as_tensor(v, dtype=torch.float32) for k, v in run.obs.items()}      # (N, T, ...)
    flat = {k: v.flatten(0, 1) for k, v in obs.items()}                                 # (N T, ...)
    s_T = run.states[:, -1]
    o_T = sim2d.observe(s_T, graph, sim2d.obs_noise_like(s_T, graph, rng))             # noisy, like every o_t
    return Batch(obs=obs, actions=torch.stack(actor.actions, 1), log_probs=torch.stack(actor.log_probs, 1),
                 rewards=torch.as_tensor(sim2d.reward(s, run.actions, s_next, graph), dtype=torch.float32),
                 values=value(flat, graph).view(cfg.robots, cfg.episode_steps),
                 last_value=value({k: torch.as_tensor(v, dtype=torch.float32) for k, v in o_T.items()}, graph),
                 terminal=torch.as_tensor(flip & valid, dtype=torch.float32),
                 valid=torch.as_tensor(valid), distance_m=run.distance_m)


@dataclass
class ReturnScale:
    """Rewards divided by the running std of the discounted return G_t = gamma G_t-1 + r_t
    (CleanRL's gym.wrappers.NormalizeReward), so value targets are O(1) whatever the design's
    speed: progress is about 0.001 m per step at first and 0.08 m per step at a walk."""

    count: float = 1e-4               # steps seen (1e-4 as in gym's RunningMeanStd, never 0)
    mean: float = 0.0                 # running mean of G_t
    var: float = 1.0                  # running variance of G_t

    def update(self, rewards: torch.Tensor, valid: torch.Tensor, gamma: float) -> None:
        """Fold in G_t of every valid step of a batch of whole episodes, rewards (N, T)."""
        G, returns = torch.zeros(len(rewards)), []
        for t in range(rewards.shape[1]):
            G = gamma * G + rewards[:, t]
            returns.append(G)
        x = torch.stack(returns, 1)[valid].double()                                    # (valid steps,)
        n, delta, total = len(x), x.mean().item() - self.mean, self.count + len(x)
        m2 = self.var * self.count + x.var(unbiased=False).item() * n + delta ** 2 * self.count * n / total
        self.mean, self.var, self.count = self.mean + delta * n / total, m2 / total, total

    def __call__(self, rewards: torch.Tensor) -> torch.Tensor:
        return rewards / math.sqrt(self.var + 1e-8)


# ----------------------------------------------------------------------------
# Eqns. 11-12, eqn. 9 with eqn. 7, and PPO line 6
# ----------------------------------------------------------------------------
def gae(rewards, values, last_value, terminal, gamma: float, lam: float):
    """PPO line 4, eqns. 11-12: generalised advantage estimates and the value targets.

        delta_t = r_t + gamma V(o_t+1) (1 - terminal_t) - V(o_t)               (eqn. 12)
        A_t     = delta_t + gamma lam (1 - terminal_t) A_t+1                    (eqn. 11, recursively)
        R_t     = A_t + V(o_t)                                                  (the value target)

    with V(o_T) = last_value after the last step (a time limit, not a true end).
    Inputs (N, T) and (N,); returns A and R, each (N, T).  Worked example
    (N = 1, T = 2, gamma = lam = 0.5, V = 0, last_value = 4, no flip):
    r = [1, 1] gives delta = [1, 1 + 0.5 * 4] = [1, 3] and A = [1 + 0.25 * 3, 3] = [1.75, 3].
    """
    advantages = torch.zeros_like(rewards)
    next_value, next_advantage = last_value, torch.zeros_like(last_value)
    for t in reversed(range(rewards.shape[1])):
        keep = 1.0 - terminal[:, t]
        delta = rewards[:, t] + gamma * next_value * keep - values[:, t]                # eqn. 12
        next_advantage = delta + gamma * lam * keep * next_advantage                    # eqn. 11
        advantages[:, t] = next_advantage
        next_value = values[:, t]
    return advantages, advantages + values


def ppo_loss(policy: Memoryless, value: ModularValue, mb: dict, graph, cfg: PPOConfig):
    """Eqn. 9 (to minimise): -L^CLIP + c1 L^VF - c2 S on one minibatch `mb` (flat tensors).

        r_t(theta) = pi_theta(a_t | o_t) / pi_theta_old(a_t | o_t)                       (eqn. 6)
        L^CLIP     = mean_t min(r_t A_t, clip(r_t, 1 - eps, 1 + eps) A_t)                 (eqn. 7)
        L^VF       = mean_t (V(o_t) - R_t)^2 / 2,   S = mean_t entropy of pi(. | o_t)

    Returns the loss and a flat dict of metrics (approx_kl: mean of (r - 1) - log r).
    """
    mean, log_std = policy.distribution(mb["obs"], graph)                                 # (M, A) x 2
    log_ratio = gaussian_log_prob(mean, log_std, mb["actions"]) - mb["log_probs"]        # (M,)
    ratio = torch.exp(log_ratio)                                                          # eqn. 6
    adv = mb["advantages"]
    if cfg.norm_adv and len(adv) > 1:                   # one sample has no std (NaN)
        adv = (adv - adv.mean()) / (adv.std() + 1e-8)
    l_clip = torch.min(ratio * adv, ratio.clamp(1 - cfg.clip_coef, 1 + cfg.clip_coef) * adv).mean()   # eqn. 7
    l_vf = 0.5 * (value(mb["obs"], graph) - mb["returns"]).pow(2).mean()
    entropy = gaussian_entropy(log_std).mean()
    loss = -l_clip + cfg.vf_coef * l_vf - cfg.ent_coef * entropy                         # eqn. 9
    with torch.no_grad():
        stats = {"policy_loss": -l_clip.item(), "value_loss": l_vf.item(), "entropy": entropy.item(),
                 "approx_kl": ((ratio - 1) - log_ratio).mean().item(),
                 "clip_fraction": ((ratio - 1).abs() > cfg.clip_coef).float().mean().item()}
    return loss, stats


def ppo_il_loss(policy: Memoryless, value: ModularValue, mb: dict, graph, cfg: PPOConfig, demo_data: dict,
                il_weight: float, rng: np.random.Generator):
    """PPO+IL, after DAPG (Rajeswaran et al. 2018, Sec. 4: the policy gradient augmented with a
    behavioural-cloning term on the demonstrations, its weight decaying), in the form of
    Algorithm 1 line 19, eqn. (RLIL_loss), with PPO's loss as L_RL:

        L = (-L^CLIP + c1 L^VF - c2 S) + lambda (L_IL + entropy_weight S_demo)

    L_IL and S_demo are modular_rlil_minimal.il_loss on a fresh batch of demo windows (DAPG also
    scales lambda by the largest advantage; Algorithm 1, and this, do not).  With lambda = 0 (or
    no demos) this is `ppo_loss`, and no random number is drawn.
    """
    loss, stats = ppo_loss(policy, value, mb, graph, cfg)
    if il_weight > 0 and demo_data:
        loss_il, entropy = il_loss(policy, demo_data, cfg, rng)
        loss = rlil_loss(loss, loss_il + cfg.entropy_weight * entropy, il_weight)
        stats["il_loss"] = loss_il.item()
    return loss, stats


def ppo_update(policy: Memoryless, value: ModularValue, opt, batch: Batch, advantages, returns,
               cfg: PPOConfig, rng: np.random.Generator, demo_data: dict | None = None,
               il_weight: float = 0.0) -> dict:
    """PPO line 6: optimise eqn. 9 (with demos: `ppo_il_loss`, weight `il_weight`) for K epochs of
    minibatches of the valid samples, given `gae`'s advantages and returns (N, T).  Returns the last
    epoch's metrics, averaged over its minibatches."""
    graph = sim2d.design_graph(cfg.train[0])
    keep = batch.valid.flatten()                                                          # (N T,)
    data = {"obs": {k: v.flatten(0, 1)[keep] for k, v in batch.obs.items()},
            "actions": batch.actions.flatten(0, 1)[keep], "log_probs": batch.log_probs.flatten()[keep],
            "advantages": advantages.flatten()[keep], "returns": returns.flatten()[keep]}  # (M_all, ...)
    params = list(policy.parameters()) + list(value.parameters())
    for _ in range(cfg.epochs):
        stats = []
        for idx in np.array_split(rng.permutation(int(keep.sum())), min(cfg.minibatches, int(keep.sum()))):
            i = torch.from_numpy(idx)
            mb = {k: ({o: x[i] for o, x in v.items()} if k == "obs" else v[i]) for k, v in data.items()}
            loss, s = ppo_il_loss(policy, value, mb, graph, cfg, demo_data, il_weight, rng)
            opt.zero_grad()
            loss.backward()
            torch.nn.utils.clip_grad_norm_(params, cfg.max_grad_norm)
            opt.step()
            stats.append(s)
    return {k: float(np.mean([s[k] for s in stats])) for k in stats[0]}


# ----------------------------------------------------------------------------
# Everything a run carries, and the loop
# ----------------------------------------------------------------------------
@dataclass
class PPORun:
    """What PPO carries from one iteration to the next: enough to resume a run."""

    cfg: PPOConfig
    policy: ModularPolicy
    value: ModularValue
    opt: torch.optim.Optimizer
    rng: np.random.Generator
    iteration: int = 0               # last finished PPO iteration
    sim_steps: int = 0               # simulator steps of training so far (evaluation excluded; with
                                     # demos, theirs included from the start)
    return_scale: ReturnScale = field(default_factory=ReturnScale)
    metrics: list = field(default_factory=list)   # one row per evaluation, iteration 0 included

    def rng_state(self) -> dict:
        return {"numpy": self.rng.bit_generator.state, "torch": torch.get_rng_state()}


def evaluation_row(run: PPORun, seconds: float) -> dict:
    """Sec. IV's metric with modular_rlil_minimal.evaluate_policy: the same starts as Algorithm 1's runs."""
    design = run.cfg.train[0]
    result = evaluate_policy(Memoryless(run.policy), design, run.cfg, eval_seed(run.cfg))
    d = result.distance_m
    return {"iteration": run.iteration, "sim_steps": run.sim_steps, "distance_m": float(d.mean()),
            "distance_min_m": float(d.min()), "distance_max_m": float(d.max()),
            "flipped": int(result.flipped.sum()), "seconds": seconds}


def set_initial_std(policy: ModularPolicy, std: float) -> None:
    """Start every joint's std at `std`: the bias of the raw log-std outputs (the second half of
    each limb head) is set to the sigmoid's inverse of where log(std) sits in [log_std_min, log_std_max]."""
    lo, hi = policy.cfg.log_std_min, policy.cfg.log_std_max
    u = min(max((math.log(std) - lo) / (hi - lo), 1e-3), 1 - 1e-3)
    with torch.no_grad():
        for kind in ("leg", "wheel"):
            bias = policy.nets[kind].head.bias
            bias[len(bias) // 2:] = math.log(u / (1 - u))


def new_run(cfg: PPOConfig) -> PPORun:
    """A fresh policy (std `init_std`), critic and optimiser (Adam, eps 1e-5 as in CleanRL), seeded in one place."""
    rng = seed_everything(cfg.seed)
    policy, value = ModularPolicy(cfg.gnn), ModularValue(cfg.gnn)
    set_initial_std(policy, cfg.init_std)
    opt = torch.optim.Adam(list(policy.parameters()) + list(value.parameters()), lr=cfg.lr, eps=1e-5)
    return PPORun(cfg, policy, value, opt, rng)


def behavioural_cloning(policy: ModularPolicy, demo_data: dict, cfg: PPOConfig, rng: np.random.Generator) -> float:
    """DAPG's pre-training (Rajeswaran et al. 2018, Sec. 4) is Algorithm 1's line 1:
    modular_rlil_minimal.pretrain_bc, `bc_steps` Adam steps on L_IL at Algorithm 1's policy_lr,
    here on the memoryless policy PPO runs.  Returns the IL loss of the last 10 % of the steps."""
    bc_cfg = Config(bc_steps=cfg.bc_steps, il_batch=cfg.il_batch, il_window=cfg.il_window)
    return pretrain_bc(Memoryless(policy), demo_data, bc_cfg, rng)


def il_weight_at(cfg: PPOConfig, i: int) -> float:
    """lambda in PPO iteration i (1, 2, ...): il_weight il_decay^(i-1), DAPG's lambda_0 lambda_1^k
    (Rajeswaran et al. 2018, Sec. 4), i.e. Algorithm 1 line 30 applied once per PPO iteration."""
    return cfg.il_weight * cfg.il_decay ** (i - 1)


def ppo(cfg: PPOConfig, run: PPORun | None = None, log=print, on_evaluation=None,
        demo_data: dict | None = None) -> PPORun:
    """PPO (Schulman et al. 2017, Algorithm 1) on the modular policy, from scratch or continuing `run`.

    With `cfg.demos`, PPO+IL after DAPG (Rajeswaran et al. 2018): behavioural cloning first, then
    `ppo_il_loss`.  demo_data: T_demo from modular_rlil_minimal.load_demos (loaded here if None).
    After every evaluation (iteration 0 included) `on_evaluation(run)` is called
    (train.py saves checkpoints and plots there).  Returns the PPORun.
    """
    torch.set_num_threads(cfg.threads)
    demo_data = load_demos(cfg) if demo_data is None else demo_data                    # {} without demos
    t0 = time.perf_counter()
    if run is None:
        run = new_run(cfg)
        if demo_data:            # the demonstrations' simulator steps count, as Algorithm 1's sim_steps counts them
            run.sim_steps = len(cfg.demos) * cfg.demo_episodes * cfg.demo_steps
        if demo_data and cfg.bc_steps:                                                  # DAPG's pre-training
            log(f"behavioural cloning on {', '.join(demo_data)}: IL loss "
                f"{behavioural_cloning(run.policy, demo_data, cfg, run.rng):.3f}")
        record(run, evaluation_row(run, time.perf_counter() - t0), log)
        log(f"iteration 0: {run.metrics[-1]['distance_m']:.2f} m in {cfg.eval_steps} steps")
        if on_evaluation:
            on_evaluation(run)
        t0 = time.perf_counter()
    policy, n_iters = Memoryless(run.policy), iterations(cfg)
    per_eval = max(1, round(cfg.eval_every / (cfg.robots * cfg.episode_steps)))
    train_distance = []
    for i in range(run.iteration + 1, n_iters + 1):                                     # PPO line 1
        if cfg.anneal_lr:
            for group in run.opt.param_groups:
                group["lr"] = cfg.lr * (1 - (i - 1) / n_iters)
        batch = collect_episodes(policy, run.value, cfg, run.rng)                       # PPO lines 2-3
        run.return_scale.update(batch.rewards, batch.valid, cfg.gamma)
        advantages, returns = gae(run.return_scale(batch.rewards), batch.values, batch.last_value,
                                  batch.terminal, cfg.gamma, cfg.gae_lambda)            # PPO line 4
        il_weight = il_weight_at(cfg, i) if demo_data else 0.0                          # DAPG's decaying lambda
        stats = ppo_update(policy, run.value, run.opt, batch, advantages, returns, cfg, run.rng,
                           demo_data, il_weight)                                        # PPO line 6
        run.iteration, run.sim_steps = i, run.sim_steps + cfg.robots * cfg.episode_steps  # PPO line 7: theta_old <- theta
        train_distance.append(batch.distance_m.mean())
        if i % per_eval == 0 or i == n_iters:
            row = evaluation_row(run, 0.0)
            row.update({"train_distance_m": float(np.mean(train_distance)), **stats,
                        "lr": run.opt.param_groups[0]["lr"], "seconds": time.perf_counter() - t0})
            if demo_data:
                row["il_weight"] = il_weight
            record(run, row, log)
            log(f"iteration {i}/{n_iters}  {run.sim_steps} steps: {row['distance_m']:.2f} m "
                f"(min {row['distance_min_m']:.2f}, max {row['distance_max_m']:.2f}) in {cfg.eval_steps} steps; "
                f"training episodes {row['train_distance_m']:.2f} m; value loss {stats['value_loss']:.4f}, "
                f"entropy {stats['entropy']:.2f}, approx KL {stats['approx_kl']:.4f}, "
                f"clipped {stats['clip_fraction']:.2f}"
                + (f"; lambda {il_weight:.3g}, IL loss {stats['il_loss']:.3f}" if "il_loss" in stats else ""))
            train_distance, t0 = [], time.perf_counter()
            if on_evaluation:
                on_evaluation(run)
    return run
