"""Tests of the planar world (sim2d.py): designs, physics sanity, determinism, reward, batching;
and of its contacts and joints under aggressive actions (tools/check_physics.py)."""
import subprocess
import sys

import numpy as np
import pytest
import torch

from tools import check_physics
import sim2d

NAMED = list(sim2d.NAMED_DESIGNS)


def test_names_and_codes():
    assert sim2d.parse_design("hexapod") == "llllll"
    assert sim2d.parse_design("car") == "wnwwnw"
    assert sim2d.parse_design("leg-leg-wheel") == "llwwll"
    assert sim2d.parse_design("LEG_NONE_WHEEL") == "lnwwnl"
    assert sim2d.parse_design("lwnnwl") == "lwnnwl"
    assert len(sim2d.all_designs()) == 728
    g = sim2d.design_graph("leg_none_wheel")
    assert g.leg_ports == (0, 5) and g.wheel_ports == (2, 3)
    assert g.nodes == [("body", None), ("leg", 0), ("leg", 5), ("wheel", 2), ("wheel", 3)]
    assert g.state_dim == 6 + 4 * 2 + 2 and g.action_dim == 2 * 2 + 2


@pytest.mark.parametrize("bad", ["spider", "llll", "lxwwnl", "nnnnnn", ""])
def test_bad_designs_give_one_line_errors(bad):
    with pytest.raises(ValueError) as err:
        sim2d.parse_design(bad)
    assert "\n" not in str(err.value) and ("hexapod" in str(err.value) or "no limbs" in str(err.value))


def test_cli_bad_design_exit_status_2():
    out = subprocess.run([sys.executable, "sim2d.py", "--design", "spider"], capture_output=True, text=True)
    assert out.returncode == 2
    assert out.stderr.count("\n") == 1 and "unknown design" in out.stderr


def test_cli_summary_line():
    out = subprocess.run([sys.executable, "sim2d.py", "--design", "car", "--steps", "12", "--action", "random"],
                         capture_output=True, text=True, check=True)
    last = out.stdout.strip().splitlines()[-1]
    assert last.split()[-2].startswith("distance_m=") and last.split()[-1] in ("flipped=0", "flipped=1")
    float(last.split()[-2].split("=")[1])


@pytest.mark.parametrize("design", NAMED)
def test_named_designs_stand_still(design):
    g = sim2d.design_graph(design)
    result = sim2d.simulate(g, lambda obs, s, t: np.zeros((4, g.action_dim)), n=4, steps=200, seed=1)
    s = result.states                                      # (4, 201, S)
    nominal_y = sim2d.nominal_state(g)[1]
    assert np.all(np.abs(s[:, -20:, 1] - nominal_y) < 0.02), "height drifted from nominal"
    assert np.all(np.abs(s[:, -20:, 2]) < 0.05), "not level"
    assert np.all(np.abs(result.distance_m) <= 0.05), "crept away"         # issue #11: |drift| <= 0.05 m
    assert not result.flipped.any()


def test_random_codes_random_and_out_of_range_actions_do_not_blow_up():
    rng = np.random.default_rng(0)
    codes = rng.choice(sim2d.all_designs(), 12, replace=False)
    for code in codes:
        g = sim2d.design_graph(code)
        world = sim2d.World(g, n=3, seed=int(rng.integers(1000)))
        world.reset()
        actions = sim2d.random_spline_actions(rng, 3, g.action_dim, 60, std=3.0) * 5.0   # beyond [-1, 1]
        for t in range(60):
            obs, r, term, trunc, info = world.step(actions[:, t] * 5.0)
            assert np.isfinite(info["state"]).all() and np.isfinite(r).all()
        assert np.abs(info["state"][:, 3:]).max() < 50, f"{code} blew up"


def test_non_finite_actions_are_refused():
    world = sim2d.World("car")
    world.reset(seed=0)
    with pytest.raises(ValueError, match="finite"):
        world.step(np.full((1, 4), np.nan))


def test_same_seed_same_trajectory_other_seed_other_start():
    def run(seed):
        g = sim2d.design_graph("leg_leg_wheel")
        actions = sim2d.random_spline_actions(np.random.default_rng(seed), 2, g.action_dim, 50)
        return sim2d.simulate(g, lambda obs, s, t: actions[:, t], n=2, steps=50, seed=seed).states
    a, b, c = run(3), run(3), run(4)
    assert np.array_equal(a, b)
    assert not np.allclose(a[:, 0], c[:, 0])


def test_torch_reward_agrees_with_simulated_progress():
    g = sim2d.design_graph("car")
    world = sim2d.World(g, n=3)
    _, info = world.reset(seed=0)
    s0, total = info["state"], 0.0
    a = np.full((3, g.action_dim), -1.0)                  # drive forward
    for _ in range(24):
        _, r, _, _, info = world.step(a)
        total = total + r
    progress = info["state"][:, 0] - s0[:, 0]
    assert np.all(progress > 1.0)
    assert np.allclose(total, progress, atol=0.05 * progress.max())   # penalties are small
    s = torch.tensor(s0, requires_grad=True)
    sim2d.reward(s, torch.tensor(a), s * 1.01, g).sum().backward()
    assert torch.isfinite(s.grad).all() and s.grad.abs().sum() > 0


def test_observation_has_no_x_and_no_linear_velocity():
    g = sim2d.design_graph("leg_none_wheel")
    s = np.tile(sim2d.nominal_state(g), (2, 1))
    obs = sim2d.observe(s, g)
    s2 = s.copy()
    s2[:, 0] += 5.0                                        # x
    s2[:, 3:5] += 1.0                                      # vx, vy
    obs2 = sim2d.observe(s2, g)
    for k in obs:
        assert np.array_equal(obs[k], obs2[k])
    assert obs["body"].shape == (2, 3) and obs["leg"].shape == (2, 2, 4) and obs["wheel"].shape == (2, 2, 1)
    s3 = s.copy()
    s3[:, 1] += 0.1                                        # height is observed
    assert not np.array_equal(sim2d.observe(s3, g)["body"], obs["body"])


def test_observe_gives_the_same_numbers_on_torch_tensors_and_numpy_arrays():
    """The torch path (model roll-outs) uses index and noise-std tensors made once; the numpy
    path (the simulator) plain arrays: both are the same function O."""
    g = sim2d.design_graph("leg_none_wheel")
    rng = np.random.default_rng(0)
    s = sim2d.sample_initial_states(g, 5, rng).astype(np.float32)
    noise = sim2d.obs_noise_like(s, g, rng)
    for n in (None, noise):
        on_numpy = sim2d.observe(s, g, n)
        on_torch = sim2d.observe(torch.tensor(s), g, None if n is None else {k: torch.tensor(v, dtype=torch.float32)
                                                                             for k, v in n.items()})
        for k in on_numpy:
            assert on_torch[k].dtype == torch.float32
            assert np.allclose(on_torch[k].numpy(), on_numpy[k], atol=1e-6)
    assert np.array_equal(sim2d.observe(s, g)["body"], s[:, [1, 2, 5]])


def test_batched_world_matches_single_worlds():
    g = sim2d.design_graph("hexapod")
    starts = sim2d.sample_initial_states(g, 3, np.random.default_rng(7))
    actions = sim2d.random_spline_actions(np.random.default_rng(8), 3, g.action_dim, 40)
    batched = sim2d.World(g, n=3)
    batched.reset(options={"states": starts})
    for t in range(40):
        batched.step(actions[:, t])
    for i in range(3):
        single = sim2d.World(g, n=1)
        single.reset(options={"states": starts[i:i + 1]})
        for t in range(40):
            single.step(actions[i:i + 1, t])
        assert np.array_equal(single.state[0], batched.state[i])


def test_reset_state_round_trips_and_flip_is_detected():
    g = sim2d.design_graph("hexapod")
    s = sim2d.sample_initial_states(g, 2, np.random.default_rng(0))
    world = sim2d.World(g, n=2)
    _, info = world.reset(options={"states": s})
    assert np.allclose(info["state"], s, atol=1e-9)
    upside_down = s.copy()
    upside_down[:, 2] = np.pi                              # on its back, legs up
    upside_down[:, 1] = sim2d.standing_height(g, upside_down)
    world.reset(options={"states": upside_down})
    _, _, terminated, _, info = world.step(np.zeros((2, g.action_dim)))
    assert terminated.all() and info["flipped"].all()


def test_spline_actions_are_smooth_and_bounded():
    a = sim2d.random_spline_actions(np.random.default_rng(0), 5, 3, 100)
    assert a.shape == (5, 100, 3) and np.abs(a).max() <= 1.0
    steps = np.abs(np.diff(a, axis=1))                     # white noise would give ~0.8 on average
    assert steps.mean() < 0.1 and steps.max() < 0.6        # 10 knots over 100 steps: no jumps
    assert a.std() > 0.3


def test_spline_actions_pass_through_their_knots_drawn_with_the_given_std():
    """Sec. III-B: 10 N(0, std^2) values per DoF, joined by the spline; over 100 steps the spline
    parameter is a whole number at steps 0, 11, ..., 99, where the action is that knot's value."""
    a = sim2d.random_spline_actions(np.random.default_rng(3), 4, 2, 100, std=0.3)
    knots = np.random.default_rng(3).normal(0.0, 0.3, (4, 10, 2))           # the same draws
    np.testing.assert_allclose(a[:, ::11], np.clip(knots, -1, 1), atol=1e-12)
    assert 0.2 < a.std() < 0.4                                               # between knots: a smooth curve


def test_wave_actions_swing_each_joint_at_the_episodes_period_and_keep_the_joints_off_their_limits():
    """--random-waves: per episode one period in 0.3-1.2 s shared by every DoF, per DoF its own
    amplitude in 0.3-1 and phase.  In the simulator the hexapod's joints rest at a limit far less
    often than under the paper's splines (part 7 of docs/history/2026-12-plain-rl-diagnosis.md)."""
    a = sim2d.random_wave_actions(np.random.default_rng(0), 32, 12, 100)
    assert a.shape == (32, 100, 12) and np.abs(a).max() <= 1.0
    spectrum = np.abs(np.fft.rfft(a - a.mean(1, keepdims=True), n=1200, axis=1))       # (32, 601, 12)
    hz = np.fft.rfftfreq(1200, sim2d.CONTROL_DT)[spectrum.argmax(1)]                      # (32, 12) peak per DoF
    assert ((hz > 1 / 1.2 - 0.05) & (hz < 1 / 0.3 + 0.05)).all()
    assert (np.ptp(hz, axis=1) < 0.05).all()                                            # one period per episode
    assert np.ptp(hz[:, 0]) > 1.0                                                       # episodes differ
    half_range = np.ptp(a, axis=1) / 2                                                  # (32, 12) amplitudes
    assert half_range.min() > 0.25 and half_range.max() <= 1.0 and half_range.std() > 0.1
    corr = np.corrcoef(a[0].T)[np.triu_indices(12, 1)]                                  # phases differ per DoF
    assert np.abs(corr).min() < 0.5

    g = sim2d.design_graph("hexapod")

    def at_limit(actions):
        run = sim2d.simulate(g, lambda obs, s, t: actions[:, t], 16, 100, seed=1)
        q = sim2d.split_state(run.states.reshape(-1, g.state_dim), g)["leg"][..., :2]
        limits = np.array([sim2d.HIP_LIMITS, sim2d.KNEE_LIMITS])                        # (2 joints, lo/hi)
        return (np.abs(q[..., None] - limits).min(-1) < 0.05).mean()

    splines = at_limit(sim2d.random_spline_actions(np.random.default_rng(0), 16, g.action_dim, 100))
    waves = at_limit(sim2d.random_wave_actions(np.random.default_rng(0), 16, g.action_dim, 100))
    assert splines > 0.5 and waves < 0.5 * splines


def test_rendering_writes_files(tmp_path):
    g = sim2d.design_graph("leg_none_wheel")
    states = sim2d.simulate(g, lambda obs, s, t: np.full((1, g.action_dim), -0.5), n=1, steps=6).states[0]
    sim2d.save_gif(g, states, str(tmp_path / "a.gif"))
    sim2d.save_gif(g, states, str(tmp_path / "b.gif"), every=2)
    sim2d.save_png(g, states, str(tmp_path / "a.png"))
    assert (tmp_path / "a.gif").stat().st_size > 1000 and (tmp_path / "a.png").stat().st_size > 1000
    from PIL import Image                                  # matplotlib's own dependency
    with Image.open(tmp_path / "a.gif") as a, Image.open(tmp_path / "b.gif") as b:
        assert (a.n_frames, b.n_frames) == (7, 4)          # states 0..6, and every second one
        frames = []
        for k in (0, 6):
            a.seek(k)
            frames.append(np.asarray(a.convert("RGB"), dtype=int))
    assert np.abs(frames[0] - frames[1]).sum() > 0         # the robot moved: each frame redrawn


def test_simulate_records_what_it_applied_and_passes_the_step():
    """The one simulation loop: act(obs, state, t) sees t = 0, 1, ...; actions are stored as
    applied (clipped to [-1, 1]); obs are the noisy per-module observations of the states."""
    g = sim2d.design_graph("leg_none_wheel")
    seen = []

    def act(obs, state, t):
        seen.append(t)
        assert obs["leg"].shape == (3, 2, 4) and state.shape == (3, g.state_dim)
        return np.full((3, g.action_dim), 2.0 * (-1) ** t)
    run = sim2d.simulate(g, act, n=3, steps=5, seed=0)
    assert seen == [0, 1, 2, 3, 4]
    assert run.states.shape == (3, 6, g.state_dim) and run.obs["wheel"].shape == (3, 5, 2, 1)
    assert np.array_equal(run.actions[:, :, 0], np.tile([1.0, -1.0, 1.0, -1.0, 1.0], (3, 1)))
    noise_free = sim2d.observe(run.states[:, :5], g)
    assert 0 < np.abs(run.obs["leg"] - noise_free["leg"]).max() < 0.5
    assert np.array_equal(run.distance_m, run.states[:, -1, 0] - run.states[:, 0, 0])


def test_reward_penalties_by_hand():
    """r = progress - W_PITCH pitch'^2 - W_EFFORT mean(a^2) - W_POSE mean over legs and joints
    of (q - q_nominal)^2, on a leg_none_wheel state worked out by hand."""
    g = sim2d.design_graph("leg_none_wheel")              # 2 legs, 2 wheels: S = 16, A = 6
    s, s_next = np.zeros(16), np.zeros(16)
    s_next[0], s_next[2] = 0.3, 0.5                       # 0.3 m forward, pitched 0.5 rad
    s_next[6:8] = sim2d.HIP_NOMINAL + 0.2, sim2d.KNEE_NOMINAL     # leg 1: hip 0.2 rad off
    s_next[10:12] = sim2d.HIP_NOMINAL, sim2d.KNEE_NOMINAL - 0.4   # leg 2: knee 0.4 rad off
    a = np.array([1.0, 0.0, 0.0, 0.0, -0.5, 0.5])
    by_hand = (0.3 - sim2d.W_PITCH * 0.25 - sim2d.W_EFFORT * (1 + 0.25 + 0.25) / 6
               - sim2d.W_POSE * (0.04 + 0.16) / 4)
    assert sim2d.reward(s, a, s_next, g) == pytest.approx(by_hand, abs=1e-12)
    assert sim2d.reward(s, a, s_next, g) < 0.3                   # every penalty lowers it
    torch_r = sim2d.reward(torch.tensor(s), torch.tensor(a), torch.tensor(s_next), g)
    assert torch_r.item() == pytest.approx(by_hand, abs=1e-12)

def test_set_motor_rates_moves_robots_exactly_as_the_public_rate_property():
    g = sim2d.design_graph("leg_leg_wheel")
    start = sim2d.sample_initial_states(g, 1, np.random.default_rng(5))[0]
    rates = sim2d.random_spline_actions(np.random.default_rng(6), 1, g.action_dim, 30)[0] \
        * sim2d.joint_speed_scale(g)                       # (30, A) rad/s
    (public, motors_a), (fast, motors_b) = sim2d.build_robot(g, start), sim2d.build_robot(g, start)
    ptrs = [m._constraint for m in motors_b]
    for t in range(30):
        for motor, r in zip(motors_a, rates[t].tolist()):
            motor.rate = r
        sim2d.set_motor_rates(ptrs, rates[t].tolist())
        assert [m.rate for m in motors_a] == [m.rate for m in motors_b]
        for _ in range(sim2d.STEPS_PER_ACTION * sim2d.PHYSICS_SUBSTEPS):
            public.step(sim2d.SUBSTEP_DT)
            fast.step(sim2d.SUBSTEP_DT)
        state = [(b.position, b.angle, b.velocity, b.angular_velocity) for b in public.bodies]
        assert state == [(b.position, b.angle, b.velocity, b.angular_velocity) for b in fast.bodies]


def test_step_space_moves_robots_exactly_as_space_step():
    g = sim2d.design_graph("hexapod")
    start = sim2d.sample_initial_states(g, 1, np.random.default_rng(5))[0]
    rates = sim2d.random_spline_actions(np.random.default_rng(6), 1, g.action_dim, 30)[0] \
        * sim2d.joint_speed_scale(g)                       # (30, A) rad/s
    (public, motors_a), (fast, motors_b) = sim2d.build_robot(g, start), sim2d.build_robot(g, start)
    for t in range(30):
        for a, b, r in zip(motors_a, motors_b, rates[t].tolist()):
            a.rate = b.rate = r
        for _ in range(sim2d.STEPS_PER_ACTION * sim2d.PHYSICS_SUBSTEPS):
            public.step(sim2d.SUBSTEP_DT)
        sim2d.step_space(fast, sim2d.STEPS_PER_ACTION * sim2d.PHYSICS_SUBSTEPS)
        state = [(b.position, b.angle, b.velocity, b.angular_velocity) for b in public.bodies]
        assert state == [(b.position, b.angle, b.velocity, b.angular_velocity) for b in fast.bodies]


def test_contacts_and_joints_hold_under_bang_bang_actions():
    # The physics targets on a small sample (the full check: python tools/check_physics.py).
    # Measured 1.65 cm / 0.76 cm / 0.035 rad; the world before the repair (2 cm ground, 1/60 s
    # steps, 10 iterations, 4e5 leg torque, no armature) failed all three: 23.7 cm / 8.8 cm / 0.43 rad.
    result = check_physics.check_physics(["hexapod"], random_codes=2, n=4, steps=60, kinds=("bang-bang",))
    assert [r["code"] for r in result["rows"]] == ["llllll"] + check_physics.check_codes(["hexapod"], 2)[1:]
    assert result["rows"][0]["pymunk_steps"] == 60 * sim2d.STEPS_PER_ACTION * sim2d.PHYSICS_SUBSTEPS
    assert result["max_penetration_cm"] <= 2.0
    assert result["max_joint_gap_cm"] <= 1.0
    assert result["max_limit_violation_rad"] <= 0.05


def test_contact_and_joint_errors_of_a_known_pose():
    g = sim2d.design_graph("lnnnnn")                       # one leg: body, thigh, shin
    space, _ = sim2d.build_robot(g, sim2d.nominal_state(g))
    geometry = check_physics.robot_geometry(space)
    raw = np.array([[b.position.x, b.position.y, b.angle] for b in space.bodies])[None]   # (1, 3, 3)
    errors = check_physics.contact_and_joint_errors(raw, geometry)
    assert errors["penetration_cm"] < 1e-9 and errors["joint_gap_cm"] < 1e-9   # it stands on the ground
    assert errors["limit_violation_rad"] == 0.0
    raw[0, 0, 1] -= 50.0                                   # the body 50 cm lower: its hip anchor 50 cm from the thigh's
    raw[0, 2, 2] = raw[0, 1, 2] - 2.5                      # the shin turned so that the knee is 0.3 rad past -2.2
    errors = check_physics.contact_and_joint_errors(raw, geometry)
    assert np.isclose(errors["joint_gap_cm"], 50.0) and np.isclose(errors["limit_violation_rad"], 0.3)
    body_bottom = raw[0, 0, 1] - sim2d.BODY_HEIGHT / 2     # the level body's lowest corners
    assert np.isclose(errors["penetration_cm"], geometry["surface"] - body_bottom)


def test_check_physics_command_line_ends_with_one_summary_line(capsys):
    # Each summary figure, under its own key, is the maximum of its column in the table printed above it
    # and check_physics's own result for the same arguments, to the printed precision.
    assert check_physics.main(["--random-codes", "1", "--robots", "2", "--steps", "20"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert [i for i, line in enumerate(lines) if "=" in line] == [len(lines) - 1]   # the only key=value line
    summary = dict(kv.split("=") for kv in lines[-1].split())
    assert list(summary) == ["max_penetration_cm", "max_joint_gap_cm", "max_limit_violation_rad"]
    assert lines[0].split() == ["design", "actions", "penetration_cm", "joint_gap_cm", "limit_rad", "flips"]
    assert lines[-2].startswith("2 robots x 20 control steps x 20 pymunk steps")
    # table rows: [kind, penetration, gap, limit, flips], the names may hold spaces ("1 random code")
    rows = [line.removesuffix("(max, flips summed)").split()[-5:] for line in lines[1:-2]]
    result = check_physics.check_physics(sim2d.NAMED_DESIGNS, random_codes=1, n=2, steps=20)
    assert len(rows) == len(result["rows"]) + len(check_physics.CHECK_KINDS)   # + the random code, per kind
    for column, key, digits in ((1, "max_penetration_cm", 2), (2, "max_joint_gap_cm", 2),
                                (3, "max_limit_violation_rad", 3)):
        table_max = max((r[column] for r in rows), key=float)
        assert summary[key] == table_max == f"{result[key]:.{digits}f}", key


def test_check_physics_runs_as_a_script_from_the_repository_root():
    """`python tools/check_physics.py` finds the stage files one folder up; its last line is the summary."""
    out = subprocess.run([sys.executable, "tools/check_physics.py", "--design", "car", "--random-codes", "0",
                          "--robots", "1", "--steps", "3"], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert len(out.stdout.splitlines()) == 5 and out.stdout.splitlines()[-1].startswith("max_penetration_cm=")
