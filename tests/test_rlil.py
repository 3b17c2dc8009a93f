"""Tests of Algorithm 1 (modular_rlil_minimal.py) and its command line (train.py).

Budgets are the "tiny" preset (the class demo), shortened per test where a
test needs less.  Every learning stage has a test that fails when it stops
learning: the RL phase (the car must learn to drive), behavioural cloning (the
IL loss must fall), the model fit (it must beat predict-no-change on held-out
data), and the pieces of the policy phase (buffer refresh, validation revert,
entropy penalty, policy data noise) are checked against what they must do.
"""
import copy
import dataclasses
import json
import math
import subprocess
import sys

import numpy as np
import pytest
import torch

import modular_rlil_minimal as rlil
import sim2d
import train
from experiments import run_folders, sweeps


def tiny(**kw) -> rlil.Config:
    return rlil.preset("tiny", **kw)


def smoke(**kw) -> rlil.Config:
    """The tiny preset with short evaluations, for tests of the plumbing, not of learning."""
    return tiny(**{"eval_steps": 30, "policy_steps": 6, "bc_steps": 10, **kw})


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    return tmp_path_factory.mktemp("demo_cache")


@pytest.fixture(scope="module")
def hexapod_demos(cache):
    return rlil.load_demos(tiny(demos=("hexapod",)), cache)


@pytest.fixture(scope="module")
def car_data():
    """Random-action data of the car at the tiny budget (line 2)."""
    return {"wnwwnw": rlil.collect_random_rollouts("car", tiny(), np.random.default_rng(0))}


def quiet(*args, **kw):
    pass


def strip_times(metrics):
    return [{k: v for k, v in row.items() if k != "seconds"} for row in metrics]


# ----------------------------------------------------------------------------
# Learning: each stage must learn, or a test goes red
# ----------------------------------------------------------------------------
def test_rl_phase_teaches_the_car_to_drive(tmp_path, cache):
    """Plain RL (no demos) at the tiny budget: the car starts near 2 m in 100 steps and must
    reach at least 7 m after one iteration (measured 9.8 m, wheel top speed 9.9 m).
    Fails with the RL loss's sign flipped (the policy then drives backwards, or the
    validation revert holds it at its start)."""
    metrics = train.run(tiny(train=("car",), iters=1), tmp_path, log=quiet, cache_dir=cache)
    assert metrics[0]["distance_m"] < 4.0
    assert metrics[1]["distance_m"] > 7.0, [m["distance_m"] for m in metrics]
    assert metrics[1]["il_weight"] == 0.0 and metrics[1]["il_loss"] is None


def test_behavioural_cloning_lowers_the_il_loss(hexapod_demos):
    """Line 1: 100 BC steps must lower L_IL on a fixed demo batch by at least 5 nats per pair
    (measured: from 37.0 to 6.8).  Fails if BC ascends or skips its step."""
    cfg = tiny()
    torch.manual_seed(0)
    policy = rlil.ModularPolicy(cfg.gnn)

    def loss_on_fixed_batch():
        with torch.no_grad():
            return rlil.il_loss(policy, hexapod_demos, cfg, np.random.default_rng(123))[0].item()

    before = loss_on_fixed_batch()
    bc = rlil.pretrain_bc(policy, hexapod_demos, cfg, np.random.default_rng(0))
    after = loss_on_fixed_batch()
    assert after < before - 5.0, (before, after)
    assert bc < before - 5.0


def test_algorithm1_starts_from_behavioural_cloning_when_demos_are_given(hexapod_demos):
    """Line 1 inside Algorithm 1: the policy evaluated at iteration 0 must already imitate the
    demos, far better than the same seed's untrained policy (measured on a fixed demo batch:
    37.0 nats untrained, 6.8 after the tiny budget's 100 BC steps).  Fails when `algorithm1`
    skips `pretrain_bc`."""
    cfg = smoke(train=("car",), demos=("hexapod",), iters=1, bc_steps=100)
    at_iteration_0 = []
    rlil.algorithm1(cfg, hexapod_demos, log=quiet,
                    on_iteration=lambda run: at_iteration_0.append(copy.deepcopy(run.policy)) if run.iteration == 0 else None)
    rlil.seed_everything(cfg.seed)
    untrained = rlil.ModularPolicy(cfg.gnn)                 # the policy algorithm1 starts from

    def loss(policy):
        with torch.no_grad():
            return rlil.il_loss(policy, hexapod_demos, cfg, np.random.default_rng(123))[0].item()

    assert loss(at_iteration_0[0]) < loss(untrained) - 5.0, (loss(at_iteration_0[0]), loss(untrained))


def test_algorithm1_adds_the_policy_data_to_T_train_and_refits_the_model_on_it(monkeypatch):
    """Lines 28-29 and 5: every iteration adds 2 x policy_episodes episodes of the policy to T_train
    (clean, then noisy), and the next model fit sees them.  Fails when line 29 drops the new data."""
    seen = []                                                # episodes per design at each model fit
    fit = rlil.train_model

    def counting_fit(model, data, *args, **kw):
        seen.append({d: len(t.actions) for d, t in data.items()})
        return fit(model, data, *args, **kw)
    monkeypatch.setattr(rlil, "train_model", counting_fit)
    cfg = smoke(train=("car", "leg_none_wheel"), iters=3, policy_episodes=2)
    run = rlil.algorithm1(cfg, {}, log=quiet)
    grown = [{d: cfg.random_episodes + 2 * cfg.policy_episodes * i for d in ("wnwwnw", "lnwwnl")} for i in range(3)]
    assert seen == grown
    assert {d: len(t.actions) for d, t in run.data.items()} == {d: cfg.random_episodes + 6 * 2 for d in grown[0]}
    clean = run.data["wnwwnw"].actions[cfg.random_episodes:cfg.random_episodes + 2]   # iteration 1's clean episodes
    noisy = run.data["wnwwnw"].actions[cfg.random_episodes + 2:cfg.random_episodes + 4]
    assert not torch.equal(clean, noisy)


def fraction_of_variance_left(model, s, a, s_next, graph) -> float:
    """Held-out one-step error of the state change, per entry over its variance, averaged.
    Predicting no change scores mean(d^2) / var(d) >= 1; a useful model well below 1."""
    with torch.no_grad():
        d, d_hat = s_next - s, model(s, a, graph) - s
    return float(((d_hat - d) ** 2).mean(0).div(d.var(0).clamp_min(1e-12)).mean())


def test_model_fit_beats_predicting_no_change(car_data):
    """Line 5: the fitted car model must leave under half the variance of the state change on
    held-out data that predicting no change leaves (measured about 0.1 of it).  Fails if
    train_model never steps its optimiser or never fits the normalisation."""
    cfg = tiny()
    graph = sim2d.design_graph("car")
    held_out = rlil.collect_random_rollouts("car", cfg, np.random.default_rng(1)).transitions()
    torch.manual_seed(0)
    model = rlil.ModularModel(cfg.gnn)
    loss = rlil.train_model(model, car_data, cfg, np.random.default_rng(0), first=True)
    s, a, _ = car_data["wnwwnw"].transitions()
    torch.testing.assert_close(model.norm_in.wheel.mean, model.inputs(s, a, graph)["wheel"].reshape(-1, 2).mean(0))
    fitted = fraction_of_variance_left(model, *held_out, graph)
    no_change = fraction_of_variance_left(lambda s, a, g: s, *held_out, graph)
    assert fitted < 0.5 * no_change, (fitted, no_change)
    assert loss < 0.5


def test_validation_revert_goes_back_to_the_last_passed_check(monkeypatch, car_data):
    """Sec. III-J: validation rewards 1.0 (phase start), 2.0 (k = 2), 0.5 (k = 4).  The check at
    k = 4 is below the start, so the policy reverts to its parameters at k = 2, not to the
    start, and the learning rate halves; a dip above the start (2.0 then 1.5) reverts nothing."""
    cfg = tiny(policy_steps=4, validate_every=2, update_rate=100, lr_drop=0.5, policy_lr=1e-3)
    model = rlil.ModularModel(cfg.gnn)

    def phase(values):
        rlil.seed_everything(0)
        policy, seen = rlil.ModularPolicy(cfg.gnn), []
        start = {k: v.clone() for k, v in policy.state_dict().items()}

        def fake_validation(p, *args):
            seen.append({k: v.clone() for k, v in p.state_dict().items()})
            return values[len(seen) - 1]
        monkeypatch.setattr(rlil, "validation_reward", fake_validation)
        out = rlil.optimize_policy(policy, model, car_data, {}, 0.0, cfg, np.random.default_rng(0))
        return policy.state_dict(), start, seen, out

    final, start, seen, out = phase([1.0, 2.0, 0.5])
    assert out["reverts"] == 1 and out["lr"] == pytest.approx(0.5e-3) and out["validation_reward"] == 2.0
    assert all(torch.equal(final[k], seen[1][k]) for k in final)               # the k = 2 parameters
    assert not all(torch.equal(final[k], start[k]) for k in final)
    final, start, seen, out = phase([1.0, 2.0, 1.5])
    assert out["reverts"] == 0 and out["lr"] == 1e-3
    assert not all(torch.equal(final[k], seen[1][k]) for k in final)           # kept moving after k = 2


def test_non_finite_loss_never_reaches_the_parameters(monkeypatch, car_data):
    """A NaN reward makes every step's loss NaN: each step reverts (lr halves each time) and the
    parameters stay exactly those of the phase's start."""
    cfg = tiny(policy_steps=3, validate_every=100)
    rlil.seed_everything(0)
    policy, model = rlil.ModularPolicy(cfg.gnn), rlil.ModularModel(cfg.gnn)
    start = {k: v.clone() for k, v in policy.state_dict().items()}
    real = sim2d.reward
    monkeypatch.setattr(rlil.sim2d, "reward", lambda *a: real(*a) * float("nan"))
    out = rlil.optimize_policy(policy, model, car_data, {}, 0.0, cfg, np.random.default_rng(0))
    assert out["reverts"] == 3 and out["lr"] == pytest.approx(cfg.policy_lr / 8)
    assert all(torch.equal(v, start[k]) for k, v in policy.state_dict().items())


class Drifts(torch.nn.Module):
    """A model in which every step moves x forward by 0.1 m, whatever the action."""

    def forward(self, s, a, graph):
        return s + torch.nn.functional.one_hot(torch.tensor(0), s.shape[-1]) * 0.1

    def on_design(self, graph):                             # as gnn.ModularModel.on_design: f(s, a) for roll-outs
        return lambda s, a: self(s, a, graph)


def test_buffer_refresh_overwrites_the_second_half_with_states_T_over_2_steps_on():
    """Lines 23-24: from states at x = 0, T/2 = 5 model steps of +0.1 m put the refreshed half at
    x = 0.5 with the policy's hidden states; the first half is untouched."""
    cfg = tiny(horizon=10, buffer_size=8)
    graph = sim2d.design_graph("car")
    data = rlil.Trajectories("wnwwnw", torch.zeros(2, 5, graph.state_dim), torch.zeros(2, 4, graph.action_dim))
    policy = rlil.ModularPolicy(cfg.gnn)
    buffer = rlil.init_buffer(policy, data, cfg, np.random.default_rng(0))
    buffer.states[:4, 0] = -1.0                                                   # mark the first half
    first = (buffer.states[:4].clone(), buffer.hidden[:, :4].clone())
    rlil.refresh_buffer(buffer, policy, Drifts(), data, cfg, np.random.default_rng(0))
    torch.testing.assert_close(buffer.states[4:, 0], torch.full((4,), 0.5))
    assert (buffer.hidden[:, 4:].abs().sum((0, 2)) > 0).all()
    assert torch.equal(buffer.states[:4], first[0]) and torch.equal(buffer.hidden[:, :4], first[1])


def test_policy_phase_refreshes_the_buffer_every_update_rate_steps(monkeypatch, car_data):
    """Line 22: K = 6 steps with update rate 2 refresh the buffer 3 times."""
    cfg = tiny(policy_steps=6, update_rate=2, validate_every=100)
    calls, real = [], rlil.refresh_buffer
    monkeypatch.setattr(rlil, "refresh_buffer", lambda *a: (calls.append(1), real(*a)))
    rlil.seed_everything(0)
    policy, model = rlil.ModularPolicy(cfg.gnn), rlil.ModularModel(cfg.gnn)
    rlil.optimize_policy(policy, model, car_data, {}, 0.0, cfg, np.random.default_rng(0))
    assert len(calls) == 3


def entropy_on_demos(policy, demos, cfg) -> float:
    with torch.no_grad():
        return rlil.il_loss(policy, demos, cfg, np.random.default_rng(7))[1].item()


def test_entropy_penalty_makes_the_policy_more_certain_on_demo_observations(car_data, hexapod_demos):
    """Sec. III-J: with the entropy penalty on, the policy phase must end with a lower entropy on
    demo observations than the same phase without it (same seeds; measured 7.18 against 7.74
    nats; with the penalty's sign flipped it ends above the run without it)."""
    cfg = tiny(policy_steps=10, validate_every=100)
    model = rlil.ModularModel(cfg.gnn)
    entropies = {}
    for weight in (0.0, 1.0):
        rlil.seed_everything(0)
        policy = rlil.ModularPolicy(cfg.gnn)
        rlil.optimize_policy(policy, model, car_data, hexapod_demos, 1.0, dataclasses.replace(cfg, entropy_weight=weight),
                             np.random.default_rng(0))
        entropies[weight] = entropy_on_demos(policy, hexapod_demos, cfg)
    assert entropies[1.0] < entropies[0.0] - 0.2, entropies


def test_line2_draws_waves_with_random_waves_on_and_the_papers_splines_off():
    """Line 2's actions: the paper's splines of std random_action_std, or with --random-waves the
    sine waves of sim2d.random_wave_actions, from the same generator."""
    graph = sim2d.design_graph("hexapod")
    splines = lambda rng, n, T: sim2d.random_spline_actions(rng, n, graph.action_dim, T, std=0.5)   # noqa: E731
    waves = lambda rng, n, T: sim2d.random_wave_actions(rng, n, graph.action_dim, T)                # noqa: E731
    for on, draw in ((False, splines), (True, waves)):
        cfg = tiny(random_waves=on, random_action_std=0.5)
        data = rlil.collect_random_rollouts("hexapod", cfg, np.random.default_rng(4))
        expected = draw(np.random.default_rng(4), cfg.random_episodes, cfg.episode_steps)
        assert data.actions.shape == expected.shape
        np.testing.assert_allclose(data.actions.numpy(), expected, atol=1e-6)


def test_rlil_loss_is_the_equation():
    """eqn. (RLIL_loss): L = L_RL + lambda L_IL."""
    assert rlil.rlil_loss(torch.tensor(-2.0), torch.tensor(3.0), 0.5).item() == pytest.approx(-0.5)


def test_noisy_policy_rollouts_add_correlated_noise_to_the_clean_policy():
    """Line 28: half the episodes run the policy as it is, half with spline noise of std
    policy_noise_std.  With a policy whose mean action is 0, the clean half applies exactly 0
    and the noisy half applies smooth noise of about that std."""
    cfg = tiny(policy_episodes=8, episode_steps=40, policy_noise_std=0.3)
    policy = rlil.ModularPolicy(cfg.gnn)
    with torch.no_grad():
        for k in ("leg", "wheel"):
            policy.nets[k].head.weight.zero_()
            policy.nets[k].head.bias.zero_()
    data = rlil.collect_policy_rollouts(policy, "leg_none_wheel", cfg, np.random.default_rng(0))
    clean, noisy = data.actions[:8], data.actions[8:]
    assert data.actions.shape == (16, 40, 6) and torch.equal(clean, torch.zeros_like(clean))
    assert 0.15 < noisy.std().item() < 0.45
    assert (noisy.diff(dim=1).abs().mean() < 0.5 * noisy.abs().mean()).item()  # white noise: 1.4 x


def test_il_loss_equals_hand_computation():
    """eqn. (IL_loss) on two (o, a) pairs of two designs: -sum_d mean log N(a; mu(o), sigma(o))."""
    cfg = tiny(il_batch=1, il_window=1)
    torch.manual_seed(0)
    policy = rlil.ModularPolicy(cfg.gnn)

    class Demo:                                  # one episode of one step per design
        def __init__(self, design, rng):
            g = sim2d.design_graph(design)
            s = sim2d.sample_initial_states(g, 1, rng)
            self.obs = {k: v[:, None] for k, v in sim2d.observe(s, g).items()}   # (1, 1, ...)
            self.actions = rng.uniform(-1, 1, (1, 1, g.action_dim))

    rng = np.random.default_rng(0)
    demo = {"llllll": Demo("hexapod", rng), "wnwwnw": Demo("car", rng)}
    loss, _ = rlil.il_loss(policy, demo, cfg, np.random.default_rng(0))
    hand = 0.0
    for design, d in demo.items():
        g = sim2d.design_graph(design)
        obs = {k: torch.as_tensor(v[:, 0], dtype=torch.float32) for k, v in d.obs.items()}
        mean, log_std, _ = policy(obs, g, policy.initial_hidden(1, g))
        a = torch.as_tensor(d.actions[:, 0], dtype=torch.float32)
        var = torch.exp(2 * log_std)
        hand -= (-(a - mean) ** 2 / (2 * var) - log_std - 0.5 * math.log(2 * math.pi)).sum().item()
    assert loss.item() == pytest.approx(hand, rel=1e-5)


def test_model_bias_compares_model_and_simulator_progress():
    """model_bias rolls the policy out T steps in the model from the evaluation starts, reads
    the simulator's progress over the same T steps, and replays the simulator's actions in
    the model (0.1 m per step against the simulator's 0.05)."""
    cfg = tiny(horizon=4, eval_steps=20)
    graph = sim2d.design_graph("car")
    states = np.zeros((3, cfg.eval_steps + 1, graph.state_dim))
    states[..., 0] = 0.05 * np.arange(cfg.eval_steps + 1)                    # 0.05 m per step
    run = sim2d.Episodes("wnwwnw", states, {}, np.zeros((3, cfg.eval_steps, graph.action_dim)), np.zeros(3, bool))
    bias = rlil.model_bias(rlil.ModularPolicy(cfg.gnn), Drifts(), "car", run, cfg)
    assert bias == pytest.approx({"model_progress_m": 0.4, "sim_progress_m": 0.2, "model_path_error_m": 0.2})


# ----------------------------------------------------------------------------
# Runs: outputs, resume, seeding, the in-memory loop, non-finite metrics
# ----------------------------------------------------------------------------
def test_tiny_run_writes_every_output_and_decays_lambda(tmp_path, cache):
    cfg = smoke(train=("leg_none_wheel",), demos=("hexapod", "car"), il_weight=0.4, il_decay=0.5)
    metrics = train.run(cfg, tmp_path, log=quiet, cache_dir=cache)
    for name in run_folders.OUTPUTS:
        assert (tmp_path / name).stat().st_size > 0, name
    saved = json.loads((tmp_path / "metrics.json").read_text())
    config = saved["config"]
    assert config["train"] == ["lnwwnl"] and config["demos"] == ["llllll", "wnwwnw"] and config["threads"] == 1
    assert set(config["versions"]) >= {"torch", "numpy", "pymunk"} and config["versions"]["torch"] == torch.__version__
    assert config["versions"]["cpu_capability"] == torch.backends.cpu.get_cpu_capability()
    assert [row["iteration"] for row in saved["iterations"]] == [0, 1, 2]
    assert [m["il_weight"] for m in metrics] == pytest.approx([0.4, 0.4, 0.2])   # lambda used, then halved
    for row in saved["iterations"]:
        assert row["distance_min_m"] <= row["distance_m"] <= row["distance_max_m"]
    for row in saved["iterations"][1:]:                  # model vs simulator, once there is a model
        assert math.isfinite(row["model_progress_m"]) and math.isfinite(row["sim_progress_m"])
        assert math.isfinite(row["il_loss"]) and math.isfinite(row["model_loss"])
    assert (tmp_path / "metrics.csv").read_text().splitlines()[0].startswith("iteration,distance_m")
    policy = torch.load(tmp_path / "policy.pt", weights_only=False)
    assert policy["config"]["seed"] == 0 and policy["iteration"] == 2


def test_existing_run_is_not_overwritten(tmp_path, cache):
    cfg = smoke(train=("car",), iters=1)
    train.run(cfg, tmp_path, log=quiet, cache_dir=cache)
    before = (tmp_path / "metrics.json").read_bytes()
    with pytest.raises(run_folders.UsageError, match="--resume"):
        train.run(cfg, tmp_path, log=quiet, cache_dir=cache)
    assert (tmp_path / "metrics.json").read_bytes() == before


def test_resumed_run_ends_where_an_uninterrupted_one_does(tmp_path, cache):
    cfg = smoke(train=("leg_none_wheel",), demos=("car",), iters=2)
    whole = train.run(cfg, tmp_path / "whole", log=quiet, cache_dir=cache)
    train.run(dataclasses.replace(cfg, iters=1), tmp_path / "split", log=quiet, cache_dir=cache)
    resumed = train.run(cfg, tmp_path / "split", resume=True, log=quiet, cache_dir=cache)
    assert strip_times(resumed) == strip_times(whole)


def test_same_seed_same_metrics_other_seed_differs(tmp_path, cache):
    cfg = smoke(train=("car",), iters=1)
    a = train.run(cfg, tmp_path / "a", log=quiet, cache_dir=cache)
    b = train.run(cfg, tmp_path / "b", log=quiet, cache_dir=cache)
    c = train.run(dataclasses.replace(cfg, seed=1), tmp_path / "c", log=quiet, cache_dir=cache)
    assert strip_times(a) == strip_times(b)
    assert strip_times(a) != strip_times(c)


def test_algorithm1_in_memory_matches_the_command_line_run(tmp_path, cache):
    cfg = smoke(train=("lnwwnl",), demos=("wnwwnw",), iters=1)
    run = rlil.algorithm1(cfg, rlil.load_demos(cfg, cache), log=quiet)
    on_disk = train.run(cfg, tmp_path, log=quiet, cache_dir=cache)
    assert strip_times(run.metrics) == strip_times(on_disk)
    assert run.iteration == 1 and run.il_weight == pytest.approx(cfg.il_weight * cfg.il_decay)


def test_non_finite_metrics_are_logged_and_stored_as_null(tmp_path, cache, monkeypatch):
    """A NaN model loss must not pass silently: a warning line, and null in metrics.json."""
    monkeypatch.setattr(rlil, "train_model", lambda *a, **k: float("nan"))
    lines = []
    train.run(smoke(train=("car",), iters=1), tmp_path, log=lines.append, cache_dir=cache)
    assert any("WARNING" in line and "model_loss" in line for line in lines)
    assert json.loads((tmp_path / "metrics.json").read_text())["iterations"][1]["model_loss"] is None


# ----------------------------------------------------------------------------
# The command line
# ----------------------------------------------------------------------------
def run_cli(*args):
    return subprocess.run([sys.executable, "train.py", *args], capture_output=True, text=True)


def test_every_config_field_is_a_flag_with_help_and_round_trips():
    parser = train.build_parser()
    helps = {a.dest: a.help for a in parser._actions}
    for _, dest, f in run_folders.config_flags():
        assert helps[dest] and not helps[dest].startswith(" ("), dest
    cfg = tiny(train=("llwwll",), demos=("hexapod", "car"), seed=3, il_weight=2.5)
    args = parser.parse_args(run_folders.config_args(cfg) + ["--preset", "default"])
    assert train.config_from_args(args) == rlil.validate_config(cfg)


def test_cli_bad_input_exit_2_one_line_and_nothing_left_behind(tmp_path, capsys):
    out = run_cli("--train", "car", "--demos", "lnnnnl", "--out", str(tmp_path / "new"))   # the real process
    assert out.returncode == 2 and out.stderr.count("\n") == 1 and "cannot be demonstrated" in out.stderr
    assert not (tmp_path / "new").exists()
    for args in (["--train", "spider"], ["--train", "nnnnnn"], ["--train", "car", "--iters", "0"],
                 ["--train", "car", "--policy-steps", "-3"], ["--train", "car", "--preset", "huge"],
                 ["--train", "car", "--lr-drop", "2"], ["--train", "car", "--seed", "x"],
                 ["--figure3", "--seeds", "0"], ["--eval", str(tmp_path), "--design", "car"],
                 ["--train", "car", "--resume", "--out", str(tmp_path)],
                 ["--train", "car", "--demos", "lnnnnl", "--out", str(tmp_path / "new")],
                 ["--train", "car", "car"], ["--train", "car", "--demos", "hexapod", "hexapod"],
                 ["--train", "car", "--horizon", "1000000000"], ["--train", "car", "--batch", "100000"],
                 ["--train", "car", "--out", "/proc/forbidden/x"]):
        with pytest.raises(SystemExit) as exit_:
            train.main(args)
        err = capsys.readouterr().err
        assert exit_.value.code == 2 and err.count("\n") == 1 and "Traceback" not in err, (args, err)
    assert not (tmp_path / "new").exists()
    (tmp_path / "a_file").write_text("mine")
    with pytest.raises(SystemExit):
        train.main(["--train", "car", "--out", str(tmp_path / "a_file")])
    assert "is a file" in capsys.readouterr().err and (tmp_path / "a_file").read_text() == "mine"
    (tmp_path / "policy.pt").write_bytes(b"not a checkpoint")
    with pytest.raises(SystemExit):
        train.main(["--eval", str(tmp_path), "--design", "car"])
    assert "corrupt" in capsys.readouterr().err


def test_a_run_failing_before_its_first_checkpoint_leaves_no_directory(tmp_path, cache, monkeypatch):
    monkeypatch.setattr(rlil, "collect_random_rollouts", lambda *a: 1 / 0)
    with pytest.raises(ZeroDivisionError):
        train.run(tiny(train=("car",)), tmp_path / "run", log=quiet, cache_dir=cache)
    assert not (tmp_path / "run").exists()


def test_every_iteration_is_evaluated_from_the_same_starts_and_seeds_differ(monkeypatch):
    """Sec. IV's figure compares iterations: the same perturbed starts at every iteration (and in
    --eval), another set for another seed, and none of the training data's seeds."""
    seeds = []
    episodes = sim2d.Episodes("wnwwnw", np.zeros((1, 2, 8)), {}, np.zeros((1, 1, 4)), np.zeros(1, bool))
    monkeypatch.setattr(rlil, "evaluate_policy", lambda policy, design, cfg, seed: seeds.append(seed) or episodes)
    monkeypatch.setattr(rlil, "model_bias", lambda *a: {"model_progress_m": 0.0})
    cfg = smoke(train=("car",))
    for i in range(3):
        rlil.evaluate_iteration(None, None, ["car"], cfg, i)
    assert seeds == [rlil.eval_seed(cfg)] * 3
    assert rlil.eval_seed(dataclasses.replace(cfg, seed=1)) != seeds[0]


def test_the_metrics_row_counts_the_evaluated_starts_that_flipped_and_the_log_says_so(monkeypatch):
    """A robot that flips and drives on its back still adds its progress to the distance (Sec. IV's
    metric as written); the row says how many of the starts did, summed over the training designs."""
    def episodes(flipped):
        return sim2d.Episodes("wnwwnw", np.zeros((3, 2, 8)), {}, np.zeros((3, 1, 4)), np.array(flipped))
    runs = {"wnwwnw": episodes([True, False, True]), "lnwwnl": episodes([False, False, True])}
    monkeypatch.setattr(rlil, "evaluate_policy", lambda policy, design, cfg, seed: runs[design])
    row = rlil.evaluate_iteration(None, None, ["wnwwnw", "lnwwnl"], smoke(train=("car",)), 0)
    assert row["flipped"] == 3 and isinstance(row["flipped"], int)
    assert rlil.flips(row, 6) == ", 3 of 6 starts flipped" and rlil.flips({**row, "flipped": 0}, 6) == ""


def test_cli_eval_zero_shot(tmp_path, cache):
    train.run(smoke(train=("car",), iters=1), tmp_path, log=quiet, cache_dir=cache)
    out = subprocess.run([sys.executable, "train.py", "--eval", str(tmp_path), "--design", "lwnnwl"],
                         capture_output=True, text=True, check=True)
    assert np.isfinite(float(out.stdout.strip().splitlines()[-1].split("distance_m=")[1]))
    png = tmp_path / "mine.png"                                  # a user's file is never overwritten
    png.write_bytes(b"keep")
    with pytest.raises(SystemExit) as exit_:
        train.main(["--eval", str(tmp_path), "--design", "car", "--png", str(png)])
    assert exit_.value.code == 2
    assert png.read_bytes() == b"keep"


# ----------------------------------------------------------------------------
# Figure 3
# ----------------------------------------------------------------------------
def fake_sweep(tmp_path, skip=()):
    """Finished runs of a 2-seed, 1-iteration sweep (distance grows with RL+IL), but `skip`; the base
    config has 2 torch threads (not the default 1), so the sweep's thread rule shows in its runs."""
    base = tiny(iters=1, threads=2)
    runs = sweeps.figure3_runs(tmp_path, base, seeds=2, jobs=2)
    for k, r in enumerate(runs):
        r["dir"].mkdir(parents=True)
        iterations = range(1 if k in skip else 2)
        rows = [{"iteration": i, "distance_m": float(i + k + (10 if r["method"] == "RL+IL" else 0))}
                for i in iterations]
        (r["dir"] / "metrics.json").write_text(json.dumps({"config": dataclasses.asdict(r["cfg"]), "iterations": rows}))
    return base, runs


def test_figure3_reuses_finished_runs_and_writes_plot_and_csv(tmp_path):
    """A sweep whose runs are all finished launches nothing and tabulates every run."""
    base, runs = fake_sweep(tmp_path)
    assert len(runs) == 4 * 2 * 2 and len({r["dir"] for r in runs}) == 16
    # what each run's train.py gets from its arguments (a field equal to the default is not passed):
    # one torch thread when runs share the machine, the base config's 2 when they run one at a time
    received = lambda r: train.config_from_args(train.build_parser().parse_args(r["args"]))   # noqa: E731
    assert [received(r).threads for r in runs] == [1] * len(runs)
    alone = sweeps.figure3_runs(tmp_path, base, seeds=2, jobs=1)
    assert [received(r).threads for r in alone] == [2] * len(runs)
    assert [r["dir"] for r in alone] == [r["dir"] for r in runs]        # same runs, whatever --jobs
    assert [dataclasses.replace(received(r), threads=1) for r in alone] == [received(r) for r in runs]
    assert sweeps.figure3(tmp_path, base, seeds=2, jobs=2, log=quiet) == []
    lines = (tmp_path / "figure3.csv").read_text().splitlines()
    assert lines[0] == ("panel,train,demos,method,seed,iteration,distance_m,model_progress_m,sim_progress_m,"
                        "seconds,cpu_capability")
    assert len(lines) == 1 + 16 * 2
    assert "a,hexapod,hexapod,RL+IL,0,0,10.0,,,," in lines and "d,leg_none_wheel,hexapod+car,RL,1,1," in "\n".join(lines)
    assert not any((r["dir"] / "train.log").exists() for r in runs)    # nothing was run again
    assert (tmp_path / "figure3.png").stat().st_size > 10_000
    table = (tmp_path / "figure3.md").read_text()
    assert "| (b) car (car demos) | RL+IL | 2 of 2 | 0, 0 |" in table   # RL+IL starts at 14 m, above 90 % of 15.5
    assert "| (a) hexapod (hexapod demos) | RL | 2 of 2 | never, never |" in table


def test_figure3_names_a_failed_run_and_fails(tmp_path, monkeypatch):
    """A run that stops short is named in the summary and the plot, and the sweep reports failure
    (the command line exits 1); the other seed's final still counts, and only it."""
    base, runs = fake_sweep(tmp_path, skip={1})              # (a) RL+IL seed 1 has iteration 0 only
    monkeypatch.setattr(sweeps, "run_one", lambda cmd, run_dir: 1)
    problems = sweeps.figure3(tmp_path, base, seeds=2, jobs=2, log=quiet)
    assert len(problems) == 1 and "(a) RL+IL seed 1" in problems[0] and "exit status 1" in problems[0]
    table = (tmp_path / "figure3.md").read_text()
    assert "| (a) hexapod (hexapod demos) | RL+IL | 1 of 2 |" in table and "(a) RL+IL seed 1" in table
    assert "| 11.00 [11.00, 11.00] | 11.00 - 11.00 |" in table       # seed 0's final alone


# ----------------------------------------------------------------------------
# Not in the paper: the clone's data, the improvement check; switches that left the code
# (each a switch, off = the paper)
# ----------------------------------------------------------------------------
def test_a_run_written_before_a_removal_loads_only_if_it_left_the_removed_switch_off():
    """Committed runs recorded settings that have since left the code (run_folders.REMOVED_AT_OFF): at
    their off value the run used today's algorithm and loads; switched on, it is refused by name."""
    d = json.loads(json.dumps(run_folders.config_to_dict(rlil.Config())))
    old = {**d, "ensemble": 1, "held_out_models": 0, "trust_region": 0.0, "critic": False,
           "critic_gamma": 0.99, "critic_lambda": 0.95, "critic_steps": 4, "random_wave_share": 1.0,
           "wheel_splines": False, "random_wave_offset": 0.0, "bc_lr": 1e-3,
           "random_knots": 10, "recent_data": 0.0, "improvement_tries": 1,
           "gnn": {**d["gnn"], "contact_features": False}}
    assert run_folders.config_from_dict(old) == rlil.Config()
    for changed, name in (({"gnn": {**d["gnn"], "contact_features": True}}, "gnn.contact_features"),
                          ({"ensemble": 3}, "ensemble"), ({"critic": True, "critic_gamma": 0.99}, "critic"),
                          ({"random_waves": True, "random_wave_share": 0.5}, "random_wave_share"),
                          ({"random_waves": True, "wheel_splines": True}, "wheel_splines"),
                          ({"random_waves": True, "random_wave_offset": 1.0}, "random_wave_offset"),
                          ({"bc_lr": 2e-3}, "bc_lr"), ({"random_knots": 5}, "random_knots"),
                          ({"recent_data": 0.5}, "recent_data"), ({"improvement_tries": 3}, "improvement_tries")):
        with pytest.raises(run_folders.UsageError, match=name):
            run_folders.config_from_dict({**d, **changed})


def test_clone_data_adds_the_clones_rollouts_before_the_first_model_fit(monkeypatch, hexapod_demos):
    """--clone-data: the first model fit sees the random episodes plus 2 x policy_episodes episodes
    of the cloned policy (noiseless, then noisy), counted in sim_steps, and the clone's return on
    its noiseless ones becomes the reference of the improvement check; without demos it does
    nothing.  Fails when `add_clone_rollouts` is skipped."""
    seen, at_0 = [], []
    fit = rlil.train_model

    def counting_fit(model, data, *args, **kw):
        seen.append(len(data["wnwwnw"].actions))
        return fit(model, data, *args, **kw)
    monkeypatch.setattr(rlil, "train_model", counting_fit)
    cfg = smoke(train=("car",), demos=("hexapod",), iters=1, policy_episodes=2, clone_data=True)
    run = rlil.algorithm1(cfg, hexapod_demos, log=quiet,
                          on_iteration=lambda r: at_0.append(r.kept_return) if r.iteration == 0 else None)
    n = cfg.random_episodes
    assert seen == [n + 2 * cfg.policy_episodes]
    clone = rlil.Trajectories("wnwwnw", run.data["wnwwnw"].states[n:n + 4], run.data["wnwwnw"].actions[n:n + 4])
    assert at_0 == [pytest.approx(rlil.policy_return({"wnwwnw": clone}, cfg))]
    steps = rlil.sim_steps(dataclasses.replace(cfg, clone_data=False), 0)
    assert run.metrics[0]["sim_steps"] == steps + 2 * cfg.policy_episodes * cfg.episode_steps
    seen.clear()
    rlil.algorithm1(dataclasses.replace(cfg, demos=()), {}, log=quiet)    # plain RL: no clone to run
    assert seen == [n]


def test_improvement_check_keeps_the_previous_policy_when_the_new_one_returns_less(car_data):
    """--keep-better: the new policy stays when its noiseless return is at least the kept one's
    minus the margin (and becomes the reference); otherwise the previous weights come back and
    the reference stays.  `policy_return` is the mean over the noiseless episodes of the summed
    reward.  Fails when the check keeps every policy."""
    cfg = tiny(policy_episodes=3)
    traj = car_data["wnwwnw"]
    by_hand = np.mean([sum(float(sim2d.reward(traj.states[e, t], traj.actions[e, t], traj.states[e, t + 1],
                                              sim2d.design_graph("car"))) for t in range(cfg.episode_steps))
                       for e in range(3)])
    value = rlil.policy_return(car_data, cfg)
    assert value == pytest.approx(by_hand, rel=1e-4, abs=1e-4)
    rlil.seed_everything(0)
    previous = rlil.ModularPolicy(cfg.gnn).state_dict()
    for kept, margin, expect_keep in ((value + 1, 0.0, False), (value + 1, 2.0, True), (value - 1, 0.0, True),
                                      (None, 0.0, True)):
        rlil.seed_everything(1)
        policy = rlil.ModularPolicy(cfg.gnn)
        new = copy.deepcopy(policy.state_dict())
        run = rlil.Run(cfg, policy, None, {}, 0.0, np.random.default_rng(0), kept_return=kept)
        out = rlil.improvement_check(policy, previous, car_data, run,
                                     dataclasses.replace(cfg, improvement_margin=margin))
        assert out == {"policy_return": value, "kept_new": expect_keep}
        weights = previous if not expect_keep else new
        assert all(torch.equal(policy.state_dict()[k], weights[k]) for k in weights)
        assert run.kept_return == (value if expect_keep else kept)


def test_phase_tries_keep_the_try_that_returns_most_and_add_only_its_rollouts(monkeypatch):
    """--phase-tries 3 inside Algorithm 1: each try starts from the same policy (a phase here adds
    its try's number to every parameter), the one whose noiseless roll-outs return most is kept
    (scripted returns 1, 5, 2: the second), only its roll-outs join T_train, and sim_steps counts
    every try's collection.  Fails if the best try is not the one kept, if a try starts from the
    previous try's policy, or if every try's data is added."""
    returns, calls = iter([1.0, 5.0, 2.0]), []

    def phase(policy, *args):
        calls.append(1)
        with torch.no_grad():
            for p in policy.parameters():
                p.add_(float(len(calls)))
        return {"rl_loss": 0.0, "il_loss": None, "validation_reward": 0.0, "reverts": 0, "lr": 1e-3}
    monkeypatch.setattr(rlil, "optimize_policy", phase)
    monkeypatch.setattr(rlil, "policy_return", lambda new_data, cfg: next(returns))
    cfg = smoke(train=("car",), iters=1, policy_episodes=2, phase_tries=3, keep_better=False)
    start = []
    run = rlil.algorithm1(cfg, {}, log=quiet, on_iteration=lambda r: start.append(copy.deepcopy(r.policy.state_dict())))
    assert all(torch.allclose(start[1][k], start[0][k] + 2.0) for k in start[0] if start[0][k].is_floating_point())
    assert run.metrics[1]["try_returns"] == [1.0, 5.0, 2.0]
    assert len(run.data["wnwwnw"].actions) == cfg.random_episodes + 2 * cfg.policy_episodes
    assert run.metrics[1]["sim_steps"] - run.metrics[0]["sim_steps"] == 3 * 2 * cfg.policy_episodes * cfg.episode_steps


def test_algorithm1_with_keep_better_continues_from_the_kept_policy(tmp_path, monkeypatch):
    """Inside Algorithm 1: an iteration whose policy returns less ends with the policy it started
    from (its data still added to T_train), the next phase starts there, and a checkpoint keeps
    the reference.  The returns are scripted: 1, then 0 (rejected), then 2."""
    returns = iter([1.0, 0.0, 2.0])
    monkeypatch.setattr(rlil, "policy_return", lambda new_data, cfg: next(returns))
    cfg = smoke(train=("car",), iters=3, policy_episodes=2, keep_better=True)
    policies = []
    run = rlil.algorithm1(cfg, {}, log=quiet, on_iteration=lambda r: policies.append(copy.deepcopy(r.policy.state_dict())))
    assert [row.get("kept_new") for row in run.metrics] == [None, True, False, True]
    assert all(torch.equal(policies[2][k], policies[1][k]) for k in policies[1])
    assert not all(torch.equal(policies[3][k], policies[2][k]) for k in policies[2])
    assert len(run.data["wnwwnw"].actions) == cfg.random_episodes + 3 * 2 * cfg.policy_episodes
    assert run.kept_return == 2.0
    run_folders.save_checkpoint(tmp_path, run)
    path = tmp_path / "checkpoint.pt"
    assert run_folders.restore_run(run_folders.load_checkpoint(path), cfg, path).kept_return == 2.0
