"""Tests of Algorithm 1 (modular_rlil_minimal.py) and its command line (train.py), at tiny budgets."""
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
from gnn import GNNConfig

TINY = dict(random_episodes=4, episode_steps=20, policy_episodes=2, demo_episodes=4, demo_steps=20,
            bc_steps=2, model_steps=5, finetune_steps=3, model_batch=64, policy_steps=4, horizon=4, batch=8,
            buffer_size=16, update_rate=2, validate_every=2, validation_multiple=2, il_batch=4, il_window=4,
            eval_episodes=2, eval_steps=20, iters=2, gnn=GNNConfig(hidden=16))


def tiny(**kw) -> rlil.Config:
    return rlil.Config(**{**TINY, **kw})


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    return tmp_path_factory.mktemp("demo_cache")


def quiet(*args, **kw):
    pass


def strip_times(metrics):
    return [{k: v for k, v in row.items() if k != "seconds"} for row in metrics]


def test_tiny_run_writes_every_output(tmp_path, cache):
    cfg = tiny(train=("leg_none_wheel",), demos=("hexapod", "car"))
    metrics = train.train(cfg, tmp_path, log=quiet, cache_dir=cache)
    for name in train.OUTPUTS:
        assert (tmp_path / name).stat().st_size > 0, name
    saved = json.loads((tmp_path / "metrics.json").read_text())
    assert saved["config"]["train"] == ["lnwwnl"] and saved["config"]["demos"] == ["llllll", "wnwwnw"]
    assert [row["iteration"] for row in saved["iterations"]] == [0, 1, 2]
    for row in saved["iterations"]:
        assert row["distance_min_m"] <= row["distance_m"] <= row["distance_max_m"]
        for key in ("il_weight", "model_loss", "seconds"):
            assert key in row
    for row in saved["iterations"][1:]:                  # model vs simulator, once there is a model
        assert math.isfinite(row["model_progress_m"]) and math.isfinite(row["sim_progress_m"])
    assert (tmp_path / "metrics.csv").read_text().splitlines()[0].startswith("iteration,distance_m")
    assert len(metrics) == 3
    policy = torch.load(tmp_path / "policy.pt", weights_only=False)
    assert policy["config"]["seed"] == 0 and policy["iteration"] == 2


def test_existing_run_is_not_overwritten(tmp_path, cache):
    cfg = tiny(train=("car",), iters=1)
    train.train(cfg, tmp_path, log=quiet, cache_dir=cache)
    before = (tmp_path / "metrics.json").read_bytes()
    with pytest.raises(train.UsageError, match="--resume"):
        train.train(cfg, tmp_path, log=quiet, cache_dir=cache)
    assert (tmp_path / "metrics.json").read_bytes() == before


def test_resumed_run_ends_where_an_uninterrupted_one_does(tmp_path, cache):
    cfg = tiny(train=("leg_none_wheel",), demos=("car",), iters=2)
    whole = train.train(cfg, tmp_path / "whole", log=quiet, cache_dir=cache)
    train.train(dataclasses.replace(cfg, iters=1), tmp_path / "split", log=quiet, cache_dir=cache)
    resumed = train.train(cfg, tmp_path / "split", resume=True, log=quiet, cache_dir=cache)
    assert strip_times(resumed) == strip_times(whole)


def test_same_seed_same_metrics_other_seed_differs(tmp_path, cache):
    cfg = tiny(train=("car",), iters=1)
    a = train.train(cfg, tmp_path / "a", log=quiet, cache_dir=cache)
    b = train.train(cfg, tmp_path / "b", log=quiet, cache_dir=cache)
    c = train.train(dataclasses.replace(cfg, seed=1), tmp_path / "c", log=quiet, cache_dir=cache)
    assert strip_times(a) == strip_times(b)
    assert strip_times(a) != strip_times(c)


def test_each_phase_runs_alone(cache):
    cfg = tiny()
    rng = rlil.seed_everything(0)
    data = {"lnwwnl": rlil.collect_random_rollouts("lnwwnl", cfg, rng)}             # line 2
    assert data["lnwwnl"].states.shape == (4, 21, 16) and data["lnwwnl"].actions.shape == (4, 20, 6)
    policy, model = rlil.ModularPolicy(cfg.gnn), rlil.ModularModel(cfg.gnn)
    demo = rlil.load_demos(dataclasses.replace(cfg, demos=("hexapod",)), cache)
    assert np.isfinite(rlil.pretrain_bc(policy, demo, cfg, rng))                      # line 1
    model.fit_normalization([(sim2d.design_graph("lnwwnl"), *data["lnwwnl"].transitions())])
    assert np.isfinite(rlil.train_model(model, data, cfg, 5, rng))                    # line 5
    out = rlil.optimize_policy(policy, model, data, demo, 0.1, cfg, rng)              # lines 7-26
    assert np.isfinite(out["rl_loss"]) and np.isfinite(out["il_loss"])
    new = rlil.collect_policy_rollouts(policy, "lnwwnl", cfg, rng)                    # lines 28-29
    assert new.actions.shape == (2 * cfg.policy_episodes, 20, 6)
    assert rlil.decay_il_weight(0.4, cfg) == pytest.approx(0.4 * cfg.il_decay)        # line 30


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


def test_il_weight_decays(tmp_path, cache):
    cfg = tiny(train=("car",), demos=("car",), iters=2, il_weight=0.4, il_decay=0.5)
    metrics = train.train(cfg, tmp_path, log=quiet, cache_dir=cache)
    assert [m["il_weight"] for m in metrics[1:]] == pytest.approx([0.4, 0.2])
    rl_only = train.train(tiny(train=("car",), iters=1), tmp_path / "rl", log=quiet, cache_dir=cache)
    assert rl_only[1]["il_weight"] == 0.0


def validated_phase(monkeypatch, values, policy_steps):
    """optimize_policy with validation rewards `values` (the phase's start, then each check)."""
    cfg = tiny(policy_steps=policy_steps, validate_every=2, lr_drop=0.5, policy_lr=1e-3)
    rng = rlil.seed_everything(0)
    data = {"wnwwnw": rlil.collect_random_rollouts("wnwwnw", cfg, rng)}
    policy, model = rlil.ModularPolicy(cfg.gnn), rlil.ModularModel(cfg.gnn)
    values = iter(values)
    monkeypatch.setattr(rlil, "validation_reward", lambda *a, **k: next(values))
    start = {k: v.clone() for k, v in policy.state_dict().items()}
    return policy, start, rlil.optimize_policy(policy, model, data, {}, 0.0, cfg, rng)


def test_adaptive_learning_rate_reverts_below_the_phase_start(monkeypatch):
    policy, start, out = validated_phase(monkeypatch, [1.0, 0.5, 0.25], policy_steps=4)
    assert out["reverts"] == 2 and out["lr"] == pytest.approx(1e-3 * 0.25)
    for k, v in policy.state_dict().items():     # reverted twice, to the start
        assert torch.equal(v, start[k]), k


def test_adaptive_learning_rate_keeps_a_dip_above_the_phase_start(monkeypatch):
    """Sec. III-J compares with the phase's start: 2.0 then 1.5 is worse than the last check
    but better than the start (1.0), so nothing reverts; 0.5 reverts to the last check."""
    policy, start, out = validated_phase(monkeypatch, [1.0, 2.0, 1.5], policy_steps=4)
    assert out["reverts"] == 0 and out["lr"] == 1e-3
    assert not all(torch.equal(v, start[k]) for k, v in policy.state_dict().items())
    _, _, out = validated_phase(monkeypatch, [1.0, 2.0, 0.5], policy_steps=4)
    assert out["reverts"] == 1 and out["validation_reward"] == 2.0


def test_non_finite_loss_is_reverted(monkeypatch):
    cfg = tiny(policy_steps=2, validate_every=100)
    rng = rlil.seed_everything(0)
    data = {"wnwwnw": rlil.collect_random_rollouts("wnwwnw", cfg, rng)}
    policy, model = rlil.ModularPolicy(cfg.gnn), rlil.ModularModel(cfg.gnn)
    real = sim2d.reward
    monkeypatch.setattr(rlil.sim2d, "reward", lambda *a: real(*a) * float("nan"))
    out = rlil.optimize_policy(policy, model, data, {}, 0.0, cfg, rng)
    assert out["reverts"] == 2
    assert all(torch.isfinite(p).all() for p in policy.parameters())


def test_cli_bad_input_exit_2(tmp_path):
    def run(*args):
        return subprocess.run([sys.executable, "train.py", *args], capture_output=True, text=True)
    for args in (["--train", "spider"], ["--train", "nnnnnn"], ["--train", "car", "--iters", "0"],
                 ["--eval", str(tmp_path), "--design", "car"], ["--train", "car", "--resume", "--out", str(tmp_path)]):
        out = run(*args)
        assert out.returncode == 2 and out.stderr.count("\n") == 1 and "Traceback" not in out.stderr, args
    (tmp_path / "a_file").write_text("mine")
    out = run("--train", "car", "--out", str(tmp_path / "a_file"))
    assert out.returncode == 2 and "is a file" in out.stderr and (tmp_path / "a_file").read_text() == "mine"
    (tmp_path / "policy.pt").write_bytes(b"not a checkpoint")
    out = run("--eval", str(tmp_path), "--design", "car")
    assert out.returncode == 2 and "corrupt" in out.stderr


def test_cli_eval_zero_shot(tmp_path, cache):
    train.train(tiny(train=("car",), iters=1), tmp_path, log=quiet, cache_dir=cache)
    out = subprocess.run([sys.executable, "train.py", "--eval", str(tmp_path), "--design", "lwnnwl"],
                         capture_output=True, text=True, check=True)
    assert np.isfinite(float(out.stdout.strip().splitlines()[-1].split("distance_m=")[1]))


def test_figure3_reuses_finished_runs_and_writes_plot_and_csv(tmp_path):
    """A sweep whose runs are all finished launches nothing and tabulates every run."""
    runs = train.figure3_runs(tmp_path, seeds=2, iters=1)
    assert len(runs) == 4 * 2 * 2 and len({r["dir"] for r in runs}) == 16
    for k, r in enumerate(runs):                 # fake finished runs: distance grows with RL+IL
        r["dir"].mkdir(parents=True)
        rows = [{"iteration": i, "distance_m": float(i + k + (10 if r["method"] == "RL+IL" else 0))}
                for i in range(2)]
        (r["dir"] / "metrics.json").write_text(json.dumps({"config": {}, "iterations": rows}))
    train.figure3(tmp_path, seeds=2, iters=1, jobs=2, log=quiet)
    lines = (tmp_path / "figure3.csv").read_text().splitlines()
    assert lines[0] == "panel,train,demos,method,seed,iteration,distance_m"
    assert len(lines) == 1 + 16 * 2
    assert "a,hexapod,hexapod,RL+IL,0,0,10.0" in lines and "d,leg_none_wheel,hexapod+car,RL,1,1," in "\n".join(lines)
    assert not any((r["dir"] / "train.log").exists() for r in runs)    # nothing was run again
    assert (tmp_path / "figure3.png").stat().st_size > 10_000
    table = (tmp_path / "figure3.md").read_text()
    assert "| (a) hexapod (hexapod demos) | RL+IL | 0 |" in table     # RL+IL starts at 10 m, above 90 %
    assert "| (a) hexapod (hexapod demos) | RL | not converged |" in table


def test_algorithm1_in_memory_matches_the_command_line_run(tmp_path, cache):
    cfg = tiny(train=("lnwwnl",), demos=("wnwwnw",), iters=1)
    state = rlil.algorithm1(cfg, log=quiet, cache_dir=cache)
    on_disk = train.train(cfg, tmp_path, log=quiet, cache_dir=cache)
    assert strip_times(state.metrics) == strip_times(on_disk)
    assert state.iteration == 1 and state.il_weight == pytest.approx(cfg.il_weight * cfg.il_decay)


def test_model_bias_compares_model_and_simulator_progress():
    """model_bias rolls the policy out T steps in the model from the evaluation starts and
    reads the simulator's progress over the same T steps."""
    cfg = tiny(horizon=4)
    graph = sim2d.design_graph("car")

    class Drifts(torch.nn.Module):            # a model in which every action moves x by 0.1 m
        def forward(self, s, a, graph):
            return s + torch.nn.functional.one_hot(torch.tensor(0), s.shape[-1]) * 0.1

    sim_states = np.zeros((cfg.eval_steps + 1, 3, graph.state_dim))
    sim_states[..., 0] = 0.05 * np.arange(cfg.eval_steps + 1)[:, None]                # 0.05 m per step
    model_m, sim_m = rlil.model_bias(rlil.ModularPolicy(cfg.gnn), Drifts(), "car", sim_states, cfg)
    assert model_m == pytest.approx(0.4) and sim_m == pytest.approx(0.2)
