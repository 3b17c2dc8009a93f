"""Tests of the demonstration datasets (demos.py): shapes, locomotion, gait, feedback, cache, CLI."""
import doctest
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import demos
import sim2d

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def default_demos(tmp_path_factory):
    """The hexapod and car datasets at the paper's sizes (50 x 100 steps), built once."""
    cache = tmp_path_factory.mktemp("demo_cache")
    return {d: demos.load_or_make_demos(d, cache_dir=cache) for d in ("hexapod", "car")}


def arrays(data: demos.DemoData) -> dict:
    return {"actions": data.actions, "states": data.states, "distance_m": data.distance_m,
            "flipped": data.flipped, **{f"obs_{k}": v for k, v in data.obs.items()}}


def assert_same(a: demos.DemoData, b: demos.DemoData):
    assert a.design == b.design
    for k, v in arrays(a).items():
        assert np.array_equal(v, arrays(b)[k]), k


# ----------------------------------------------------------------------------
# The dataset: what the policy sees and does, per module
# ----------------------------------------------------------------------------
@pytest.mark.parametrize("design", ["hexapod", "car", "leg_none_wheel"])
def test_dataset_shapes_per_module(design):
    graph = sim2d.design_graph(design)
    E, T, L, W = 3, 7, graph.n_legs, graph.n_wheels
    data = demos.collect_demos(design, episodes=E, steps=T, seed=0)
    assert data.design == graph.code
    assert data.obs["body"].shape == (E, T, 3)
    assert data.obs["leg"].shape == (E, T, L, 4)
    assert data.obs["wheel"].shape == (E, T, W, 1)
    assert data.actions.shape == (E, T, graph.action_dim)
    assert data.states.shape == (E, T + 1, graph.state_dim)
    assert data.distance_m.shape == (E,) and data.flipped.shape == (E,) and data.flipped.dtype == bool
    assert np.abs(data.actions).max() <= 1.0
    np.testing.assert_allclose(data.distance_m, data.states[:, -1, 0] - data.states[:, 0, 0])
    # o_t is the noisy O(s_t) of the state the action was chosen in (not s_t+1).
    clean = sim2d.observe(data.states[:, :-1], graph)
    for k, std in (("body", sim2d.OBS_NOISE_BODY), ("leg", sim2d.OBS_NOISE_LEG), ("wheel", sim2d.OBS_NOISE_WHEEL)):
        if data.obs[k].size:
            ratio = (data.obs[k] - clean[k]).reshape(-1, len(std)).std(0) / np.array(std)
            assert np.all((ratio > 0.5) & (ratio < 1.6)), (k, ratio)


def test_hexapod_and_car_move_forward_without_flipping(default_demos):
    for design, data in default_demos.items():
        q = demos.demo_quality(data)
        assert data.actions.shape[:2] == (50, 100)
        assert q["min_distance_m"] > 5.0, (design, q)      # > 0.6 m/s for every perturbed start
        assert q["flips"] <= 1, (design, q)
        assert q["max_abs_pitch"] < 0.3, (design, q)


def test_hexapod_and_car_speeds_within_factor_1_5(default_demos):
    speeds = [demos.demo_quality(d)["speed_m_s"] for d in default_demos.values()]
    assert max(speeds) / min(speeds) < 1.5, speeds
    assert all(0.7 < s < 1.2 for s in speeds), speeds    # near the common 1 m/s target


def test_hexapod_walks_an_alternating_tripod_gait(default_demos):
    data, graph = default_demos["hexapod"], sim2d.design_graph("hexapod")
    hip = data.actions[:, 12:, 0::2]                       # (E, T, 6) hip commands after the ramp
    half = round(demos.DemoConfig().gait_period / 2 / sim2d.CONTROL_DT)   # 3 control steps

    def corr(a, b, lag=0):                                 # hip command of port a vs port b, lag steps later
        return np.corrcoef(hip[:, :hip.shape[1] - lag, a].ravel(), hip[:, lag:, b].ravel())[0, 1]
    for a in range(6):
        for b in range(6):
            if (a in demos.TRIPOD_B) == (b in demos.TRIPOD_B):            # same tripod: in step
                assert corr(a, b) > 0.9, (a, b)
            else:                                                         # half a period apart
                assert corr(a, b) < 0 and corr(a, b, half) > 0.9, (a, b)
    # Swing feet are raised and move forward relative to the hip; stance feet push back.
    states = data.states[:, 13:]                           # (E, T', S) s_t+1 reached phase(t+1)
    phase = np.stack([demos.tripod_phase(t, graph.leg_ports, demos.DemoConfig().gait_period)
                      for t in range(13, 101)])            # (T', 6)
    fk = sim2d.forward_kinematics(graph, states.reshape(-1, states.shape[-1]))
    foot_y = fk["foot"][..., 1].reshape(*states.shape[:2], 6)
    swing = np.broadcast_to(phase >= 0.5 + 1e-9, foot_y.shape)
    assert foot_y[swing].mean() > foot_y[~swing].mean() + 2.0          # cm
    hip_cmd = data.actions[:, 12:100, 0::2]                # a_t drives towards phase(t+1)
    assert hip_cmd[swing].mean() > 0.2 and hip_cmd[~swing].mean() < -0.2


# ----------------------------------------------------------------------------
# Closed loop: the corrections point the right way; vectorised = per robot
# ----------------------------------------------------------------------------
def test_feedback_corrects_pitch_height_and_speed():
    cfg = demos.DemoConfig()
    hip_x = np.array([38.0, 0.0, -38.0])
    level = demos.stance_depth(np.array([[0.43]]), np.array([[0.0]]), hip_x, 0.43, cfg)
    nose_up = demos.stance_depth(np.array([[0.43]]), np.array([[0.1]]), hip_x, 0.43, cfg)
    sagging = demos.stance_depth(np.array([[0.40]]), np.array([[0.0]]), hip_x, 0.43, cfg)
    assert nose_up[0, 0] < level[0, 0] and nose_up[0, 2] > level[0, 2]   # front shorter, rear longer
    assert np.all(sagging > level)
    slow, fast = demos.modulated_step_size(1.0, np.array([0.5, 1.5]), cfg)
    assert slow > demos.modulated_step_size(1.0, np.array(1.0), cfg) > fast
    car = sim2d.design_graph("car")
    state = np.tile(sim2d.nominal_state(car), (3, 1))
    state[2, 2] = 0.6                                      # pitched beyond the back-off
    est = np.array([[0.43, 0.0, 0.5], [0.43, 0.0, 1.0], [0.43, 0.0, 1.0]])
    wheels = demos.wheel_drive_actions(car, state, 50, est, cfg)           # (3, 4)
    assert np.all(wheels[0] < wheels[1]) and np.all(wheels[1] < 0) and np.all(wheels[2] == 0)


def test_demo_actions_vectorised_matches_per_robot(default_demos):
    graph = sim2d.design_graph("hexapod")
    states = default_demos["hexapod"].states[:5, 40]       # (5, S)
    est = states[:, [1, 2, 3]] + np.linspace(-0.05, 0.05, 5)[:, None]
    batch = demos.demo_actions(graph, states, 40, est, demos.DemoConfig())
    single = np.concatenate([demos.demo_actions(graph, states[i:i + 1], 40, est[i:i + 1], demos.DemoConfig())
                             for i in range(5)])
    np.testing.assert_allclose(batch, single, rtol=0, atol=1e-12)


# ----------------------------------------------------------------------------
# Seeds and cache
# ----------------------------------------------------------------------------
def test_same_seed_same_dataset_other_seed_or_design_differs():
    a = demos.collect_demos("hexapod", episodes=4, steps=20, seed=0)
    assert_same(a, demos.collect_demos("hexapod", episodes=4, steps=20, seed=0))
    b = demos.collect_demos("hexapod", episodes=4, steps=20, seed=1)
    assert not np.array_equal(a.states[:, 0], b.states[:, 0])
    assert not np.array_equal(a.obs["body"], b.obs["body"])
    assert demos.demo_seed("llllll", 0) != demos.demo_seed("wnwwnw", 0)


def test_cache_reused_when_unchanged_rebuilt_when_changed(tmp_path, monkeypatch):
    first = demos.load_or_make_demos("car", episodes=3, steps=5, seed=2, cache_dir=tmp_path)
    [path] = tmp_path.glob("*.npz")
    assert path == demos.cache_path("car", 3, 5, 2, tmp_path)
    mtime = path.stat().st_mtime_ns
    with monkeypatch.context() as m:                       # a second call must load, not build
        m.setattr(demos, "collect_demos", lambda *a, **k: pytest.fail("rebuilt an unchanged dataset"))
        again = demos.load_or_make_demos("car", episodes=3, steps=5, seed=2, cache_dir=tmp_path)
    assert_same(first, again)
    assert again.meta == first.meta and path.stat().st_mtime_ns == mtime
    demos.load_or_make_demos("car", episodes=3, steps=6, seed=2, cache_dir=tmp_path)    # other steps
    demos.load_or_make_demos("car", episodes=3, steps=5, seed=3, cache_dir=tmp_path)    # other seed
    assert len(list(tmp_path.glob("*.npz"))) == 3
    monkeypatch.setattr(demos, "source_hash", lambda: "sim2d-or-demos-edited")           # other source
    assert demos.cache_path("car", 3, 5, 2, tmp_path) != path
    demos.load_or_make_demos("car", episodes=3, steps=5, seed=2, cache_dir=tmp_path)
    assert len(list(tmp_path.glob("*.npz"))) == 4
    assert not list(tmp_path.glob("*.tmp"))                # atomic writes leave nothing behind


# ----------------------------------------------------------------------------
# Bad input: one-line errors, exit status 2
# ----------------------------------------------------------------------------
@pytest.mark.parametrize("design, episodes, steps", [
    ("lnnnnl", 2, 5),      # legs only at the front: the rear drags
    ("nnwwnn", 2, 5),      # wheels only at the rear
    ("llnnll", 2, 5),      # hexapod without its rear legs
    ("spider", 2, 5),
    ("hexapod", 0, 5),
    ("car", 2, -1),
])
def test_bad_requests_raise_one_line_value_error(design, episodes, steps, tmp_path):
    with pytest.raises(ValueError) as err:
        demos.load_or_make_demos(design, episodes=episodes, steps=steps, cache_dir=tmp_path)
    assert "\n" not in str(err.value) and str(err.value)
    assert not list(tmp_path.iterdir())


def test_named_designs_are_demonstrable():
    for design in sim2d.NAMED_DESIGNS:
        demos.check_demonstrable(sim2d.design_graph(design))


def run_cli(*args):
    return subprocess.run([sys.executable, str(REPO / "demos.py"), *args], capture_output=True, text=True,
                          cwd=REPO, timeout=120)


@pytest.mark.parametrize("args", [
    ["--design", "spider"],
    ["--design", "lnnnnl"],
    ["--design", "car", "--episodes", "0"],
    ["--design", "car", "--steps", "ten"],
])
def test_cli_bad_input_exits_2_without_traceback(args, tmp_path):
    r = run_cli(*args, "--cache-dir", str(tmp_path))
    assert r.returncode == 2, r.stderr
    assert "Traceback" not in r.stderr and "error:" in r.stderr
    if "ten" not in args:                                  # our own errors are one line
        assert len(r.stderr.strip().splitlines()) == 1, r.stderr


def test_cli_prints_summary_and_loads_cache(tmp_path):
    args = ["--design", "leg_leg_wheel", "--episodes", "2", "--steps", "6", "--cache-dir", str(tmp_path)]
    first, second = run_cli(*args), run_cli(*args)
    for r in (first, second):
        assert r.returncode == 0, r.stderr
        last = r.stdout.strip().splitlines()[-1]
        assert re.search(r"mean_distance_m=-?\d+\.\d+ min_distance_m=-?\d+\.\d+ flips=\d+$", last), last
    assert "built" in first.stdout and "loaded" in second.stdout


def test_doctests():
    assert doctest.testmod(demos).failed == 0


def test_execution_noise_perturbs_the_robot_but_records_the_demonstrators_answer():
    """DART-style demos: the robot executes a_t + noise, the dataset records a_t, the
    demonstrator's own answer in each state the noise led to."""
    cfg = demos.DemoConfig(execution_noise=0.2)
    noisy = demos.collect_demos("hexapod", episodes=4, steps=20, seed=0, cfg=cfg)
    clean = demos.collect_demos("hexapod", episodes=4, steps=20, seed=0)
    assert np.array_equal(noisy.states[:, 0], clean.states[:, 0])            # same starts
    assert not np.allclose(noisy.states[:, -1], clean.states[:, -1])         # the noise moved the robots
    replay = demos.Demonstrator("hexapod", cfg)
    for t in range(20):
        obs = {k: v[:, t] for k, v in noisy.obs.items()}
        np.testing.assert_array_equal(replay(obs, noisy.states[:, t], t), noisy.actions[:, t])
