"""experiments/gradient_check.py: the probe of whether the model's gradient points uphill in the simulator."""
import dataclasses

import numpy as np
import pytest
import torch

import modular_rlil_minimal as rlil
import sim2d
from experiments import gradient_check as gc
from gnn import ModularPolicy


def test_paired_returns_of_one_policy_are_equal():
    """Before and after a step come from the same starts and sensor noise, so an unchanged policy
    changes by exactly 0: every difference the probe reports is the step's."""
    torch.manual_seed(0)
    policy = ModularPolicy(rlil.preset("tiny").gnn)
    a = gc.real_returns(policy, "car", 4, 20, seed=5, horizon=10)
    b = gc.real_returns(policy, "car", 4, 20, seed=5, horizon=10)
    assert all(np.array_equal(x, y) for x, y in zip(a[:2], b[:2])) and torch.equal(a[2], b[2])
    other = gc.real_returns(policy, "car", 4, 20, seed=6, horizon=10)
    assert not np.array_equal(a[1], other[1])                               # the seed does pick the starts


def test_a_step_along_the_gradient_raises_the_models_return():
    """On the tiny car every probe's step raises the model's own T-step return from the probe's
    starts (it descends L_RL = -R); a step up L_RL would lower it."""
    rows = gc.probe_rows("car", 0, 0, horizons=[5], probes=3, starts=4, base=rlil.preset("tiny", model_steps=100))
    assert len(rows) == 3 and all(r["model_T"] > 0 for r in rows)
    assert set(rows[0]) == set(gc.COLUMNS)
    assert "| car | 0 | 5 | 3 |" in gc.summary(rows)


@pytest.mark.parametrize("script, argv, message", [
    ("gradient_check", ["--horizons", "0"], "--horizons takes 1 to 100"),
    ("gradient_check", ["--preset", "huge"], "unknown preset 'huge'"),
    ("gradient_check", ["--designs", "tank"], "tank"),
    ("flattery_curve", ["--after", "-1"], "--after takes 0 to 50"),
    ("flattery_curve", ["--set", "horizon=x"], "horizon takes a int"),
    ("flattery_curve", ["--design", "tank"], "tank"),
    ("phase_probe", ["--variants", "K9"], "unknown variant 'K9'"),
    ("phase_probe", ["--repeats", "0"], "--repeats takes 1 to 100"),
    ("phase_probe", ["--design", "tank"], "tank"),
    ("phase_probe", ["--demos", "tank"], "tank"),
    ("phase_probe", ["--set", "batch=0"], "batch must be"),
    ("phase_probe", ["--set", "nope=1"], "--set nope=1"),
    ("clone_flips", ["--seeds", "-1"], "--seeds takes 0 to"),
    ("clone_flips", ["--train", "tank"], "tank"),
    ("clone_flips", ["--out", "x.txt"], "name a .csv file")])
def test_bad_flags_are_one_line(script, argv, message, capsys):
    """Each probe script refuses a bad flag with one line naming it, exit status 2."""
    import importlib
    with pytest.raises(SystemExit) as e:
        importlib.import_module(f"experiments.{script}").main(argv)
    err = capsys.readouterr().err.strip().splitlines()
    assert e.value.code == 2 and message in err[-1]


class Drifts:
    """A model in which every step moves x forward by 0.1 m, whatever the action."""

    def on_design(self, graph):
        return lambda s, a: s + torch.nn.functional.pad(torch.full((len(s), 1), 0.1), (0, s.shape[1] - 1))


def test_replay_runs_the_demonstrators_actions_through_the_model_step_by_step():
    """experiments/model_replay.py: T model steps predict 0.1 T m in a model that drifts 0.1 m a
    step; the simulator's side is the demonstrations' own progress."""
    from experiments import model_replay
    demo = model_replay.demo_lib.collect_demos("car", 2, 12, seed=3)
    r = model_replay.replay(Drifts(), demo, horizon=5)
    assert r["model_T"] == pytest.approx(0.5) and r["model_episode"] == pytest.approx(1.2)
    true = demo.states[:, :, 0] - demo.states[:, :1, 0]
    assert r["sim_T"] == pytest.approx(true[:, 5].mean()) and r["sim_episode"] == pytest.approx(true[:, 12].mean())


def test_the_flattery_curve_watches_the_phase_without_changing_it():
    """experiments/flattery_curve.py: one row per validation check; the last row is the model's
    and the simulator's T-step progress that a run's iteration 1 records (the watch draws no
    random number the phase uses), and the policy moves between checks."""
    from experiments import flattery_curve as fc
    cfg = rlil.preset("tiny", train=("car",), model_steps=100, iters=1)
    rows = fc.phase_rows(cfg, after=0)
    assert [r["step"] for r in rows] == list(range(0, cfg.policy_steps + 1, cfg.validate_every))
    assert set(rows[0]) == set(fc.COLUMNS) and rows[0]["sim_progress_m"] != rows[-1]["sim_progress_m"]
    row = rlil.algorithm1(cfg, {}, log=lambda m: None).metrics[1]
    assert rows[-1]["model_progress_m"] == pytest.approx(row["model_progress_m"], abs=1e-6)
    assert rows[-1]["sim_progress_m"] == pytest.approx(row["sim_progress_m"], abs=1e-6)
    assert "| car | 0 | 30 | 1 |" in fc.summary(rows)


def test_the_clone_row_is_a_runs_iteration_0(tmp_path):
    """experiments/clone_flips.py clones as algorithm1's line 1 does (its demos, seeding and steps):
    its distance and flipped count are the run's iteration-0 row, and the cloning did something."""
    from experiments import clone_flips
    cfg = rlil.preset("tiny", train=("wnwwnw",), demos=("wnwwnw",), bc_steps=30, eval_steps=60, policy_steps=6,
                      iters=1, seed=3)
    row = clone_flips.clone_row(cfg, tmp_path)
    run = rlil.algorithm1(cfg, rlil.load_demos(cfg, tmp_path), log=lambda m: None).metrics[0]
    assert row["distance_m"] == run["distance_m"] and row["flipped"] == run["flipped"]
    assert set(row) == set(clone_flips.COLUMNS) and row["starts"] == cfg.eval_episodes
    uncloned = clone_flips.clone_row(rlil.preset("tiny", train=("wnwwnw",), demos=("wnwwnw",), bc_steps=0,
                                                 eval_steps=60, seed=3), tmp_path)
    assert uncloned["distance_m"] != row["distance_m"]


def test_the_phase_probe_starts_where_the_run_is_and_runs_a_phase():
    """experiments/phase_probe.py: the starting policy is the run's own after `after` iterations
    (its distance is the run's row; here after 0, the untrained policy), each variant's phase moves the policy, the repeats of one
    variant draw differently, and the start sampler is Algorithm 1's again afterwards."""
    from experiments import phase_probe as pp
    sampler = rlil.sample_sim_states
    cfg = rlil.preset("tiny", train=("car",), model_steps=100, iters=1, seed=2)
    rows = pp.probe_rows("car", 2, 0, ["lr3e-3", "B_ps"], repeats=2, base=cfg)
    assert len(rows) == 4 and set(rows[0]) == set(pp.COLUMNS)
    assert rlil.sample_sim_states is sampler
    run = rlil.algorithm1(cfg, {}, log=lambda m: None).metrics[0]
    assert rows[0]["start_m"] == run["distance_m"]
    assert all(r["distance_m"] != r["start_m"] for r in rows)
    assert rows[0]["validation_reward"] != rows[1]["validation_reward"]
    assert "| car, 2, 0 (" in pp.summary(rows)


def test_the_ensemble_runs_each_row_on_one_member_and_the_probe_phases_on_it():
    """`Ensemble` (part 30): row b of a batch goes through member b mod E, with the gradient, and
    `probe_rows` fits the extra members and runs the phase on all of them (the ensemble's phase
    differs from the single model's, from the same start and draws)."""
    from experiments import phase_probe as pp
    cfg = rlil.preset("tiny", train=("car",), model_steps=50, iters=1, seed=2)
    policy, model, traj, _ = pp.starting_point(cfg, 0)
    graph = sim2d.design_graph(traj.design)
    ens = pp.ensemble_at(model, traj, cfg, 3)
    assert len(ens.members) == 3 and ens.members[0] is model
    s = rlil.sample_sim_states(traj, 7, np.random.default_rng(0)).requires_grad_(True)
    a = torch.zeros(7, graph.action_dim)
    out = ens.on_design(graph)(s, a)
    singles = [m.on_design(graph)(s, a) for m in ens.members]
    for b in range(7):
        assert torch.allclose(out[b], singles[b % 3][b], atol=1e-5)          # another batch, other rounding
    assert (singles[1] - singles[0]).abs().max() > 1e-2                  # the members differ
    out.sum().backward()
    assert s.grad is not None and torch.isfinite(s.grad).all()
    rows = pp.probe_rows("car", 2, 0, ["own", "ens4"], repeats=1, base=dataclasses.replace(cfg, model_steps=50))
    assert rows[0]["start_m"] == rows[1]["start_m"] and rows[0]["distance_m"] != rows[1]["distance_m"]


def test_the_phase_probe_starts_from_rlils_policy_with_demos():
    """`--demos` (part 26): the starting policy is RL+IL's after `after` iterations (here 0: the
    clone, the run's row 0), not plain RL's, and the phase is plain RL's (it moves the policy)."""
    from experiments import phase_probe as pp
    cfg = rlil.preset("tiny", train=("car",), model_steps=100, iters=1, seed=2)
    rows = pp.probe_rows("car", 2, 0, ["own"], repeats=1, base=cfg, demos=["car"])
    with_demos = dataclasses.replace(cfg, demos=("wnwwnw",))
    clone = rlil.algorithm1(with_demos, rlil.load_demos(with_demos), log=lambda m: None).metrics[0]
    plain = rlil.algorithm1(cfg, {}, log=lambda m: None).metrics[0]
    assert rows[0]["start_m"] == clone["distance_m"] != plain["distance_m"]
    assert rows[0]["start_from"] == "RL+IL" and rows[0]["distance_m"] != rows[0]["start_m"]


def test_the_phase_probe_table_reads_its_csv(tmp_path):
    """results/phase_probe.md (tables.py) is `summary` of the CSVs as read back: columns in
    VARIANTS' order whatever the CSV's, a missing cell "-", two starting points two rows, and
    `start_from` (RL or RL+IL) read back as text."""
    from experiments import phase_probe as pp
    from experiments.sweeps import write_rows_csv
    from experiments.tables import read_rows_csv
    rows = [{"design": "hexapod", "seed": seed, "after": 4, "start_m": 0.25, "variant": v, "repeat": r,
             "distance_m": d + r, "reverts": 0, "validation_reward": 0.5, "start_from": ("RL", "RL+IL")[seed]}
            for seed, v, d in ((0, "K480", 4.0), (0, "K120", 0.2), (1, "K120", 0.1)) for r in range(2)]
    write_rows_csv(tmp_path / "probe.csv", pp.COLUMNS, rows)
    read = read_rows_csv(tmp_path / "probe.csv")
    assert [r["start_from"] for r in read] == [r["start_from"] for r in rows]     # text, as part 26 wrote it
    table = pp.summary(read)
    assert table == pp.summary(rows)
    assert table.splitlines()[0] == "| design, seed, after (start, m) | K120 | K480 |"
    assert table.splitlines()[2:] == ["| hexapod, 0, 4 (0.25) | 0.20, 1.20 | 4.00, 5.00 |",
                                      "| hexapod, 1, 4 (0.25) | 0.10, 1.10 | - |"]


def test_the_phase_probe_draws_a_share_of_the_starts_from_p_s():
    """`starts_from_p_s(share)`: the first share of the states are p(s)'s (at rest within the
    perturbation of sim2d.sample_initial_states), the rest come from T_train."""
    from experiments import phase_probe as pp
    import sim2d
    cfg = rlil.preset("tiny", train=("car",))
    traj = rlil.collect_random_rollouts("wnwwnw", cfg, np.random.default_rng(0))
    s = pp.starts_from_p_s(0.5)(traj, 8, np.random.default_rng(1))
    speed = s[:, 3:5].abs().max(1).values
    assert s.shape == (8, traj.states.shape[-1]) and s.dtype == traj.states.dtype
    assert bool((speed[:4] <= sim2d.INIT_BODY_VEL).all()) and not bool((speed[4:] <= sim2d.INIT_BODY_VEL).all())


def test_the_phase_probe_noise_variants_change_the_phase_and_only_it():
    """Parts 23 and 25's variants: "det" (L_RL's roll-outs on the mean action), "floor25" and
    "floor05" (a lower and a higher log-std floor) each end the phase elsewhere than the same draws at the run's own noise, and
    leave `rlil.rollout` and the policy's floor as they were; the start's log-std is in the floor's range."""
    from experiments import phase_probe as pp
    rollout = rlil.rollout
    cfg = rlil.preset("tiny", train=("car",), model_steps=100, iters=1, seed=2)
    cfg.gnn.log_std_min = -1.0
    rows = pp.probe_rows("car", 2, 0, ["own", "det", "floor25", "floor05"], repeats=1, base=cfg)
    d = {r["variant"]: r["distance_m"] for r in rows}
    assert len(set(d.values())) == 4, d
    assert rlil.rollout is rollout and cfg.gnn.log_std_min == -1.0
    assert -1.0 <= rows[0]["start_log_std"] <= 0.0


def test_the_takeoff_probe_counts_points_that_walk_and_beat_own_by_a_metre():
    """`takeoff` (part 29's rule): per point the mean over the repeats; a variant counts at a point
    only if its mean is at least 2 m and at least 1 m above `own`'s there."""
    from experiments import phase_probe as pp
    means = {0: (0.0, 2.5), 1: (1.5, 2.4), 3: (0.2, 1.9)}      # own, K1920_B16: walks; too close to own; short of 2 m
    rows = [{"design": "hexapod", "seed": s, "after": 2, "start_m": 0.1, "variant": v, "repeat": r,
             "distance_m": m + (r - 1) * 0.5, "reverts": 0, "validation_reward": 0.3}
            for s, pair in means.items() for v, m in zip(("own", "K1920_B16"), pair) for r in range(3)]
    lines = pp.takeoff(rows).splitlines()
    assert lines[2] == "| hexapod, 0, 2 (0.10) | 0.00 | 2.50 |"
    assert lines[-1].endswith("| - | 1 of 3 |")


def test_the_walking_probe_gains_count_only_walking_points():
    """`gains` (part 23's rule): a variant's gain is its mean over the repeats minus `own`'s,
    averaged over the starting points at 10 m or more only, with the points where it is above."""
    from experiments import phase_probe as pp
    rows = [{"design": "hexapod", "seed": s, "after": 7, "start_m": start, "variant": v, "repeat": r,
             "distance_m": start + shift + r, "reverts": 0, "validation_reward": 1.0, "start_log_std": -0.9}
            for s, start in ((1, 15.0), (4, 5.0), (5, 18.0))
            for v, shift in (("own", 0.0), ("det", 1.0 if s != 4 else -9.0), ("floor25", -0.5 if s == 1 else 0.5))
            for r in range(3)]
    lines = pp.gains(rows).splitlines()
    assert lines[0].startswith("Starting points at 10 m or more: 2 of 3")
    assert "| det | 18.50 | +1.00 | 2 of 2 |" in lines
    assert "| floor25 | 17.50 | +0.00 | 1 of 2 |" in lines
