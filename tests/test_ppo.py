"""Tests of the PPO baseline (ppo_minimal.py), its command line and the sample-efficiency sweep.

PPO must learn at the tiny budget (the car must drive), its equations must be
the ones the docstrings write (GAE, the clipped surrogate, the return scale),
and its runs must behave like Algorithm 1's on the command line (outputs,
resume, evaluation, bad input).  PPO+IL (--demos, after DAPG) must clone the demos first,
keep imitating them while lambda decays, and be plain PPO bit for bit at lambda = 0.
"""
import copy
import dataclasses
import json
import subprocess
import sys

import numpy as np
import pytest
import torch

import gnn
import modular_rlil_minimal as rlil
import ppo_minimal as ppo
import sim2d
import train
from experiments import run_folders, sweeps


def tiny(**kw) -> ppo.PPOConfig:
    return ppo.preset("tiny", **kw)


def quiet(*args, **kw):
    pass


def strip_times(metrics):
    return [{k: v for k, v in row.items() if k != "seconds"} for row in metrics]


# ----------------------------------------------------------------------------
# Learning
# ----------------------------------------------------------------------------
def test_ppo_teaches_the_car_to_drive():
    """The tiny preset on the car: from under 4 m (the untrained policy drives 2.8 m) to at least
    7 m in 100 steps (measured 9.5 m; wheel top speed 9.9 m).  It took about 10 s on the idle
    2-core machine (issue #13 asks for <= 20 s); the time is measured, never asserted (shared
    machines are noisy).  Fails with the policy-gradient sign flipped (-l_clip -> +l_clip in
    ppo_loss: the car then drives backwards)."""
    run = ppo.ppo(ppo.validate_config(tiny(train=("car",))), log=quiet)
    distance = [m["distance_m"] for m in run.metrics]
    assert distance[0] < 4.0 and distance[-1] > 7.0, distance
    assert run.sim_steps == ppo.iterations(run.cfg) * 8 * 100 >= run.cfg.env_steps
    assert [m["sim_steps"] for m in run.metrics] == [0, 8_000, 16_000]


# ----------------------------------------------------------------------------
# The equations
# ----------------------------------------------------------------------------
def test_gae_is_the_docstrings_worked_example_and_a_flip_cuts_the_bootstrap():
    r, v = torch.tensor([[1.0, 1.0]]), torch.zeros(1, 2)
    adv, ret = ppo.gae(r, v, torch.tensor([4.0]), torch.zeros(1, 2), gamma=0.5, lam=0.5)
    assert adv.tolist() == [[1.75, 3.0]] and ret.tolist() == [[1.75, 3.0]]
    adv, _ = ppo.gae(r, v, torch.tensor([4.0]), torch.tensor([[0.0, 1.0]]), gamma=0.5, lam=0.5)
    assert adv.tolist() == [[1.25, 1.0]]                  # flipped at the last step: no V(o_T)
    # against the definition A_t = sum_l (gamma lam)^l delta_t+l, random numbers, no flip
    g, lam, T = 0.9, 0.8, 6
    r, v, last = torch.randn(3, T), torch.randn(3, T), torch.randn(3)
    nxt = torch.cat([v[:, 1:], last[:, None]], 1)
    delta = r + g * nxt - v
    expected = torch.stack([sum((g * lam) ** l * delta[:, t + l] for l in range(T - t)) for t in range(T)], 1)
    assert torch.allclose(ppo.gae(r, v, last, torch.zeros(3, T), g, lam)[0], expected, atol=1e-5)


def test_ppo_loss_is_eqn_9_with_the_clipped_surrogate_of_eqn_7():
    torch.manual_seed(0)
    graph, cfg = sim2d.design_graph("car"), tiny(train=("car",), norm_adv=False, vf_coef=0.5, ent_coef=0.1)
    policy, value = ppo.Memoryless(gnn.ModularPolicy(cfg.gnn)), gnn.ModularValue(cfg.gnn)
    obs = sim2d.observe(torch.as_tensor(sim2d.sample_initial_states(graph, 4, np.random.default_rng(0)),
                                        dtype=torch.float32), graph)
    mean, log_std = policy.distribution(obs, graph)
    actions = mean + 0.3
    ratio = torch.tensor([0.5, 0.9, 1.5, 1.5])            # r_t, three of them outside [0.8, 1.2]
    adv, returns = torch.tensor([-1.0, -1.0, 2.0, -2.0]), torch.tensor([0.1, 0.2, 0.3, 0.4])
    mb = {"obs": obs, "actions": actions, "advantages": adv, "returns": returns,
          "log_probs": gnn.gaussian_log_prob(mean, log_std, actions).detach() - ratio.log()}
    loss, stats = ppo.ppo_loss(policy, value, mb, graph, cfg)
    # eqn. 7 by hand, min(r A, clip(r, 0.8, 1.2) A) per sample: min(-0.5, -0.8) = -0.8 (clipped),
    # min(-0.9, -0.9), min(3.0, 2.4) = 2.4 (clipped), min(-3.0, -2.4) = -3.0 (not clipped)
    l_clip = (-0.8 - 0.9 + 2.4 - 3.0) / 4
    l_vf = 0.5 * (value(obs, graph) - returns).pow(2).mean()
    entropy = gnn.gaussian_entropy(log_std).mean()
    assert loss.item() == pytest.approx(-l_clip + 0.5 * l_vf.item() - 0.1 * entropy.item(), abs=1e-5)
    assert stats["policy_loss"] == pytest.approx(-l_clip, abs=1e-6)
    assert stats["clip_fraction"] == 0.75
    # the clipped samples (0 and 2) give the policy no gradient; without them (A = 0) nothing moves it
    clipped_only = {**mb, "advantages": adv * torch.tensor([1.0, 0.0, 1.0, 0.0])}
    policy.zero_grad()
    ppo.ppo_loss(policy, value, clipped_only, graph, dataclasses.replace(cfg, ent_coef=0.0))[0].backward()
    assert all(p.grad is None or not p.grad.any() for p in policy.parameters()), "a clipped sample moved the policy"


def test_return_scale_is_the_std_of_the_discounted_return():
    scale, r = ppo.ReturnScale(), torch.randn(5, 7)
    scale.update(r, torch.ones(5, 7, dtype=bool), gamma=0.9)
    G = np.zeros((5, 7))
    for t in range(7):
        G[:, t] = (0.9 * G[:, t - 1] if t else 0) + r[:, t].numpy()
    assert scale.var == pytest.approx(G.var(), rel=1e-3) and scale.mean == pytest.approx(G.mean(), rel=1e-3)
    assert torch.allclose(scale(r), r / np.sqrt(G.var()), rtol=1e-3)


def test_steps_after_a_flip_are_simulated_but_not_trained_on(monkeypatch):
    """With the flip threshold at 0.02 rad some robots 'flip' at once: the flip step is a
    terminal (no bootstrap), the steps after it are invalid."""
    monkeypatch.setattr(sim2d, "FLIP_PITCH", 0.02)
    cfg = ppo.validate_config(tiny(train=("hexapod",), robots=6, episode_steps=20))
    run = ppo.new_run(cfg)
    batch = ppo.collect_episodes(ppo.Memoryless(run.policy), run.value, cfg, run.rng)
    flipped = batch.terminal.sum(1)
    assert flipped.max() == 1 and 0 < flipped.sum() < 6 or flipped.sum() == 6
    for i in range(6):
        if flipped[i]:
            t = int(batch.terminal[i].argmax())
            assert batch.valid[i, :t + 1].all() and not batch.valid[i, t + 1:].any()
        else:
            assert batch.valid[i].all()
    # the update never sees the invalid steps: give them NaN advantages and returns, and count samples
    assert not batch.valid.all()
    advantages, returns = ppo.gae(batch.rewards, batch.values, batch.last_value, batch.terminal, cfg.gamma,
                                  cfg.gae_lambda)
    advantages[~batch.valid], returns[~batch.valid] = float("nan"), float("nan")
    seen, loss = [], ppo.ppo_loss

    def counting_loss(policy, value, mb, graph, cfg):
        seen.append(len(mb["returns"]))
        return loss(policy, value, mb, graph, cfg)
    monkeypatch.setattr(ppo, "ppo_loss", counting_loss)
    ppo.ppo_update(ppo.Memoryless(run.policy), run.value, run.opt, batch, advantages, returns, cfg, run.rng)
    assert sum(seen) == cfg.epochs * int(batch.valid.sum())
    assert all(torch.isfinite(p).all() for p in [*run.policy.parameters(), *run.value.parameters()])


def test_memoryless_policy_ignores_and_keeps_the_hidden_state():
    graph = sim2d.design_graph("leg_none_wheel")
    policy = ppo.Memoryless(gnn.ModularPolicy(gnn.GNNConfig(hidden=16)))
    obs = sim2d.observe(torch.as_tensor(sim2d.sample_initial_states(graph, 3, np.random.default_rng(1)),
                                        dtype=torch.float32), graph)
    h = torch.randn(5, 3, 16)                          # (nodes, robots, H)
    a, h_out = policy.act(obs, graph, h, deterministic=True)
    assert h_out is h and torch.equal(a, policy.act(obs, graph, torch.zeros_like(h), deterministic=True)[0])
    ppo.set_initial_std(policy.policy, 0.6)
    assert torch.allclose(policy.distribution(obs, graph)[1].exp().mean(), torch.tensor(0.6), rtol=0.3)


def test_algorithm1_counts_simulator_steps_without_evaluation():
    """Demos, random roll-outs, the clone's roll-outs (--clone-data, on by default) and one
    policy collection per iteration."""
    cfg = rlil.preset("tiny", train=("car",), demos=("hexapod", "car"))
    demos, random, policy = 2 * 8 * 40, 8 * 40, 2 * 4 * 40
    assert [rlil.sim_steps(cfg, i) for i in (0, 1, 2)] == [demos + random + policy, demos + random + 2 * policy,
                                                            demos + random + 3 * policy]
    paper = dataclasses.replace(cfg, clone_data=False)
    assert [rlil.sim_steps(paper, i) for i in (0, 1, 2)] == [demos + random, demos + random + policy,
                                                              demos + random + 2 * policy]


# ----------------------------------------------------------------------------
# The command line
# ----------------------------------------------------------------------------
def smoke(**kw) -> ppo.PPOConfig:
    """Plumbing, not learning: 2 iterations of 4 robots x 20 steps, evaluated after each."""
    return tiny(**{"train": ("car",), "env_steps": 160, "robots": 4, "episode_steps": 20, "minibatches": 2,
                   "epochs": 2, "eval_every": 80, "eval_episodes": 2, "eval_steps": 20, **kw})


def test_ppo_run_writes_every_output_resumes_and_evaluates(tmp_path):
    whole = train.run(smoke(), tmp_path / "whole", log=quiet)
    for name in run_folders.OUTPUTS:
        assert (tmp_path / "whole" / name).stat().st_size > 0, name
    saved = json.loads((tmp_path / "whole" / "metrics.json").read_text())
    assert saved["config"]["method"] == "ppo" and saved["config"]["env_steps"] == 160
    assert [(r["iteration"], r["sim_steps"]) for r in saved["iterations"]] == [(0, 0), (1, 80), (2, 160)]
    train.run(smoke(env_steps=80), tmp_path / "split", log=quiet)
    resumed = train.run(smoke(), tmp_path / "split", resume=True, log=quiet)
    assert len(resumed) == 3
    again = train.run(smoke(), tmp_path / "again", log=quiet)
    assert strip_times(again) == strip_times(whole)                  # same seed, same numbers
    train.run(smoke(env_steps=80), tmp_path / "short", log=quiet)   # a finished run of another budget
    (tmp_path / "unfinished").mkdir()                                # the split run before its resume:
    train.run(smoke(env_steps=80), tmp_path / "unfinished" / "run", log=quiet)
    meta = json.loads((tmp_path / "unfinished" / "run" / "metrics.json").read_text())
    meta["config"]["env_steps"] = 160                                # ... as a run of 160 steps would read
    (tmp_path / "unfinished" / "run" / "metrics.json").write_text(json.dumps(meta))
    assert sweeps.keep_metrics(tmp_path, tmp_path / "kept") == ["again", "short", "split", "whole"]
    assert sweeps.keep_metrics(tmp_path / "unfinished", tmp_path / "kept2") == []
    out = subprocess.run([sys.executable, "train.py", "--eval", str(tmp_path / "whole"), "--design", "lwnnwl"],
                         capture_output=True, text=True, check=True)
    assert np.isfinite(float(out.stdout.strip().splitlines()[-1].split("distance_m=")[1]))


def test_resumed_ppo_run_ends_where_an_uninterrupted_one_does(tmp_path, monkeypatch):
    whole = train.run(smoke(), tmp_path / "whole", log=quiet)
    calls = []

    def stop_after_first(run):                               # interrupt after the iteration-1 checkpoint
        calls.append(run.iteration)
        if run.iteration == 1:
            raise KeyboardInterrupt
    real_save = run_folders.save_checkpoint
    monkeypatch.setattr(train, "save_checkpoint", lambda out, run: (real_save(out, run), stop_after_first(run)))
    with pytest.raises(KeyboardInterrupt):
        train.run(smoke(), tmp_path / "split", log=quiet)
    monkeypatch.setattr(train, "save_checkpoint", real_save)
    resumed = train.run(smoke(), tmp_path / "split", resume=True, log=quiet)
    assert calls == [0, 1] and strip_times(resumed) == strip_times(whole)


def test_ppo_flags_round_trip_and_bad_input_exits_2(tmp_path, capsys):
    parser = train.build_parser()
    cfg = ppo.validate_config(smoke(train=("lnwwnl",), seed=2, gamma=0.95, anneal_lr=False,
                                    gnn=gnn.GNNConfig(hidden=16)))
    args = parser.parse_args(run_folders.config_args(cfg) + ["--preset", "default"])
    assert train.config_from_args(args) == cfg
    for args in (["--method", "ppo", "--train", "car", "--demos", "lnnnnl"],
                 ["--method", "ppo", "--train", "car", "--env-steps", "0"],
                 ["--method", "ppo", "--train", "car", "hexapod"],
                 ["--method", "ppo", "--train", "car", "--gamma", "1.5"],
                 ["--train", "car", "--env-steps", "1000"],
                 ["--method", "ppo", "--train", "car", "--iters", "3"],
                 ["--method", "sac", "--train", "car"],
                 ["--sample-efficiency", "--jobs", "0"]):
        with pytest.raises(SystemExit) as exit_:
            train.main(args + ["--out", str(tmp_path / "new")])
        err = capsys.readouterr().err
        assert exit_.value.code == 2 and err.count("\n") == 1 and "Traceback" not in err, (args, err)
    assert not (tmp_path / "new").exists()
    train.run(smoke(), tmp_path / "run", log=quiet)                  # a resume must keep the config
    with pytest.raises(run_folders.UsageError, match="only --env-steps may change"):
        train.run(smoke(gamma=0.9), tmp_path / "run", resume=True, log=quiet)
    with pytest.raises(run_folders.UsageError, match="different configuration"):
        train.run(rlil.preset("tiny", train=("car",)), tmp_path / "run", resume=True, log=quiet)


# ----------------------------------------------------------------------------
# PPO+IL (after DAPG): behavioural cloning, then PPO's loss + lambda L_IL
# ----------------------------------------------------------------------------
@pytest.fixture(scope="module")
def car_demos(tmp_path_factory):
    """The car's demonstrations at the tiny budget (8 x 40), in a cache of the test's own."""
    return rlil.load_demos(ppo.validate_config(smoke(demos=("car",))), tmp_path_factory.mktemp("demo_cache"))


def demo_il_loss(policy, demos) -> float:
    """L_IL of the memoryless policy on one fixed batch of demo windows."""
    with torch.no_grad():
        return rlil.il_loss(ppo.Memoryless(policy), demos, smoke(), np.random.default_rng(123))[0].item()


def test_ppo_il_with_lambda_0_and_no_cloning_is_plain_ppo_bit_for_bit(car_demos):
    """Demos given but il_weight = 0 and bc_steps = 0: every metric equals plain PPO's (no extra
    random draw anywhere), and the rows add only lambda (0).  Fails when the IL loss is drawn
    with lambda = 0."""
    plain = ppo.ppo(ppo.validate_config(smoke()), log=quiet)
    cfg = ppo.validate_config(smoke(demos=("car",), il_weight=0.0, bc_steps=0))
    with_demos = ppo.ppo(cfg, log=quiet, demo_data=car_demos)
    pairs = list(zip(with_demos.metrics, plain.metrics))
    ignore = ("seconds", "sim_steps")
    assert [{k: row[k] for k in p if k not in ignore} for row, p in pairs] \
        == [{k: v for k, v in p.items() if k not in ignore} for p in plain.metrics]
    demo_steps = cfg.demo_episodes * cfg.demo_steps                     # the demos' simulator steps count from the start
    assert [row["sim_steps"] - p["sim_steps"] for row, p in pairs] == [demo_steps] * len(pairs)
    assert [set(row) - set(plain_row) for row, plain_row in pairs] == [set(), {"il_weight"}, {"il_weight"}]
    assert [row["il_weight"] for row in with_demos.metrics[1:]] == [0.0, 0.0]


def test_ppo_il_term_lowers_the_il_loss_and_lambda_decays_per_iteration(car_demos):
    """Two smoke iterations without cloning: with the tiny preset's lambda (1, then 0.7) the IL
    loss on a fixed demo batch falls far below that of the same run with lambda = 0 (measured
    1.26 nats against 3.47).  Fails when ppo_il_loss drops the imitation term."""
    without = ppo.ppo(ppo.validate_config(smoke(demos=("car",), bc_steps=0, il_weight=0.0)), log=quiet,
                      demo_data=car_demos)
    with_il = ppo.ppo(ppo.validate_config(smoke(demos=("car",), bc_steps=0)), log=quiet, demo_data=car_demos)
    assert [row["il_weight"] for row in with_il.metrics[1:]] == [1.0, 0.7]
    assert all(np.isfinite(row["il_loss"]) for row in with_il.metrics[1:])
    assert demo_il_loss(with_il.policy, car_demos) < demo_il_loss(without.policy, car_demos) - 1.0, \
        (demo_il_loss(with_il.policy, car_demos), demo_il_loss(without.policy, car_demos))


def test_ppo_il_starts_from_behavioural_cloning(car_demos):
    """DAPG's pre-training: the policy evaluated at iteration 0 already imitates the demos, far
    better than the same seed's untrained policy (measured on a fixed demo batch: 3.92 nats
    untrained, -4.42 after the tiny preset's 100 steps).  Fails when `ppo` skips `behavioural_cloning`."""
    cfg = ppo.validate_config(smoke(demos=("car",), env_steps=80))
    at_iteration_0 = []
    ppo.ppo(cfg, log=quiet, demo_data=car_demos,
            on_evaluation=lambda run: at_iteration_0.append(copy.deepcopy(run.policy)) if run.iteration == 0 else None)
    untrained = ppo.new_run(cfg).policy                                # the policy ppo starts from
    assert demo_il_loss(at_iteration_0[0], car_demos) < demo_il_loss(untrained, car_demos) - 5.0, \
        (demo_il_loss(at_iteration_0[0], car_demos), demo_il_loss(untrained, car_demos))


def test_ppo_il_command_line_names_the_run_and_rejects_bad_demos(tmp_path, capsys, monkeypatch, car_demos):
    """`train.py --method ppo --demos car --train car --preset tiny` (at the smoke budget) runs
    PPO+IL: run name car-ppo_car-seed0, method PPO+IL, the demos in metrics.json and in the
    flags that rebuild it; a bad demo design or window is one line and exit status 2 (at the smoke
    budget, so that a check that lets bad input through fails fast instead of training for hours)."""
    monkeypatch.setattr(rlil, "load_demos", lambda cfg, cache_dir=None: car_demos)   # the test's cache
    smoke_flags = ["--env-steps", "160", "--robots", "4", "--episode-steps", "20", "--minibatches", "2",
                   "--epochs", "2", "--eval-every", "80", "--eval-episodes", "2", "--eval-steps", "20",
                   "--bc-steps", "10"]
    argv = ["--method", "ppo", "--demos", "car", "--train", "car", "--preset", "tiny", *smoke_flags]
    assert train.main(argv + ["--out", str(tmp_path / "run")]) == 0
    assert "behavioural cloning on wnwwnw" in capsys.readouterr().out
    cfg = train.config_from_args(train.build_parser().parse_args(argv))
    assert run_folders.run_name(cfg) == "car-ppo_car-seed0"
    assert run_folders.method_of(cfg) == "PPO+IL"                            # curve.png's label
    assert run_folders.run_name(dataclasses.replace(cfg, demos=())) == "car-ppo-seed0"
    saved = json.loads((tmp_path / "run" / "metrics.json").read_text())
    assert run_folders.config_from_dict(saved["config"]) == cfg and saved["config"]["demos"] == ["wnwwnw"]
    assert [row["il_weight"] for row in saved["iterations"][1:]] == [1.0, 0.7]
    args = train.build_parser().parse_args(run_folders.config_args(cfg) + ["--preset", "default"])
    assert train.config_from_args(args) == cfg                          # what sweeps relaunch
    for bad in (["--demos", "lnnnnl"], ["--demos", "car", "car"], ["--demos", "car", "--il-window", "500"],
                ["--demos", "car", "--il-decay", "1.5"]):
        with pytest.raises(SystemExit) as exit_:
            train.main(["--method", "ppo", "--train", "car", "--preset", "tiny", *smoke_flags, *bad,
                        "--out", str(tmp_path / "new")])
        err = capsys.readouterr().err
        assert exit_.value.code == 2 and err.count("\n") == 1 and "Traceback" not in err, (bad, err)
    assert not (tmp_path / "new").exists()


# ----------------------------------------------------------------------------
# The sample-efficiency sweep
# ----------------------------------------------------------------------------
def test_sample_efficiency_runs_every_method_and_writes_plot_csv_and_summary(tmp_path, monkeypatch):
    """Finished fake runs are reused (nothing launched) and summarised: steps and seconds to 5 m
    and 10 m, the final mean and range."""
    base, base_ppo = rlil.preset("tiny", iters=1), smoke()
    runs = sweeps.sample_efficiency_runs(tmp_path, base, base_ppo, seeds=2, jobs=2)
    assert len(runs) == 2 * 4 * 2 and len({r["dir"] for r in runs}) == 16
    assert {(r["train"], r["method"]) for r in runs} == {(d, m) for d in ("hexapod", "leg_none_wheel")
                                                         for m in ("RL+IL", "RL", "PPO", "PPO+IL")}
    for method in ("RL+IL", "PPO+IL"):                  # Figure 3's demos; PPO and RL have none
        lnw = next(r for r in runs if r["train"] == "leg_none_wheel" and r["method"] == method)
        assert lnw["args"][lnw["args"].index("--demos") + 1:][:2] == ["llllll", "wnwwnw"]
    assert not any("--demos" in r["args"] for r in runs if r["method"] in ("RL", "PPO"))
    for r in runs:
        r["dir"].mkdir(parents=True)
        rows = [{"iteration": i, "sim_steps": 1000 * (i + 1), "seconds": 10.0,
                 "distance_m": 4.0 * i + r["seed"] + (6.0 if r["method"] == "PPO" else 0.0)}
                for i in range(r["last"] + 1)]
        (r["dir"] / "metrics.json").write_text(json.dumps({"config": run_folders.config_to_dict(r["cfg"]),
                                                           "iterations": rows}))
    monkeypatch.setattr(sweeps, "run_one", lambda *a, **k: pytest.fail("a finished run was launched"))
    assert sweeps.sample_efficiency(tmp_path, base, base_ppo, seeds=2, jobs=2, log=quiet) == []
    lines = (tmp_path / "sample_efficiency.csv").read_text().splitlines()
    assert lines[0] == "train,method,seed,iteration,sim_steps,seconds,distance_m"
    assert "hexapod,PPO,1,2,3000,30.0,15.0" in lines
    table = (tmp_path / "sample_efficiency.md").read_text()
    # RL: seeds 0 and 1 give means 0.5, 4.5 m: 5 m not reached; PPO: 6.5, 10.5, 14.5 m
    assert "| hexapod | RL | 2 of 2 | not reached |  | not reached |  | not reached |  | 2,000 | 20 | 4.50 | 4.00 - 5.00 |" in table
    assert "| hexapod | PPO | 2 of 2 | 1,000 | 10 | 2,000 | 20 | not reached |  | 3,000 | 30 | 14.50 | 14.00 - 15.00 |" in table
    # PPO+IL: 0.5, 4.5, 8.5 m
    assert "| hexapod | PPO+IL | 2 of 2 | 3,000 | 30 | not reached |  | not reached |  | 3,000 | 30 | 8.50 | 8.00 - 9.00 |" in table
    assert (tmp_path / "sample_efficiency.png").stat().st_size > 10_000
    assert "SB3" not in table                           # no sb3_ppo_runs/: no SB3 row, not an empty one
    (tmp_path / "sb3_ppo_runs").mkdir()                 # interfaces/sb3_ppo.py --out CSVs, collected as they are
    for seed in (0, 1):
        (tmp_path / "sb3_ppo_runs" / f"hexapod-seed{seed}.csv").write_text(
            "steps,seconds,distance_m\n0,0.0,0.1\n2048,5.0,%.1f\n4096,9.0,%.1f\n" % (4 + 2 * seed, 12 + 2 * seed))
    assert sweeps.sample_efficiency(tmp_path, base, base_ppo, seeds=2, jobs=2, log=quiet) == []
    assert "hexapod,SB3 PPO,1,2,4096,9.0,14.0" in (tmp_path / "sample_efficiency.csv").read_text().splitlines()
    table = (tmp_path / "sample_efficiency.md").read_text()   # SB3: means 0.1, 5, 13 m
    assert "| hexapod | SB3 PPO | 2 of 2 | 2,048 | 5 | 4,096 | 9 | not reached |  | 4,096 | 9 | 13.00 | 12.00 - 14.00 |" in table
    assert "| leg_none_wheel | SB3 PPO | 0 of 2 |" in table


def test_the_side_by_side_table_lists_only_the_designs_and_methods_asked():
    """experiments/side_by_side.py's table (tables.py): RL+IL and PPO of one design, no empty rows."""
    rows = [{"train": "leg_none_wheel", "method": m, "seed": s, "iteration": i, "sim_steps": 1000 * (i + 1),
             "seconds": 10.0 * (i + 1), "distance_m": 6.0 * i + (1.0 if m == "PPO" else 0.0)}
            for m in ("RL+IL", "PPO") for s in range(2) for i in range(3)]
    table = sweeps.summarize_sample_efficiency(rows, 2, designs=("leg_none_wheel",), methods=("RL+IL", "PPO"))
    assert len(table.strip().splitlines()) == 4 and "hexapod" not in table
    assert "| leg_none_wheel | RL+IL | 2 of 2 | 2,000 | 20 | 3,000 | 30 | not reached |" in table
    assert "| leg_none_wheel | PPO | 2 of 2 | 2,000 | 20 | 3,000 | 30 | not reached |" in table
    stopped = rows + [{"train": "leg_none_wheel", "method": "PPO", "seed": 0, "iteration": 3, "sim_steps": 4000,
                       "seconds": 40.0, "distance_m": 20.0}]          # one seed went on further before its stop
    table = sweeps.summarize_sample_efficiency(stopped, 2, designs=("leg_none_wheel",), methods=("RL+IL", "PPO"))
    assert "| leg_none_wheel | PPO | 2 of 2 | 2,000 | 20 | 3,000 | 30 | not reached |  | 3,000 | 30 | 13.00 |" in table


def test_side_by_side_passes_its_evaluation_grid_to_ppo_only(tmp_path):
    """--ppo-eval-every N reaches PPO's command line as --eval-every N and not RL+IL's; without it
    PPO keeps its own grid."""
    from experiments import side_by_side
    fine = side_by_side.commands("leg_none_wheel", 1, tmp_path, 12800)
    i = fine["PPO"][1].index("--eval-every")
    assert fine["PPO"][1][i + 1] == "12800" and "--eval-every" not in fine["RL+IL"][1]
    assert "--eval-every" not in side_by_side.commands("leg_none_wheel", 1, tmp_path)["PPO"][1]
    import train
    assert train.config_from_args(train.build_parser().parse_args(fine["PPO"][1])).eval_every == 12800


def test_side_by_side_refuses_an_existing_run_folder_before_it_runs_anything(tmp_path, monkeypatch, capsys):
    """experiments/side_by_side.py never runs over a run the user has: one line, exit 2, nothing started."""
    from experiments import side_by_side
    (tmp_path / "leg_none_wheel-ppo-seed1").mkdir()
    monkeypatch.setattr(side_by_side, "run_pair", lambda *a: pytest.fail("a run was started"))
    with pytest.raises(SystemExit) as e:
        side_by_side.main(["--seeds", "2", "--out", str(tmp_path), "--csv", str(tmp_path / "t.csv")])
    err = capsys.readouterr().err.strip().splitlines()
    assert e.value.code == 2 and "leg_none_wheel-ppo-seed1 exists: name another --out" in err[-1]
    assert not (tmp_path / "t.csv").exists()
