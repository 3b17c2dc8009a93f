"""The planar world as a gymnasium.Env: one robot of any design, registered as "ModularRobot-v0".

    import gymnasium
    import interfaces.gymnasium_env                      # registers ModularRobot-v0 on import
    env = gymnasium.make("ModularRobot-v0", design="hexapod")          # a name or a 6-letter code
    obs, info = env.reset(seed=0)
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample())

or, without the import, gymnasium.make("interfaces.gymnasium_env:ModularRobot-v0", design="car")
(gymnasium imports the module named before the colon).  Everything is sim2d's: the env runs a
sim2d.World of n = 1 robot, so the starts p(s), the physics, the sensor noise, the reward
(sim2d.reward) and the flip (the World's `terminated`: |pitch| > sim2d.FLIP_PITCH) are the ones
training uses; this file only flattens the observation and counts nothing of its own.

* observation: Box(obs_dim,) float32, sim2d.observe's per-module dict (noise included) flattened
  in the order body [y, pitch, pitch_rate], legs [q_hip, q_knee, dq_hip, dq_knee] each, wheels
  [dq_wheel] each: the order of sim2d.obs_noise_like's draws (`flat_observation`).
* action: Box(action_dim,) in [-1, 1], normalised joint-velocity commands [hip, knee] per leg,
  then one per wheel, held for one control step of 1/12 s.
* reset(seed=s): the start and the noise come from the env's np_random, so an episode from
  reset(seed=s) is exactly sim2d.simulate(design, act, n=1, seed=s)'s.  options={"states": (S,)}
  starts from a given flat state instead.  info["state"]: the true flat state (S,), float64.
* terminated: the robot flipped; truncated: `episode_steps` control steps were taken (default
  100, training's episode length: modular_rlil_minimal.Config.episode_steps), also exposed as
  env.max_episode_steps and env.spec.max_episode_steps.  gymnasium.make(..., max_episode_steps=N)
  only adds gymnasium's TimeLimit on top, which can shorten an episode but not lengthen it:
  pass episode_steps=N to change its length.
* render_mode="rgb_array": render() returns an (H, W, 3) uint8 frame drawn by sim2d's GIF code.

Many robots: gymnasium.vector.SyncVectorEnv over this env works (tests/test_interfaces.py), but
sim2d.World(design, n=N) is the faster path: one Python loop over N pymunk spaces, the state of
all N read in bulk (pymunk.batch) and reward and observation computed once on (N, S) arrays,
where SyncVectorEnv pays an env's Python overhead (its wrappers, a reset check, one small array
per robot) N times per step.  Measured on a 2-core machine, 16 robots, 99 steps of zero actions:
65 against 150 us per robot step (hexapod), 41 against 110 (car), World against SyncVectorEnv.
"""
from __future__ import annotations

import dataclasses

import gymnasium
import numpy as np
from gymnasium import spaces

import modular_rlil_minimal as rlil
import sim2d

ID = "ModularRobot-v0"
EPISODE_STEPS = rlil.Config.episode_steps       # 100 control steps: training's episode length
DEFAULT_DESIGN = "leg_none_wheel"               # the README's main command's design


def flat_observation(obs: dict, graph: sim2d.DesignGraph) -> np.ndarray:
    """sim2d.observe's {"body": (N, 3), "leg": (N, L, 4), "wheel": (N, W, 1)} -> (N, obs_dim) float32."""
    n = len(obs["body"])
    flat = np.concatenate([obs["body"], obs["leg"].reshape(n, graph.n_legs * sim2d.LEG_OBS_DIM),
                           obs["wheel"].reshape(n, graph.n_wheels * sim2d.WHEEL_OBS_DIM)], -1)
    return flat.astype(np.float32)


class ModularRobotEnv(gymnasium.Env):
    """One robot of `design` (a name or a 6-letter code, as sim2d.parse_design accepts) in sim2d's world."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": round(1 / sim2d.CONTROL_DT)}

    def __init__(self, design: str = DEFAULT_DESIGN, episode_steps: int = EPISODE_STEPS,
                 render_mode: str | None = None):
        self.graph = sim2d.design_graph(design)
        if isinstance(episode_steps, bool) or not isinstance(episode_steps, (int, np.integer)) or episode_steps < 1:
            raise ValueError(f"episode_steps must be a positive whole number of control steps, got {episode_steps!r}")
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be None or one of {self.metadata['render_modes']}, got {render_mode!r}")
        self.max_episode_steps = int(episode_steps)
        self.render_mode = render_mode
        self.world = sim2d.World(self.graph, n=1, max_steps=self.max_episode_steps)
        self.observation_space = spaces.Box(-np.inf, np.inf, (self.graph.obs_dim,), np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, (self.graph.action_dim,), np.float32)
        self._states: list[np.ndarray] = []            # this episode's true states, for render()
        self._figure = None

    # gymnasium.make sets env.spec with max_episode_steps=None when the registration has none (and
    # ours has none, so that make adds no TimeLimit): fill in the length this env truncates at.
    @property
    def spec(self):
        return self._spec

    @spec.setter
    def spec(self, value):
        if value is not None and value.max_episode_steps is None:
            value = dataclasses.replace(value, max_episode_steps=self.max_episode_steps)
        self._spec = value

    _spec = None

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        self.world.np_random = self.np_random          # p(s) and the sensor noise draw from the env's generator
        obs, info = self.world.reset(options=options)
        self._states = [info["state"][0]]
        return flat_observation(obs, self.graph)[0], {"state": info["state"][0].copy()}

    def step(self, action):
        if not self._states:
            raise RuntimeError("call reset() before step()")
        obs, reward, terminated, truncated, info = self.world.step(np.asarray(action, dtype=float)[None])
        self._states.append(info["state"][0])
        return (flat_observation(obs, self.graph)[0], float(reward[0]), bool(terminated[0]), bool(truncated[0]),
                {"state": info["state"][0].copy(), "flipped": bool(info["flipped"][0])})

    def render(self):
        """The current frame as the project's GIFs draw it (sim2d.save_gif): (H, W, 3) uint8."""
        if self.render_mode is None:
            gymnasium.logger.warn("render() without render_mode: make the env with render_mode='rgb_array'")
            return None
        if not self._states:
            raise RuntimeError("call reset() before render()")
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
        states = np.stack(self._states)
        if self._figure is None:                       # the figure of save_gif, drawn off-screen (no pyplot)
            fig = Figure(figsize=(8, 3.4), dpi=80)
            FigureCanvasAgg(fig)
            ax = fig.add_subplot()
            sim2d._style_axes(ax, states[-1, 0] / sim2d.M_PER_CM)
            self._figure, self._robot = (fig, ax), []
        fig, ax = self._figure
        for artist in self._robot:                     # per frame: move the view, redraw only the robot
            artist.remove()
        sim2d._style_axes(ax, states[-1, 0] / sim2d.M_PER_CM, static=False)
        self._robot = sim2d._draw_robot(ax, self.graph, states[-1], sim2d._wheel_angles(self.graph, states)[-1])
        t = len(states) - 1
        ax.set_title(f"{self.graph.name}   t = {t * sim2d.CONTROL_DT:4.1f} s   "
                     f"distance = {states[-1, 0] - states[0, 0]:5.2f} m", fontsize=13)
        fig.canvas.draw()
        return np.asarray(fig.canvas.buffer_rgba())[..., :3].copy()

    def close(self):
        self._figure = None
        super().close()


if ID not in gymnasium.registry:                       # importing twice (or a reload) registers once
    gymnasium.register(id=ID, entry_point=f"{__name__}:ModularRobotEnv")
