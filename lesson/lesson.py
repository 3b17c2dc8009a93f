# ---
# jupyter:
#   jupytext:
#     formats: py:percent
#     text_representation:
#       extension: .py
#       format_name: percent
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Learning modular robot locomotion from demonstrations: the lesson's notebook
#
# The companion of [docs/lesson.md](../docs/lesson.md), one hour: Whitman & Choset
# (arXiv 2210.17491) in six parts, each with an exercise you write and
# `python lesson/grade.py exN` grades.  Every cell runs the project's own
# functions at the tiny budget, on one CPU core.
#
#     python lesson/lesson.py --out /tmp/lesson       # as a plain script: figures go to /tmp/lesson
#     pip install -r requirements-lesson.txt           # jupytext and jupyter, optional
#     jupytext --to notebook lesson/lesson.py          # then open lesson/lesson.ipynb in Jupyter
#
# As a script it takes about 20 s (docs/lesson.md gives the measured time) and
# never needs a display; without `--out` the figures go to a new temporary folder.

# %%
import argparse
import sys
import tempfile
import time
from pathlib import Path

IN_NOTEBOOK = "ipykernel" in sys.modules


def find_root() -> Path:
    """The project folder (the one holding sim2d.py), from this file or, in Jupyter, the current folder."""
    start = Path(__file__).resolve().parent if "__file__" in globals() else Path.cwd().resolve()
    for folder in (start, *start.parents):
        if (folder / "sim2d.py").is_file():
            return folder
    raise SystemExit(f"lesson.py: error: no sim2d.py in {start} or above it: run it from the project")


ROOT = find_root()
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

parser = argparse.ArgumentParser(description="The lesson's notebook as a script: every part, figures to --out.")
parser.add_argument("--out", help="folder for the figures (default: a new temporary folder); not inside the "
                                  "project except under runs/")
args, _ = parser.parse_known_args()           # known only: Jupyter passes its own arguments
OUT = Path(args.out).resolve() if args.out else Path(tempfile.mkdtemp(prefix="lesson-"))
if OUT.is_relative_to(ROOT) and not OUT.is_relative_to(ROOT / "runs"):
    raise SystemExit(f"lesson.py: error: --out {args.out} is inside the project: "
                     "name a folder outside it or under runs/")
OUT.mkdir(parents=True, exist_ok=True)

import matplotlib  # noqa: E402

if not IN_NOTEBOOK:
    matplotlib.use("Agg")                     # a plain script never needs a display
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import torch  # noqa: E402

import gnn  # noqa: E402
import modular_rlil_minimal as rlil  # noqa: E402
import sim2d  # noqa: E402
from experiments import stats  # noqa: E402
from lesson import grade  # noqa: E402

torch.set_num_threads(1)                      # tiny tensors: one thread is fastest (docs/gnn.md)
T0 = time.perf_counter()


def show(fig, name: str) -> None:
    """Save the figure to OUT; in Jupyter, show it inline too."""
    path = OUT / name
    fig.savefig(path, dpi=100, bbox_inches="tight")
    if IN_NOTEBOOK:
        plt.show()
    else:
        plt.close(fig)
        print(f"figure: {path}")


# %% [markdown]
# ## Part 1: the world, the observation and the reward (Sec. III-A, III-F)
#
# A design is six ports, each a leg `l`, a wheel `w` or nothing `n`.  The state is
# flat, body first ([x, y, pitch, vx, vy, pitch rate]), then 4 numbers per leg,
# then 1 per wheel.  The observation O drops x, vx and vy and adds sensor noise,
# split per module the way the networks read it.  Below: the car under random
# spline actions (Sec. III-B), and its reward split into its terms.
#
# **Exercise 1**: `python lesson/exercises/ex1_reward.py`

# %%
graph = sim2d.design_graph("leg_none_wheel")
print(f"{graph.name} ({graph.code}): nodes {graph.nodes}")
print(f"state {graph.state_dim} numbers, action {graph.action_dim}, observation {graph.obs_dim}")
obs = sim2d.observe(sim2d.sample_initial_states(graph, 3, np.random.default_rng(0)), graph)
print("observe(s) of 3 robots:", {k: v.shape for k, v in obs.items()})

car = sim2d.design_graph("car")
actions = sim2d.random_spline_actions(np.random.default_rng(0), 4, car.action_dim, 100)   # (4, 100, A)
run = sim2d.simulate(car, lambda o, s, t: actions[:, t], n=4, steps=100, seed=0)
s, a, s_next = run.states[:, :-1], run.actions, run.states[:, 1:]                        # (4, 100, S), (4, 100, A)
r = sim2d.reward(s, a, s_next, car)                                                       # (4, 100)
terms = {"progress x' - x": s_next[..., 0] - s[..., 0], "- pitch penalty": -sim2d.W_PITCH * s_next[..., 2] ** 2,
         "- effort penalty": -sim2d.W_EFFORT * (a ** 2).mean(-1)}
print(f"summed reward per robot over 100 steps: {np.round(r.sum(1), 2)} (distance {np.round(run.distance_m, 2)} m)")

fig, ax = plt.subplots(figsize=(7, 3.5))
t = np.arange(100) * sim2d.CONTROL_DT
for name, v in terms.items():
    ax.plot(t, np.cumsum(v[0]), label=name)
ax.plot(t, np.cumsum(r[0]), "k--", label="reward r")
ax.set(xlabel="time (s)", ylabel="summed over steps", title="The car under random spline actions: the reward's terms")
ax.legend()
show(fig, "lesson-1-reward.png")

# %% [markdown]
# ## Part 2: the modular policy, one network per module type (Sec. II-B)
#
# One set of layers per module type (body, leg, wheel), shared by every module
# of that type in every design: the parameter count does not depend on the
# design.  A step encodes each node, passes messages on the star-shaped design
# graph, updates each node's memory and reads out each limb's action.
# `gnn.node_by_node` writes it one node at a time; training runs the batched
# path, tested to give the same numbers.
#
# **Exercise 2**: `python lesson/exercises/ex2_message_passing.py`

# %%
cfg = rlil.preset("tiny")
torch.manual_seed(0)
policy = gnn.ModularPolicy(cfg.gnn)
print("policy parameters per type:", {k: gnn.count_parameters(policy.nets[k]) for k in gnn.TYPES})
for name in sim2d.NAMED_DESIGNS:
    g = sim2d.design_graph(name)
    print(f"  {name:15s} {g.code}: {len(g.nodes)} nodes, the same {gnn.count_parameters(policy)} parameters")
s0 = torch.as_tensor(sim2d.sample_initial_states(graph, 3, np.random.default_rng(1)), dtype=torch.float32)
o, h0 = sim2d.observe(s0, graph), policy.initial_hidden(3, graph)
batched, plain = policy(o, graph, h0), policy.forward_node_by_node(o, graph, h0)
print("node by node = batched:", all(torch.allclose(x, y, atol=1e-6) for x, y in zip(batched, plain)))

fig, axes = plt.subplots(1, 4, figsize=(11, 3))
COLOUR = {"body": "tab:grey", "leg": "tab:blue", "wheel": "tab:green"}
for ax, name in zip(axes, sim2d.NAMED_DESIGNS):
    g = sim2d.design_graph(name)
    for kind, port in g.nodes[1:]:                      # ports 0-2 on the left, 3-5 on the right, front up
        x, y = (-1 if port < 3 else 1), 1 - (port if port < 3 else 5 - port)
        ax.plot([0, x], [0, y], "k-", lw=1)
        ax.scatter([x], [y], s=500, color=COLOUR[kind], zorder=2)
        ax.text(x, y, f"{kind[0]}{port}", ha="center", va="center", color="white", fontsize=8)
    ax.scatter([0], [0], s=900, color=COLOUR["body"], zorder=2)
    ax.text(0, 0, "body", ha="center", va="center", color="white", fontsize=8)
    ax.set(title=f"{name} ({g.code})", xlim=(-1.6, 1.6), ylim=(-1.6, 1.6), xticks=[], yticks=[])
fig.suptitle("Design graphs: the policy graph has the same star, one network per node type", y=1.04)
show(fig, "lesson-2-design-graphs.png")

# %% [markdown]
# ## Part 3: L_RL through the model (Sec. III-C, III-F; Algorithm 1 lines 5, 9-16)
#
# Line 2 collects random spline roll-outs, line 5 fits the modular model f~ to
# them (it predicts the change of state), and the policy then learns from
# L_RL = -R, R the summed reward of T model steps, by back-propagating through
# every model step.  Below: how far the fitted model's open-loop prediction of x
# follows the simulator, and one L_RL with its gradient.
#
# **Exercise 3**: `python lesson/exercises/ex3_rl_loss.py`

# %%
cfg = rlil.preset("tiny", train=("car",))
rng = rlil.seed_everything(0)
data = {car.code: rlil.collect_random_rollouts("car", cfg, rng)}                          # line 2
model, policy = gnn.ModularModel(cfg.gnn), gnn.ModularPolicy(cfg.gnn)
print(f"line 5: model loss {rlil.train_model(model, data, cfg, rng, first=True):.3f} after {cfg.model_steps} steps")

traj = data[car.code]
with torch.no_grad():
    s_pred, f = [traj.states[:4, 0]], model.on_design(car)
    for k in range(traj.actions.shape[1]):                                               # the recorded actions
        s_pred.append(f(s_pred[-1], traj.actions[:4, k]))
fig, ax = plt.subplots(figsize=(7, 3.5))
for i in range(4):
    line, = ax.plot(traj.states[i, :, 0], label=f"simulator, episode {i}")
    ax.plot(torch.stack(s_pred)[:, i, 0], "--", color=line.get_color())
ax.set(xlabel="control step", ylabel="x (m)", title="The model (dashed) replaying the simulator's random actions")
ax.legend(fontsize=7)
show(fig, "lesson-3-model.png")

model.requires_grad_(False)                                                              # frozen in the policy phase
s0 = rlil.sample_sim_states(traj, cfg.batch, rng)
R, s_T, h_T = rlil.rollout(policy, model, s0, policy.initial_hidden(cfg.batch, car), car, cfg.horizon)
loss_rl = -R.mean()                                                                      # line 16
loss_rl.backward()
norm = torch.sqrt(sum((p.grad ** 2).sum() for p in policy.parameters() if p.grad is not None))
print(f"L_RL over T = {cfg.horizon} model steps: {loss_rl.item():.3f}; |dL_RL/dtheta| = {norm:.3f}")

# %% [markdown]
# ## Part 4: imitation, L_IL with the entropy penalty, and L_RLIL (Sec. III-D, III-E, III-J)
#
# The demonstrations are (o, a) pairs of other designs: here the hexapod's
# tripod gait.  Line 1 clones them by minimising L_IL (minus the log-likelihood
# of the demonstrated actions); in the policy phase L = L_RL + lambda (L_IL +
# entropy_weight H), the entropy H of the policy on the demonstrations' observations.
#
# **Exercise 4**: `python lesson/exercises/ex4_il_loss.py`

# %%
cfg = rlil.preset("tiny", demos=("hexapod",))
demo_data = rlil.load_demos(cfg, cache_dir=OUT / "cache")                                 # made in about 1 s
rng = rlil.seed_everything(0)
policy = gnn.ModularPolicy(cfg.gnn)
opt = torch.optim.Adam(policy.parameters(), lr=cfg.policy_lr)
curve = []
for step in range(cfg.bc_steps):                                                          # line 1, as pretrain_bc
    loss_il, entropy = rlil.il_loss(policy, demo_data, cfg, rng)
    opt.zero_grad()
    loss_il.backward()
    opt.step()
    curve.append((loss_il.item(), entropy.item()))
fig, ax = plt.subplots(figsize=(7, 3.5))
ax.plot([c[0] for c in curve], label="L_IL (nats per pair)")
ax.plot([c[1] for c in curve], label="entropy H on demo observations")
ax.set(xlabel="behavioural cloning step (line 1)", title="Cloning the hexapod's demonstrations")
ax.legend()
show(fig, "lesson-4-cloning.png")
loss_il, entropy = rlil.il_loss(policy, demo_data, cfg, rng)
for lam in (10.0, 5.0, 0.0):                                                             # lambda halves every iteration
    total = rlil.rlil_loss(loss_rl.detach(), loss_il + cfg.entropy_weight * entropy, lam)
    print(f"lambda {lam:4.1f}: L = L_RL {loss_rl.item():.3f} + lambda (L_IL {loss_il.item():.3f} "
          f"+ {cfg.entropy_weight} H {entropy.item():.3f}) = {total.item():.3f}")

# %% [markdown]
# ## Part 5: the adaptive learning rate (Sec. III-J)
#
# Every few steps the policy's validation reward (T deterministic model steps
# from a fixed set of states) is compared with its value at the phase's start:
# below it, the policy and Adam go back to the last passed check and the
# learning rate halves.  Below: the rule on a toy "policy", with made-up
# validation rewards.
#
# **Exercise 5**: `python lesson/exercises/ex5_adaptive_lr.py`

# %%
torch.manual_seed(0)
toy, x = torch.nn.Linear(3, 2), torch.randn(4, 3)
opt = torch.optim.Adam(toy.parameters(), lr=0.1)
rule = rlil.AdaptiveLearningRate(toy, opt, start_value=1.0, lr_drop=0.5)
for value in (1.5, 0.5, 1.2, float("nan")):
    opt.zero_grad()
    toy(x).pow(2).sum().backward()
    opt.step()
    rule.check(value)
    print(f"validation reward {value:4}: reverts {rule.reverts}, lr {rule.lr:.3f}, last passed {rule.last}")

# %% [markdown]
# ## Part 6: the experiment: do the car's own demonstrations help the car?
#
# **Write your prediction in `lesson/exercises/ex6_experiment.py` (PREDICTION)
# before you run this cell.**  It runs Algorithm 1 at the tiny budget on the
# car, without demonstrations (RL) and with the car's own (RL+IL), and draws
# both curves over the committed runs of the same commands (results/class_demo.csv,
# seeds 0-4).  The paper (Sec. IV): "the car demonstrations had little effect
# on the car policy convergence".
#
# **Exercise 6**: the two `train.py` commands in the exercise's docstring, then
# `python lesson/exercises/ex6_experiment.py`

# %%
def quiet(message: str) -> None:
    pass


curves = {}
for method, demos in (("RL", ()), ("RL+IL", ("car",))):
    cfg = rlil.preset("tiny", train=("car",), demos=demos)
    t = time.perf_counter()
    result = rlil.algorithm1(cfg, rlil.load_demos(cfg, cache_dir=OUT / "cache"), log=quiet)
    curves[method] = {row["iteration"]: row["distance_m"] for row in result.metrics}
    print(f"{method:6s} distance per iteration: {' '.join(f'{d:.2f}' for d in curves[method].values())} m "
          f"({time.perf_counter() - t:.0f} s)")
iters = max(curves["RL"])
mine = stats.area_under_curve(curves["RL+IL"], iters) - stats.area_under_curve(curves["RL"], iters)
committed = grade.committed_auc_differences()
print(f"area under the curve, RL+IL - RL: {mine:.2f} m; committed seeds 0-4: "
      + " ".join(f"{v:.2f}" for v in committed.values()))

fig, ax = plt.subplots(figsize=(7, 3.5))
rows = grade.committed_curves()
for method, colour in (("RL", "tab:red"), ("RL+IL", "tab:blue")):
    seeds = np.array([[rows[method, seed][i] for i in range(iters + 1)] for seed in sorted(committed)])
    ax.fill_between(range(iters + 1), seeds.min(0), seeds.max(0), color=colour, alpha=0.2,
                    label=f"{method}, committed seeds 0-4 (min-max)")
    ax.plot(list(curves[method]), list(curves[method].values()), "o-", color=colour, label=f"{method}, this run")
ax.set(xlabel="iteration", ylabel=f"distance in {cfg.eval_steps} steps (m)", xticks=range(iters + 1),
       title="The car at the tiny budget: with and without its own demonstrations")
ax.legend(fontsize=7)
show(fig, "lesson-6-experiment.png")
print(f"lesson.py: all six parts in {time.perf_counter() - T0:.0f} s; figures in {OUT}")
