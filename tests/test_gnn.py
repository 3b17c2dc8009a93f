"""Tests of gnn.py: any design runs, one network per module type, the policy's
memory, gradients through model roll-outs, the model learning sim dynamics.

    python -m pytest tests/test_gnn.py -q        # CPU, about 10 s
"""
import math
import random

import numpy as np
import pytest
import torch

import gnn
import sim2d
from tools.bench import random_transitions

# The named designs, the extremes (all legs, all wheels, one limb) and a fixed sample of the 728.
CODES = sorted(set(sim2d.NAMED_DESIGNS.values()) | {"llllll", "wwwwww", "nnlnnn", "nnnnnw"}
               | set(random.Random(0).sample(sim2d.all_designs(), 12)))


def initial_states(graph, n: int, seed: int = 0) -> torch.Tensor:
    """(n, S) float32 states perturbed around the nominal pose."""
    s = sim2d.sample_initial_states(graph, n, np.random.default_rng(seed))
    return torch.as_tensor(s, dtype=torch.float32)


def noisy_obs(s, graph) -> dict:
    return sim2d.observe(s, graph, sim2d.obs_noise_like(s, graph))


def random_actions(graph, n: int, seed: int = 0) -> torch.Tensor:
    a = np.random.default_rng(seed).uniform(-1, 1, (n, graph.action_dim))
    return torch.as_tensor(a, dtype=torch.float32)


def build(seed: int = 0):
    torch.manual_seed(seed)
    return gnn.ModularPolicy(), gnn.ModularModel()


def normalised_mse(model, s_pred, s, s_next, graph) -> torch.Tensor:
    """Mean over state entries of ((predicted - true) change / fitted std of that change)^2."""
    err = gnn.node_state(s_pred - s_next, graph)
    return sum((err[k] / model.norm_out[k].std).pow(2).sum() for k in err) / s.numel()


@pytest.fixture(scope="module")
def hexapod_data():
    """Sim transitions under random spline actions: 3200 to fit on, 1600 held out."""
    return (random_transitions("hexapod", n_robots=32, steps=100, seed=0),
            random_transitions("hexapod", n_robots=16, steps=100, seed=1))


@pytest.mark.parametrize("code", CODES)
def test_output_shapes_on_any_design(code):
    graph, n = sim2d.design_graph(code), 5
    policy, model = build()
    s = initial_states(graph, n)
    hidden = policy.initial_hidden(n, graph)
    assert hidden.shape == (1 + graph.n_legs + graph.n_wheels, n, policy.cfg.hidden) and not hidden.any()
    mean, log_std, hidden = policy(noisy_obs(s, graph), graph, hidden)
    assert mean.shape == log_std.shape == (n, graph.action_dim)
    assert hidden.shape == (1 + graph.n_legs + graph.n_wheels, n, policy.cfg.hidden)   # node-major
    a, _ = policy.act(noisy_obs(s, graph), graph, hidden)
    s_next = model(s, a, graph)
    assert a.shape == (n, graph.action_dim) and s_next.shape == (n, graph.state_dim)
    assert torch.isfinite(s_next).all() and torch.isfinite(mean).all()


def output_sum(net, design: str) -> torch.Tensor:
    """A scalar that depends on every output of the policy or model on a design."""
    graph = sim2d.design_graph(design)
    s = initial_states(graph, 4)
    if isinstance(net, gnn.ModularPolicy):
        hidden = torch.rand_like(net.initial_hidden(4, graph))       # not 0: W_hh gets a gradient too
        mean, log_std, hidden = net(noisy_obs(s, graph), graph, hidden)
        return mean.sum() + log_std.sum() + hidden.sum()
    return net(s, random_actions(graph, 4), graph).sum()


def reached(net, design: str) -> dict:
    """{parameter name: True if it got a non-zero gradient} from one design's outputs."""
    net.zero_grad(set_to_none=True)
    output_sum(net, design).backward()
    return {name: p.grad is not None and bool(p.grad.abs().sum() > 0) for name, p in net.named_parameters()}


@pytest.mark.parametrize("which", ["policy", "model"])
def test_one_leg_network_serves_every_leg_of_every_design(which):
    net = build()[which == "model"]
    hexapod, leg_none_wheel, car = (reached(net, d) for d in ("hexapod", "leg_none_wheel", "car"))
    leg = [name for name in hexapod if name.startswith("nets.leg.")]
    wheel = [name for name in hexapod if name.startswith("nets.wheel.")]
    assert leg and wheel
    assert all(hexapod[p] and leg_none_wheel[p] for p in leg)       # the same leg parameters serve both
    assert not any(hexapod[p] for p in wheel)                       # a hexapod has no wheels ...
    assert all(leg_none_wheel[p] and car[p] for p in wheel)         # ... other designs do
    assert not any(car[p] for p in leg)


@pytest.mark.parametrize("which", ["policy", "model"])
def test_parameters_do_not_depend_on_the_design(which):
    net = build()[which == "model"]
    names = [name for name, _ in net.named_parameters()]
    count = gnn.count_parameters(net)
    used = [reached(net, code) for code in ("hexapod", "car", "lnwwnl", "nnwnnn", "lwnlwn")]
    assert [name for name, _ in net.named_parameters()] == names    # nothing created per design
    assert gnn.count_parameters(net) == count
    assert set(names) == {p for u in used[:2] for p, hit in u.items() if hit}   # hexapod + car use all


def test_body_tells_front_from_rear_leg():
    """Swapping which port the single leg sits on changes the body's output (through the port vectors)."""
    policy, model = build()
    front, rear = sim2d.design_graph("lnnnnn"), sim2d.design_graph("nnlnnn")
    s = initial_states(front, 3)
    a = random_actions(front, 3)
    assert not torch.allclose(model(s, a, front), model(s, a, rear))
    obs = sim2d.observe(s, front)
    assert not torch.allclose(policy(obs, front, policy.initial_hidden(3, front))[0],
                              policy(obs, rear, policy.initial_hidden(3, rear))[0])


def test_node_index_is_each_nodes_type_and_port_and_made_once():
    graph = sim2d.design_graph("lnwwnl")
    ix = gnn.node_index(graph)
    assert ix.kinds == ("body", "leg", "wheel") and ix.type_of.tolist() == [0, 1, 1, 2, 2]
    assert ix.limb_type.tolist() == [0, 0, 1, 1] and ix.ports.tolist() == [0, 5, 2, 3]
    assert gnn.node_index(sim2d.design_graph("leg_none_wheel")) is ix


@pytest.mark.parametrize("code", ["lnwwnl", "llllll", "wnwwnw", "nnnnnw", "llwwll"])
def test_batched_path_equals_the_node_by_node_computation(code):
    """The batched path training runs (gathered, zero-padded weights, one batched product per
    layer) computes what `node_by_node` computes with each node's own type's modules."""
    torch.manual_seed(0)
    graph, n = sim2d.design_graph(code), 4
    cfg = gnn.GNNConfig()
    policy, model, value = gnn.ModularPolicy(cfg), gnn.ModularModel(cfg), gnn.ModularValue(cfg)
    s, a = initial_states(graph, n), random_actions(graph, n) * 1.5
    model.fit_normalization([(graph, s, a, s + 0.1 * torch.randn_like(s))])
    obs, hidden = noisy_obs(s, graph), torch.randn(1 + graph.n_legs + graph.n_wheels, n, cfg.hidden).tanh()
    for batched, plain in zip(policy(obs, graph, hidden), policy.forward_node_by_node(obs, graph, hidden)):
        torch.testing.assert_close(batched, plain)
    torch.testing.assert_close(model(s, a, graph), model.forward_node_by_node(s, a, graph))
    torch.testing.assert_close(value(obs, graph), value.forward_node_by_node(obs, graph))


def test_node_by_node_is_the_docstrings_steps_on_a_body_with_one_leg():
    """Steps 1-3 by hand for a robot with one leg, one round, no memory: z = tanh(W_enc x + p),
    body += tanh(W_own z_b + W_up z_l), leg += tanh(W_own z_l + W_down body), out = head(z)."""
    torch.manual_seed(0)
    graph, nets = sim2d.design_graph("nnlnnn"), gnn.ModularModel(gnn.GNNConfig(hidden=8)).nets
    x = [torch.randn(2, 5), torch.randn(2, 6)]
    zb, zl = torch.tanh(nets.body.encode(x[0])), torch.tanh(nets.leg.encode(x[1]) + nets.body.ports.weight[2])
    zb = zb + torch.tanh(nets.body.own(zb) + nets.leg.up(zl))
    zl = zl + torch.tanh(nets.leg.own(zl) + nets.leg.down(zb))
    out, h = gnn.node_by_node(nets, graph, x, None, rounds=1)
    torch.testing.assert_close(out[0], nets.body.head(zb))
    torch.testing.assert_close(out[1], nets.leg.head(zl))
    assert h is None


def test_batch_equals_one_robot_at_a_time():
    policy, model = build()
    graph, n = sim2d.design_graph("leg_leg_wheel"), 6
    s, a = initial_states(graph, n), random_actions(graph, n)
    obs = sim2d.observe(s, graph)
    hidden = torch.randn(7, n, policy.cfg.hidden).tanh()
    batched = policy(obs, graph, hidden) + (model(s, a, graph),)
    for i in range(n):
        single = policy({k: v[i:i + 1] for k, v in obs.items()}, graph, hidden[:, i:i + 1]) \
            + (model(s[i:i + 1], a[i:i + 1], graph),)
        for k, (b, o) in enumerate(zip(batched, single)):
            robot_i = b[:, i:i + 1] if k == 2 else b[i:i + 1]                 # the memory is node-major
            torch.testing.assert_close(robot_i, o, rtol=1e-5, atol=1e-6)


def demo_like_batch(design: str, n: int = 8, T: int = 6, seed: int = 0):
    """(graph, obs_seq (n, T, ...), actions (n, T, A)) shaped like demonstration data."""
    graph = sim2d.design_graph(design)
    s = initial_states(graph, n, seed)
    obs = [noisy_obs(s, graph) for _ in range(T)]
    obs_seq = {k: torch.stack([o[k] for o in obs], 1) for k in obs[0]}
    actions = sim2d.random_spline_actions(np.random.default_rng(seed), n, graph.action_dim, steps=T)
    return graph, obs_seq, torch.as_tensor(actions, dtype=torch.float32)


def test_mixed_design_il_loss_in_one_optimiser_step():
    policy = build()[0]
    batches = [demo_like_batch("hexapod"), demo_like_batch("car")]

    def il_loss():                                       # L_IL summed over designs (Sec. III-E)
        return sum(-policy.sequence_log_prob(obs, act, g)[0].sum() for g, obs, act in batches)

    opt = torch.optim.Adam(policy.parameters(), lr=3e-3)
    before = il_loss()
    opt.zero_grad()
    before.backward()
    assert all(policy.nets[k].head.weight.grad.abs().sum() > 0 for k in ("leg", "wheel"))
    opt.step()
    with torch.no_grad():
        after = il_loss()
    assert after < before - 1.0


def test_sequence_log_prob_matches_a_step_by_step_loop():
    policy = build()[0]
    graph, obs_seq, actions = demo_like_batch("lnwwnl", n=3, T=4)
    h0 = torch.randn(5, 3, policy.cfg.hidden).tanh()
    log_prob, entropy = policy.sequence_log_prob(obs_seq, actions, graph, h0)
    assert log_prob.shape == entropy.shape == (3, 4)
    hidden = h0
    for t in range(4):
        mean, log_std, hidden = policy({k: v[:, t] for k, v in obs_seq.items()}, graph, hidden)
        torch.testing.assert_close(log_prob[:, t], gnn.gaussian_log_prob(mean, log_std, actions[:, t]))
        torch.testing.assert_close(entropy[:, t], gnn.gaussian_entropy(log_std))


def test_hidden_state_is_carried_reset_and_restored():
    policy = build()[0]
    graph, n = sim2d.design_graph("hexapod"), 4
    obs1, obs2 = (sim2d.observe(initial_states(graph, n, seed), graph) for seed in (1, 2))
    h1 = policy(obs1, graph, policy.initial_hidden(n, graph))[2]
    assert h1.abs().min() > 0                                       # every node wrote to its memory
    carried = policy(obs2, graph, h1)
    reset = policy(obs2, graph, policy.initial_hidden(n, graph))
    assert not torch.allclose(carried[0], reset[0])                 # memory changes the action
    saved = h1.clone()
    policy(obs1, graph, policy(obs2, graph, carried[2])[2])         # a few more steps
    restored = policy(obs2, graph, saved)
    for x, y in zip(carried, restored):
        assert torch.equal(x, y)


def test_model_beats_no_change_baseline_on_held_out_sim_data(hexapod_data):
    (s, a, s_next), held_out = hexapod_data
    graph = sim2d.design_graph("hexapod")
    model = build()[1]
    model.fit_normalization([(graph, s, a, s_next)])
    opt = torch.optim.Adam(model.parameters(), lr=3e-3)
    for _ in range(400):
        i = torch.randint(len(s), (256,))
        loss = model.loss(s[i], a[i], s_next[i], graph)
        opt.zero_grad()
        loss.backward()
        opt.step()
    s, a, s_next = held_out
    with torch.no_grad():
        error = normalised_mse(model, model(s, a, graph), s, s_next, graph)
        baseline = normalised_mse(model, s, s, s_next, graph)               # predicts s_next = s
        torch.testing.assert_close(error, model.loss(s, a, s_next, graph))  # loss() is this error
    assert error < 0.5 * baseline, (error.item(), baseline.item())          # measured 0.28 vs 0.96


def test_model_ignores_x_and_keeps_its_normalisation_in_the_state_dict(hexapod_data):
    (s, a, s_next), _ = hexapod_data
    graph = sim2d.design_graph("hexapod")
    model, fresh = build(0)[1], build(1)[1]
    model.fit_normalization([(graph, s, a, s_next)])
    fresh.load_state_dict(model.state_dict())
    assert (model.norm_in.leg.std != 1).all() and (model.norm_out.body.std != 1).all()
    torch.testing.assert_close(fresh(s[:50], a[:50], graph), model(s[:50], a[:50], graph))
    shift = torch.zeros(graph.state_dim)
    shift[0] = 7.0
    torch.testing.assert_close(model(s[:50] + shift, a[:50], graph), model(s[:50], a[:50], graph) + shift)


@pytest.mark.parametrize("design", ["hexapod", "leg_none_wheel"])
def test_policy_gradient_flows_through_a_model_rollout(design):
    policy, model = build()
    model.requires_grad_(False)                          # frozen, as in the policy phase
    graph = sim2d.design_graph(design)
    s = initial_states(graph, 8)
    x0, hidden, R = s[:, 0], policy.initial_hidden(8, graph), 0.0
    for _ in range(5):
        a, hidden = policy.act(noisy_obs(s, graph), graph, hidden)
        s_next = model(s, a, graph)
        R = R + sim2d.reward(s, a, s_next, graph)
        s = s_next
    used = [p for name, p in policy.named_parameters() if graph.n_wheels or ".wheel." not in name]
    # The distance covered depends on the actions only through the model.
    for loss in (-(s[:, 0] - x0).mean(), -R.mean()):
        grads = torch.autograd.grad(loss, used, retain_graph=True)
        assert all(torch.isfinite(g).all() and g.abs().sum() > 0 for g in grads)


def test_same_seed_gives_same_outputs():
    graph = sim2d.design_graph("leg_leg_wheel")
    s, a = initial_states(graph, 4), random_actions(graph, 4)
    obs = sim2d.observe(s, graph)

    def outputs(seed):
        policy, model = build(seed)
        torch.manual_seed(123)
        action, hidden = policy.act(obs, graph, policy.initial_hidden(4, graph))
        return action, hidden, model(s, a, graph)

    for x, y in zip(outputs(0), outputs(0)):
        assert torch.equal(x, y)
    assert not torch.equal(outputs(0)[0], outputs(1)[0])


def test_log_std_stays_within_bounds():
    torch.manual_seed(0)
    cfg = gnn.GNNConfig(log_std_min=-1.5, log_std_max=-0.5)
    policy = gnn.ModularPolicy(cfg)
    graph = sim2d.design_graph("leg_leg_wheel")
    for k in ("leg", "wheel"):
        with torch.no_grad():
            policy.nets[k].head.weight.mul_(1000.0)       # drive the raw log-std far out in both directions
    obs = {k: 100.0 * v for k, v in sim2d.observe(initial_states(graph, 64), graph).items()}
    _, log_std, _ = policy(obs, graph, torch.randn(7, 64, cfg.hidden).tanh())
    assert log_std.min() >= -1.5 and log_std.max() <= -0.5
    assert log_std.min() < -1.49 and log_std.max() > -0.51     # both bounds are reached, not just respected


def test_gaussian_log_prob_and_entropy_by_hand():
    mean, log_std, a = torch.tensor([[0.0, 1.0]]), torch.tensor([[0.0, math.log(2.0)]]), torch.tensor([[1., 2.]])
    half_log_2pi = 0.5 * math.log(2 * math.pi)
    # dim 0: z = (1 - 0) / 1 = 1, log std = 0;  dim 1: z = (2 - 1) / 2 = 0.5, log std = log 2
    by_hand = (-0.5 * 1.0 - 0.0 - half_log_2pi) + (-0.5 * 0.25 - math.log(2.0) - half_log_2pi)
    torch.testing.assert_close(gnn.gaussian_log_prob(mean, log_std, a), torch.tensor([by_hand]))
    entropy_by_hand = 2 * 0.5 * math.log(2 * math.pi * math.e) + math.log(2.0)
    torch.testing.assert_close(gnn.gaussian_entropy(log_std), torch.tensor([entropy_by_hand]))


def test_bench_default_run_steps_run_against_todays_algorithm():
    """bench.py measures the code the training runs; a step that no longer runs there (a removed
    function, a changed signature) must fail here, not only when someone benchmarks."""
    from tools import bench
    import modular_rlil_minimal as rlil
    cfg = rlil.preset("tiny", train=("lnwwnl",), demos=("llllll", "wnwwnw"))
    steps = bench.default_run_steps(cfg)
    assert set(steps) == {"policy", "bc", "model"}
    for step in steps.values():
        step()
