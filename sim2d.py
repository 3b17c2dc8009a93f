"""The planar modular-robot world: designs, physics, state, observation, reward.

Paper (Whitman & Choset, "Learning Modular Robot Locomotion from
Demonstrations"): Sec. III-A "Problem formulation" (state s, observation
function O, reward r, initial-state distribution p(s)), Sec. III-B "Gather
trajectories with random actions" (spline actions) and Sec. IV "Experiments"
(1/60 s physics steps, one action held for 5 of them, distance in 200 steps).
The paper uses IsaacGym in 3-D; this is a pymunk side view (y up, +x forward).

    python sim2d.py --design hexapod --action random --gif hexapod.gif
    python tools/bench.py --world           # the world's speed against bare pymunk
    python tools/check_physics.py           # how far contacts and joints give

Conventions used by every other file
------------------------------------
* A design is six ports, each 'l' (leg), 'w' (wheel) or 'n' (none), in the
  paper authors' order: 0 front-left, 1 middle-left, 2 rear-left, 3 rear-right,
  4 middle-right, 5 front-right.  Ports i and 5-i sit at the same place along
  the body (left and right); in the plane they overlap and touch only the ground.
* Joint angle = child angle - parent angle, counter-clockwise positive (y up,
  +x forward).  A hip at 0 hangs its thigh straight down; a positive hip swings
  the foot forward.  A wheel turning at a negative rate rolls the robot forward.
* The flat state vector (metres, radians, seconds), grouped by module type:
      [x, y, pitch, vx, vy, pitch_rate,                 body      (6)
       q_hip, q_knee, dq_hip, dq_knee  for each leg,    legs      (4 each)
       dq_wheel                        for each wheel]  wheels    (1 each)
  limbs of one type in ascending port order.  Actions (normalised joint-velocity
  commands in [-1, 1]) use the same grouping: [hip, knee] per leg, then one
  drive command per wheel.
* The observation (the paper's O) is the state without x, vx and vy, plus
  Gaussian sensor noise, split per module the way the GNN consumes it:
      {"body": (N, 3) [y, pitch, pitch_rate],
       "leg": (N, n_legs, 4), "wheel": (N, n_wheels, 1)}
"""
from __future__ import annotations

import argparse
import itertools
import math
import os
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pymunk
import pymunk.batch
import torch

# ----------------------------------------------------------------------------
# Physics constants, all in one place.  Internal units: cm, kg, s.
# ----------------------------------------------------------------------------
GRAVITY = 981.0            # cm/s^2
PHYSICS_DT = 1.0 / 60.0    # s, the paper's simulator step
STEPS_PER_ACTION = 5       # physics steps one action is held (paper: 5 x 1/60 s)
CONTROL_DT = PHYSICS_DT * STEPS_PER_ACTION   # 1/12 s per control step
# Contacts and joints.  Each setting below was chosen with
# `python tools/check_physics.py`: the deepest reach of any shape below the
# ground / the widest pivot-joint gap / the largest joint-limit overshoot, after
# every pymunk step, over 24 designs x {bang-bang, spline} actions x 8 robots x
# 200 control steps; targets 2 cm / 1 cm / 0.05 rad.  The figures quoted are
# what that check gave with this setting changed and all the others as chosen
# (docs/world.md, "Contacts and joints"); as chosen: 1.76 cm / 0.91 cm / 0.045 rad.
PHYSICS_SUBSTEPS = 4       # pymunk steps of 1/240 s per 1/60 s physics step (ours, not the
                           # paper's).  pymunk acts on a contact or a joint limit only once it is
                           # already violated, so a foot hitting the ground at ~4 m/s sinks in by
                           # speed x step: 1 sub-step 8.3 cm / 4.5 cm / 0.186 rad, 2: 3.3 / 1.9 /
                           # 0.104, 3: 2.4 / 1.2 / 0.068.  Cost: the hexapod world runs at about
                           # 0.6 x the speed of 1 sub-step at 10 solver iterations (docs/world.md)
SUBSTEP_DT = PHYSICS_DT / PHYSICS_SUBSTEPS   # s, one pymunk step
SOLVER_ITERATIONS = 5      # per pymunk step (pymunk's default is 10): 3 left pivots 1.25 cm
                           # apart; 10 narrow the widest gap to 0.60 cm but slow the world by 22 %
COLLISION_BIAS = 0.5 ** 60   # fraction of a contact's overlap left after 1 s (pymunk's default
                             # 0.9 ** 60 corrects 10 % per 1/60 s, this 50 %): with the default
                             # a foot pressed into the ground crept to 1.96 cm
JOINT_ERROR_BIAS = 0.5 ** 60   # the same for pivot and limit joints: widest gap 1.06 cm with the default
BODY_LENGTH, BODY_HEIGHT, BODY_MASS = 90.0, 16.0, 8.0     # cm, cm, kg
PORT_X = (38.0, 0.0, -38.0)  # cm, hip/axle x in the body frame: front, middle, rear
MOUNT_Y = -BODY_HEIGHT / 2   # cm, hips and axles sit on the body's underside
THIGH, SHIN = 18.0, 18.0     # cm, leg link lengths
LINK_MASS = 0.5              # kg per leg link
LINK_ARMATURE = 300.0        # kg cm^2 added to each leg link's moment of inertia: the rotor
                             # inertia of a geared joint motor (IsaacGym's DOF "armature").  A bare
                             # link (20.8 kg cm^2) against the body (5,570) is too light for the
                             # solver: without it pivots came 2.3 cm apart and limits 0.14 rad over
LINK_RADIUS = 2.0            # cm, thickness of a link segment
FOOT_RADIUS = 2.5            # cm, round foot at the end of the shin
HIP_NOMINAL, KNEE_NOMINAL = 0.5, -1.0   # rad: the foot sits right under the hip
HIP_LIMITS, KNEE_LIMITS = (-0.6, 1.4), (-2.2, -0.1)   # rad (RotaryLimitJoint)
# Wheel radius = standing height of a nominal leg, so every design stands level.
WHEEL_RADIUS = (THIGH + SHIN) * math.cos(HIP_NOMINAL) + FOOT_RADIUS   # ~34.1 cm
WHEEL_MASS = 1.0             # kg, same as one leg (two links)
LEG_MAX_SPEED = 6.0          # rad/s at action 1 (hip and knee)
WHEEL_MAX_SPEED = 3.5        # rad/s at action 1: 3.5 * 34.1 cm = 1.19 m/s, close to
                             # the hexapod's tripod gait (docs/world.md)
LEG_MAX_TORQUE = 1.5e5       # kg cm^2/s^2, motor max_force (unbounded if unset).  4e5 pushes
                             # pivots 1.03 cm apart and feet 2.06 cm deep; at 1e5 the
                             # leg_none_wheel demonstrator nose-dives (0.42 m/s, 1.2e5: 0.99)
WHEEL_MAX_TORQUE = 2e5
FRICTION = 1.0               # ground, feet, wheels and body
GROUND_TOP = 0.0             # cm, height of the ground's surface
GROUND_THICKNESS = 100.0     # cm: the ground is a thick finite segment under y = GROUND_TOP.  A
                             # 2 cm one lets fast feet tunnel through and hook underneath (26.8 cm
                             # deep at 1/60 s steps, 1.97 cm at 1/240 s)
GROUND_X = (-5000.0, 20000.0)   # cm: 50 m behind to 200 m ahead of the start
FLIP_PITCH = math.pi / 2     # rad: |pitch| beyond this counts as flipped (`flipped`)
ROBOT_CAT, GROUND_CAT = 0b01, 0b10   # collision categories: limbs touch only ground

# Sensor noise of the observation function O (standard deviations).
OBS_NOISE_BODY = (0.005, 0.01, 0.05)      # y (m), pitch (rad), pitch rate (rad/s)
OBS_NOISE_LEG = (0.01, 0.01, 0.05, 0.05)  # joint angles (rad), joint rates (rad/s)
OBS_NOISE_WHEEL = (0.05,)                 # wheel rate (rad/s)
OBS_NOISE_STD = {"body": np.array(OBS_NOISE_BODY), "leg": np.array(OBS_NOISE_LEG),
                 "wheel": np.array(OBS_NOISE_WHEEL)}
OBS_NOISE_STD_TORCH = {k: torch.tensor(v, dtype=torch.float32)     # made once: `observe` runs
                       for k, v in OBS_NOISE_STD.items()}             # every model step
BODY_OBS_INDEX = [1, 2, 5]                # y, pitch, pitch_rate: the body state entries O keeps
BODY_OBS_INDEX_TORCH = torch.tensor(BODY_OBS_INDEX)

# Perturbation of initial states around the nominal pose (half-widths of uniform draws).
INIT_JOINT = 0.15          # rad, leg joint angles
INIT_PITCH = 0.05          # rad
INIT_DROP = 0.02           # m, extra height above touching the ground
INIT_BODY_VEL = 0.05       # m/s
INIT_PITCH_RATE = 0.1      # rad/s
INIT_JOINT_VEL = 0.2       # rad/s

# Reward weights (Sec. III-F "Train policy using model and RL"): forward progress in metres dominates.
W_PITCH = 0.02             # per rad^2 of pitch
W_EFFORT = 0.002           # per mean squared normalised action
W_POSE = 0.005             # per mean squared leg-joint distance from nominal (rad^2)

M_PER_CM = 0.01            # metres per cm: the state vector is in metres, pymunk in cm

NAMED_DESIGNS = {
    "hexapod": "llllll",
    "car": "wnwwnw",
    "leg_leg_wheel": "llwwll",
    "leg_none_wheel": "lnwwnl",
}
LIMB_TYPES = {"l": "leg", "w": "wheel"}
LEG_DIM, WHEEL_DIM, BODY_DIM = 4, 1, 6       # state entries per module
LEG_OBS_DIM, WHEEL_OBS_DIM, BODY_OBS_DIM = 4, 1, 3
LEG_ACT_DIM, WHEEL_ACT_DIM = 2, 1


# ----------------------------------------------------------------------------
# Designs and the design graph
# ----------------------------------------------------------------------------
def parse_design(design: str) -> str:
    """Return the six-letter port code of a design name or code.

    >>> parse_design("leg-none-wheel")
    'lnwwnl'
    """
    key = design.strip().lower().replace("-", "_")
    if key in NAMED_DESIGNS:
        return NAMED_DESIGNS[key]
    code = key.replace("_", "")
    if len(code) == 6 and set(code) <= set("lwn"):
        if code == "nnnnnn":
            raise ValueError(f"design {design!r} has no limbs: at least one port must be 'l' or 'w'")
        return code
    raise ValueError(
        f"unknown design {design!r}: use one of {', '.join(NAMED_DESIGNS)} or six letters "
        "from l (leg), w (wheel), n (none), ports front-left to front-right, e.g. lnwwnl")


def design_name(code: str) -> str:
    """The readable name of a code (the named design, or the code itself)."""
    return next((name for name, c in NAMED_DESIGNS.items() if c == code), code)


def all_designs() -> list[str]:
    """All 3^6 - 1 = 728 codes with at least one limb."""
    return ["".join(p) for p in itertools.product("lwn", repeat=6) if set(p) != {"n"}]


@dataclass(frozen=True)
class DesignGraph:
    """A design as a graph: one body node with a child node per limb.

    Node 0 is the body; nodes 1.. are the legs (ascending port), then the
    wheels (ascending port), the order of the state, observation and action.
    """

    code: str

    @property
    def name(self) -> str:
        return design_name(self.code)

    @property
    def leg_ports(self) -> tuple[int, ...]:
        return tuple(i for i, c in enumerate(self.code) if c == "l")

    @property
    def wheel_ports(self) -> tuple[int, ...]:
        return tuple(i for i, c in enumerate(self.code) if c == "w")

    @property
    def n_legs(self) -> int:
        return len(self.leg_ports)

    @property
    def n_wheels(self) -> int:
        return len(self.wheel_ports)

    @property
    def nodes(self) -> list[tuple[str, int | None]]:
        """(type, port) per node: [("body", None), ("leg", 0), ..., ("wheel", 2), ...]."""
        return ([("body", None)] + [("leg", p) for p in self.leg_ports]
                + [("wheel", p) for p in self.wheel_ports])

    @property
    def edges(self) -> list[tuple[int, int]]:
        """(body node, limb node) per limb: the design graph is a star."""
        return [(0, k) for k in range(1, 1 + self.n_legs + self.n_wheels)]

    @property
    def state_dim(self) -> int:
        return BODY_DIM + LEG_DIM * self.n_legs + WHEEL_DIM * self.n_wheels

    @property
    def action_dim(self) -> int:
        return LEG_ACT_DIM * self.n_legs + WHEEL_ACT_DIM * self.n_wheels

    @property
    def obs_dim(self) -> int:
        return BODY_OBS_DIM + LEG_OBS_DIM * self.n_legs + WHEEL_OBS_DIM * self.n_wheels


def design_graph(design: str | DesignGraph) -> DesignGraph:
    """The design graph of a name or code (a DesignGraph passes through)."""
    return design if isinstance(design, DesignGraph) else DesignGraph(parse_design(design))


# ----------------------------------------------------------------------------
# State, observation and reward: plain slicing, so they work on numpy arrays
# and torch tensors alike (torch for the model roll-outs, with gradients).
# ----------------------------------------------------------------------------
def split_state(s, graph: DesignGraph) -> dict:
    """Flat state (..., S) -> {"body": (..., 6), "leg": (..., L, 4), "wheel": (..., W, 1)}."""
    nl, nw = graph.n_legs, graph.n_wheels
    legs = s[..., BODY_DIM:BODY_DIM + LEG_DIM * nl]
    wheels = s[..., BODY_DIM + LEG_DIM * nl:]
    return {"body": s[..., :BODY_DIM],
            "leg": legs.reshape(*s.shape[:-1], nl, LEG_DIM),
            "wheel": wheels.reshape(*s.shape[:-1], nw, WHEEL_DIM)}


def split_action(a, graph: DesignGraph) -> dict:
    """Flat action (..., A) -> {"leg": (..., L, 2), "wheel": (..., W, 1)}."""
    nl, nw = graph.n_legs, graph.n_wheels
    return {"leg": a[..., :LEG_ACT_DIM * nl].reshape(*a.shape[:-1], nl, LEG_ACT_DIM),
            "wheel": a[..., LEG_ACT_DIM * nl:].reshape(*a.shape[:-1], nw, WHEEL_ACT_DIM)}


def observe(s, graph: DesignGraph, noise: dict | None = None) -> dict:
    """The observation function O: drop x, vx, vy; add sensor noise.

    `noise` holds standard-normal draws shaped like the result (or None for a
    noiseless observation); they are scaled by OBS_NOISE_* here.
    """
    parts, torch_in = split_state(s, graph), isinstance(s, torch.Tensor)
    index = BODY_OBS_INDEX_TORCH if torch_in else BODY_OBS_INDEX
    obs = {"body": parts["body"][..., index],            # (..., 3) y, pitch, pitch_rate
           "leg": parts["leg"], "wheel": parts["wheel"]}
    if noise is not None:
        std = OBS_NOISE_STD_TORCH if torch_in else OBS_NOISE_STD
        obs = {k: v + std[k] * noise[k] for k, v in obs.items()}
    return obs


def obs_noise_like(s, graph: DesignGraph, rng: np.random.Generator | None = None) -> dict:
    """Standard-normal draws for `observe`, from a numpy rng or (tensors) torch.

    One draw of (..., obs_dim) split per module, in the order body, legs, wheels.
    """
    lead = tuple(s.shape[:-1])
    flat = (torch.randn(lead + (graph.obs_dim,), dtype=s.dtype) if isinstance(s, torch.Tensor)
            else rng.standard_normal(lead + (graph.obs_dim,)))
    nl = BODY_OBS_DIM + LEG_OBS_DIM * graph.n_legs
    return {"body": flat[..., :BODY_OBS_DIM],
            "leg": flat[..., BODY_OBS_DIM:nl].reshape(lead + (graph.n_legs, LEG_OBS_DIM)),
            "wheel": flat[..., nl:].reshape(lead + (graph.n_wheels, WHEEL_OBS_DIM))}


def nominal_joint_angles(graph: DesignGraph):
    """(L, 2) nominal [hip, knee] per leg."""
    return np.tile([HIP_NOMINAL, KNEE_NOMINAL], (graph.n_legs, 1))


def reward(s, a, s_next, graph: DesignGraph):
    """r(s_t, a_t, s_t+1) (Sec. III-F), one value per robot, differentiable.

    Forward progress in metres, minus small penalties on pitch, control effort
    and leg-joint distance from the nominal pose.  Summed over 200 control
    steps the progress term is the paper's metric, distance travelled.
    s, s_next: (..., S); a: (..., A) normalised actions; torch tensors (model roll-outs,
    with gradients) or numpy arrays (the simulator), the same arithmetic either way.
    """
    progress = s_next[..., 0] - s[..., 0]                              # (...,) metres
    pitch_cost = W_PITCH * s_next[..., 2] ** 2
    effort_cost = W_EFFORT * (a ** 2).mean(-1)
    if graph.n_legs:
        legs = split_state(s_next, graph)["leg"]                       # (..., L, 4)
        pose_cost = W_POSE * ((legs[..., 0] - HIP_NOMINAL) ** 2 + (legs[..., 1] - KNEE_NOMINAL) ** 2).mean(-1) / 2
    else:
        pose_cost = 0.0
    return progress - pitch_cost - effort_cost - pose_cost


def is_flipped(s) -> np.ndarray:
    """(...,) bool: the robot in state s (..., S) has flipped, |pitch| > FLIP_PITCH; the World's
    `terminated`, which ends an episode for PPO and the Gymnasium env."""
    return np.abs(s[..., 2]) > FLIP_PITCH


# ----------------------------------------------------------------------------
# Initial states p(s) and random spline actions (Sec. III-B)
# ----------------------------------------------------------------------------
def forward_kinematics(graph: DesignGraph, s: np.ndarray) -> dict:
    """Joint and contact points (cm, world frame) of robots in states s (N, S).

    Returns {"corners": (N, 4, 2) body box, "hip": (N, L, 2), "knee": (N, L, 2),
    "foot": (N, L, 2), "axle": (N, W, 2)}.  Used to place a perturbed robot on
    the ground and to draw any state trajectory, simulated or model-predicted.
    """
    x, y, pitch = s[:, 0] / M_PER_CM, s[:, 1] / M_PER_CM, s[:, 2]
    c, si = np.cos(pitch)[:, None], np.sin(pitch)[:, None]

    def to_world(px, py):                 # body-frame points (K,), (K,) -> world (N, K, 2)
        px, py = px[None], py[None]
        return np.stack([x[:, None] + px * c - py * si, y[:, None] + px * si + py * c], -1)

    def mount_x(ports):
        return np.array([PORT_X[min(p, 5 - p)] for p in ports])

    corners = to_world(np.array([-1, 1, 1, -1]) * BODY_LENGTH / 2,
                       np.array([-1, -1, 1, 1]) * BODY_HEIGHT / 2)
    hip = to_world(mount_x(graph.leg_ports), np.full(graph.n_legs, MOUNT_Y))
    axle = to_world(mount_x(graph.wheel_ports), np.full(graph.n_wheels, MOUNT_Y))
    q = split_state(s, graph)["leg"]                       # (N, L, 4)
    a1 = pitch[:, None] + q[..., 0]                        # thigh angle in the world
    knee = hip + THIGH * np.stack([np.sin(a1), -np.cos(a1)], -1)
    a2 = a1 + q[..., 1]                                    # shin angle in the world
    foot = knee + SHIN * np.stack([np.sin(a2), -np.cos(a2)], -1)
    return {"corners": corners, "hip": hip, "knee": knee, "foot": foot, "axle": axle}


def standing_height(graph: DesignGraph, s: np.ndarray) -> np.ndarray:
    """Body height (m) at which the lowest part of each robot just touches the ground."""
    s0 = s.copy()
    s0[:, 1] = 0.0
    fk = forward_kinematics(graph, s0)
    lowest = np.concatenate([fk["corners"][..., 1], fk["knee"][..., 1] - LINK_RADIUS,
                             fk["foot"][..., 1] - FOOT_RADIUS, fk["axle"][..., 1] - WHEEL_RADIUS],
                            axis=1).min(1)
    return (GROUND_TOP - lowest) * M_PER_CM


def nominal_state(graph: DesignGraph) -> np.ndarray:
    """(S,) the robot standing still in its nominal pose at x = 0."""
    s = np.zeros((1, graph.state_dim))
    parts = split_state(s, graph)
    parts["leg"][..., :2] = nominal_joint_angles(graph)
    s[:, 1] = standing_height(graph, s)
    return s[0]


def sample_initial_states(graph: DesignGraph, n: int, rng: np.random.Generator) -> np.ndarray:
    """(n, S) states perturbed from nominal (p(s) of eqn. 1), just above the ground."""
    s = np.tile(nominal_state(graph), (n, 1))
    parts = split_state(s, graph)          # views into s
    parts["leg"][..., :2] += rng.uniform(-INIT_JOINT, INIT_JOINT, (n, graph.n_legs, 2))
    parts["leg"][..., 2:] = rng.uniform(-INIT_JOINT_VEL, INIT_JOINT_VEL, (n, graph.n_legs, 2))
    parts["wheel"][...] = rng.uniform(-INIT_JOINT_VEL, INIT_JOINT_VEL, (n, graph.n_wheels, 1))
    s[:, 2] = rng.uniform(-INIT_PITCH, INIT_PITCH, n)
    s[:, 3:5] = rng.uniform(-INIT_BODY_VEL, INIT_BODY_VEL, (n, 2))
    s[:, 5] = rng.uniform(-INIT_PITCH_RATE, INIT_PITCH_RATE, n)
    lo, hi = zip(HIP_LIMITS, KNEE_LIMITS)
    parts["leg"][..., :2] = np.clip(parts["leg"][..., :2], lo, hi)
    s[:, 1] = standing_height(graph, s) + rng.uniform(0.0, INIT_DROP, n)
    return s


def random_spline_actions(rng: np.random.Generator, n: int, action_dim: int, steps: int = 100,
                          knots: int = 10, std: float = 1.0) -> np.ndarray:
    """(n, steps, action_dim) smooth random actions (Sec. III-B).

    Per robot and DoF, `knots` values drawn from N(0, std^2) are joined by a
    cubic (Catmull-Rom) spline over `steps` control steps, then clipped to [-1, 1].
    """
    values = rng.normal(0.0, std, (n, knots, action_dim))
    u = np.linspace(0.0, knots - 1, steps)                 # spline parameter per step
    i = np.clip(np.floor(u).astype(int), 0, knots - 2)
    t = (u - i)[None, :, None]
    pad = np.concatenate([values[:, :1], values, values[:, -1:]], 1)   # (n, knots + 2, A)
    p0, p1, p2, p3 = pad[:, i], pad[:, i + 1], pad[:, i + 2], pad[:, i + 3]
    spline = 0.5 * (2 * p1 + (p2 - p0) * t + (2 * p0 - 5 * p1 + 4 * p2 - p3) * t ** 2
                    + (3 * p1 - p0 - 3 * p2 + p3) * t ** 3)
    return np.clip(spline, -1.0, 1.0)


def random_wave_actions(rng: np.random.Generator, n: int, action_dim: int, steps: int = 100,
                        period: tuple = (0.3, 1.2), amplitude: tuple = (0.3, 1.0)) -> np.ndarray:
    """(n, steps, action_dim) random periodic actions (not the paper's; `--random-waves`).

    Per robot one period drawn uniformly from `period` (s; the hexapod demonstrator's gait takes
    0.5 s), and per DoF an amplitude from `amplitude` and a phase from [0, 2 pi):
    a_t = amplitude * sin(2 pi t CONTROL_DT / period + phase).  The joints swing back and forth
    around where they start instead of resting at a limit, as splines' slowly varying rates do;
    the phases are independent, so no gait is built in.
    """
    P = rng.uniform(*period, (n, 1, 1))
    amp = rng.uniform(*amplitude, (n, 1, action_dim))
    phase = rng.uniform(0.0, 2 * np.pi, (n, 1, action_dim))
    t = np.arange(steps)[None, :, None] * CONTROL_DT
    return amp * np.sin(2 * np.pi * t / P + phase)


# ----------------------------------------------------------------------------
# pymunk: one Space per robot (robots never share a collision search, and a
# robot's trajectory does not depend on how many others are simulated).
# ----------------------------------------------------------------------------
def _cross(w: float, r) -> pymunk.Vec2d:
    """Planar w x r: velocity of a point at offset r on a body turning at w."""
    return pymunk.Vec2d(-w * r[1], w * r[0])


# Robot shapes share one group (they never collide with each other) and touch only the ground.
LIMB_FILTER = pymunk.ShapeFilter(group=1, categories=ROBOT_CAT, mask=GROUND_CAT)


def _add_shape(space: pymunk.Space, shape: pymunk.Shape) -> pymunk.Shape:
    """Add a robot shape with the robot's friction and collision filter."""
    space.add(shape)
    shape.friction = FRICTION
    shape.filter = LIMB_FILTER
    return shape


def _point_velocity(body: pymunk.Body, p: pymunk.Vec2d) -> pymunk.Vec2d:
    """World velocity of the world point p fixed to `body`."""
    return body.velocity + _cross(body.angular_velocity, p - body.position)


def add_ground(space: pymunk.Space) -> pymunk.Shape:
    """The ground: a static segment GROUND_THICKNESS thick whose top is the line y = GROUND_TOP.

    Finite (GROUND_X), so that its bounding box stays small for pymunk's
    collision search; thick, so that nothing passes through it in one step.
    """
    r = GROUND_THICKNESS / 2
    ground = pymunk.Segment(space.static_body, (GROUND_X[0], GROUND_TOP - r), (GROUND_X[1], GROUND_TOP - r), r)
    ground.friction = FRICTION
    ground.filter = pymunk.ShapeFilter(categories=GROUND_CAT, mask=ROBOT_CAT)
    space.add(ground)
    return ground


def add_body(space: pymunk.Space, body_state) -> pymunk.Body:
    """The robot's body box in body state [x, y, pitch, vx, vy, pitch_rate] (m, rad, s)."""
    x, y, pitch, vx, vy, w = body_state
    body = pymunk.Body(BODY_MASS, pymunk.moment_for_box(BODY_MASS, (BODY_LENGTH, BODY_HEIGHT)))
    body.position, body.angle = (x / M_PER_CM, y / M_PER_CM), pitch
    body.velocity, body.angular_velocity = (vx / M_PER_CM, vy / M_PER_CM), w
    space.add(body)
    _add_shape(space, pymunk.Poly.create_box(body, (BODY_LENGTH, BODY_HEIGHT)))
    return body


def add_joint(space: pymunk.Space, parent: pymunk.Body, child: pymunk.Body, anchor: pymunk.Vec2d,
              limits: tuple[float, float] | None, max_torque: float) -> pymunk.SimpleMotor:
    """A revolute joint at the world point `anchor`: pivot, velocity motor, optional limits.

    The motor drives child.angular_velocity - parent.angular_velocity (the
    joint rate) to its rate, with torque up to max_torque; the limits bound
    child.angle - parent.angle (the joint angle).
    """
    motor = pymunk.SimpleMotor(child, parent, 0.0)
    motor.max_force = max_torque                         # torque limit: unbounded if unset
    joints = [pymunk.PivotJoint(parent, child, anchor)]
    if limits is not None:
        joints.append(pymunk.RotaryLimitJoint(parent, child, *limits))
    for joint in joints:
        joint.error_bias = JOINT_ERROR_BIAS
    space.add(joints[0], motor, *joints[1:])             # the order pymunk solves them in
    return motor


def add_link(space: pymunk.Space, angle: float, w_abs: float, top: pymunk.Vec2d, top_vel: pymunk.Vec2d,
             length: float) -> tuple[pymunk.Body, pymunk.Vec2d]:
    """A leg link hanging from `top` (world, cm) at world angle `angle`, turning at w_abs.

    Returns the link's body and its lower end (world, cm).
    """
    d = pymunk.Vec2d(math.sin(angle), -math.cos(angle))
    moment = pymunk.moment_for_segment(LINK_MASS, (0, length / 2), (0, -length / 2), LINK_RADIUS) + LINK_ARMATURE
    b = pymunk.Body(LINK_MASS, moment)
    b.position, b.angle = top + d * (length / 2), angle
    b.angular_velocity = w_abs
    b.velocity = top_vel + _cross(w_abs, d * (length / 2))
    space.add(b)
    _add_shape(space, pymunk.Segment(b, (0, length / 2), (0, -length / 2), LINK_RADIUS))
    return b, top + d * length


def add_leg(space: pymunk.Space, body: pymunk.Body, hip: pymunk.Vec2d, leg_state) -> list[pymunk.SimpleMotor]:
    """Thigh, shin and foot hanging from `hip` (world, cm) in leg state [q_hip, q_knee, dq_hip, dq_knee].

    Returns the [hip, knee] motors.
    """
    q_hip, q_knee, dq_hip, dq_knee = leg_state
    pitch, w = body.angle, body.angular_velocity
    thigh, knee = add_link(space, pitch + q_hip, w + dq_hip, hip, _point_velocity(body, hip), THIGH)
    hip_motor = add_joint(space, body, thigh, hip, HIP_LIMITS, LEG_MAX_TORQUE)
    shin, _ = add_link(space, pitch + q_hip + q_knee, w + dq_hip + dq_knee, knee,
                       _point_velocity(thigh, knee), SHIN)
    _add_shape(space, pymunk.Circle(shin, FOOT_RADIUS, (0, -SHIN / 2)))
    knee_motor = add_joint(space, thigh, shin, knee, KNEE_LIMITS, LEG_MAX_TORQUE)
    return [hip_motor, knee_motor]


def add_wheel(space: pymunk.Space, body: pymunk.Body, axle: pymunk.Vec2d, dq_wheel: float) -> pymunk.SimpleMotor:
    """A free-axle wheel at `axle` (world, cm) turning at dq_wheel relative to the body; its motor."""
    wheel = pymunk.Body(WHEEL_MASS, pymunk.moment_for_circle(WHEEL_MASS, 0, WHEEL_RADIUS))
    wheel.position, wheel.velocity = axle, _point_velocity(body, axle)
    wheel.angular_velocity = body.angular_velocity + dq_wheel
    space.add(wheel)
    _add_shape(space, pymunk.Circle(wheel, WHEEL_RADIUS))
    return add_joint(space, body, wheel, axle, None, WHEEL_MAX_TORQUE)


def build_robot(graph: DesignGraph, state: np.ndarray) -> tuple[pymunk.Space, list]:
    """A fresh Space holding the ground and one robot in `state` (S,).

    Returns the Space and the motors in action order.  Bodies are added in
    state order (body, then thigh and shin per leg, then wheels), which is the
    order `pymunk.batch` reads them back in.  Building a new Space for every
    reset is what makes runs reproducible (a reused Space keeps cached
    contact impulses).
    """
    space = pymunk.Space()
    space.gravity = (0.0, -GRAVITY)
    space.iterations = SOLVER_ITERATIONS
    space.collision_bias = COLLISION_BIAS
    add_ground(space)
    parts = split_state(state, graph)
    body = add_body(space, parts["body"])
    fk = forward_kinematics(graph, state[None])
    motors = []
    for k in range(graph.n_legs):
        motors += add_leg(space, body, pymunk.Vec2d(*fk["hip"][0, k]), parts["leg"][k])
    for k in range(graph.n_wheels):
        motors.append(add_wheel(space, body, pymunk.Vec2d(*fk["axle"][0, k]), parts["wheel"][k, 0]))
    return space, motors


_set_motor_rate = pymunk._chipmunk_cffi.lib.cpSimpleMotorSetRate   # private: use set_motor_rates


def set_motor_rates(motor_ptrs: list, rates: list[float]) -> None:
    """Set each motor's rate: exactly what `SimpleMotor.rate = r` does, for a list at once.

    motor_ptrs are the motors' C pointers (`motor._constraint`); rates are
    plain floats (rad/s).  `motor.rate = r` calls pymunk's C function
    cpSimpleMotorSetRate through two layers of Python property code; calling
    it directly (a private pymunk name, so it lives only here) is about 3x
    cheaper for a hexapod's 12 motors, and that property code cost as much as
    the rest of the world's overhead per robot step (docs/world.md, Speed).
    tests/test_sim2d.py checks that it moves robots exactly as `motor.rate = r` does.
    """
    list(map(_set_motor_rate, motor_ptrs, rates))


_space_step = pymunk._chipmunk_cffi.lib.cpSpaceStep   # private: use step_space


def step_space(space: pymunk.Space, steps: int) -> None:
    """Advance `space` by `steps` pymunk steps of SUBSTEP_DT: `space.step(SUBSTEP_DT)`, `steps` times.

    Calls pymunk's C function cpSpaceStep directly.  `space.step` wraps it in
    Python bookkeeping for objects added or removed during a step and for
    post-step callbacks, none of which the world uses; skipping it, 20 calls
    per control step, makes the hexapod world about 12 % faster (tools/bench.py
    --world).  tests/test_sim2d.py checks that it moves robots exactly as
    `space.step` does.
    """
    ptr = space._space
    for _ in range(steps):
        _space_step(ptr, SUBSTEP_DT)


_BODY_FIELDS = (pymunk.batch.BodyFields.POSITION | pymunk.batch.BodyFields.ANGLE
                | pymunk.batch.BodyFields.VELOCITY | pymunk.batch.BodyFields.ANGULAR_VELOCITY)


def joint_speed_scale(graph: DesignGraph) -> np.ndarray:
    """(A,) rad/s of each joint at action 1: normalised action -> motor rate."""
    return np.array([LEG_MAX_SPEED] * (LEG_ACT_DIM * graph.n_legs) + [WHEEL_MAX_SPEED] * graph.n_wheels)


class World:
    """N robots of one design, stepped together (a Gymnasium-style vector env).

    `reset(seed=...)` returns (obs, info); `step(actions)` returns (obs,
    rewards, terminated, truncated, info), where obs is the per-module dict of
    `observe`, terminated marks flipped robots (sticky; they keep being
    simulated) and truncated turns True after `max_steps` steps.  info["state"]
    is the flat (N, S) state; `reset` accepts options={"states": (N, S)} to
    start from given states instead of sampled ones.
    """

    def __init__(self, design: str | DesignGraph, n: int = 1, max_steps: int = 200, seed: int = 0):
        if n < 1:
            raise ValueError(f"number of robots must be at least 1, got {n}")
        self.graph = design_graph(design)
        self.n, self.max_steps = n, max_steps
        self.np_random = np.random.default_rng(seed)
        self.action_scale = joint_speed_scale(self.graph)
        self._buffer = pymunk.batch.Buffer()
        self.spaces: list[pymunk.Space] = []

    # -- state ---------------------------------------------------------------
    def read_state(self) -> np.ndarray:
        """(N, S) flat state of every robot, read in bulk with pymunk.batch.

        Per body pymunk.batch gives [px, py, angle, vx, vy, w] (cm, rad, s) in
        the order the bodies were added, the Space's static body last.
        """
        buf, chunks = self._buffer, []
        for space in self.spaces:
            buf.clear()
            pymunk.batch.get_space_bodies(space, _BODY_FIELDS, buf)
            chunks.append(bytes(buf.float_buf()))
        raw = np.frombuffer(b"".join(chunks)).reshape(self.n, -1, 6)   # (N, bodies + 1, 6)
        nl = self.graph.n_legs
        body, thigh, shin = raw[:, 0], raw[:, 1:1 + 2 * nl:2], raw[:, 2:2 + 2 * nl:2]
        wheel = raw[:, 1 + 2 * nl:-1]                          # the static body comes last
        legs = np.stack([thigh[..., 2] - body[:, None, 2], shin[..., 2] - thigh[..., 2],
                         thigh[..., 5] - body[:, None, 5], shin[..., 5] - thigh[..., 5]], -1)
        return np.concatenate([body[:, :2] * M_PER_CM, body[:, 2:3], body[:, 3:5] * M_PER_CM, body[:, 5:6],
                               legs.reshape(self.n, -1), wheel[..., 5] - body[:, None, 5]], 1)

    def _observe(self, s: np.ndarray) -> dict:
        return observe(s, self.graph, obs_noise_like(s, self.graph, self.np_random))

    # -- Gymnasium-style API -------------------------------------------------
    def reset(self, seed: int | None = None, options: dict | None = None):
        """Rebuild every robot at a perturbed (or given) initial state."""
        if seed is not None:
            self.np_random = np.random.default_rng(seed)
        if options and "states" in options:
            states = np.asarray(options["states"], dtype=float).reshape(self.n, self.graph.state_dim)
        else:
            states = sample_initial_states(self.graph, self.n, self.np_random)
        built = [build_robot(self.graph, s) for s in states]
        self.spaces = [space for space, _ in built]
        self.motors = [motors for _, motors in built]        # keeps the C objects alive
        self._motor_ptrs = [[m._constraint for m in motors] for motors in self.motors]
        self.t = 0
        self.terminated = np.zeros(self.n, dtype=bool)
        self.state = self.read_state()
        return self._observe(self.state), {"state": self.state}

    def step(self, actions):
        """Hold normalised joint-velocity commands (N, A), clipped to [-1, 1], for 1/12 s."""
        actions = np.asarray(actions, dtype=float).reshape(self.n, self.graph.action_dim)
        if not np.isfinite(actions).all():
            raise ValueError("actions must be finite numbers (they are clipped to [-1, 1])")
        actions = np.clip(actions, -1.0, 1.0)
        rates = (actions * self.action_scale).tolist()
        for space, motors, rate in zip(self.spaces, self._motor_ptrs, rates):
            set_motor_rates(motors, rate)
            step_space(space, STEPS_PER_ACTION * PHYSICS_SUBSTEPS)
        s, s_next = self.state, self.read_state()
        r = reward(s, actions, s_next, self.graph)       # numpy here: a third of torch's cost on tiny arrays
        self.state, self.t = s_next, self.t + 1
        flipped = is_flipped(s_next)
        self.terminated |= flipped
        truncated = np.full(self.n, self.t >= self.max_steps)
        info = {"state": s_next, "flipped": flipped}
        return self._observe(s_next), r, self.terminated.copy(), truncated, info


# ----------------------------------------------------------------------------
# The one simulation loop: data collection, demonstrations, evaluation (the
# paper's metric, Sec. IV: distance in 200 control steps) and benchmarks all
# run robots through `simulate`.
# ----------------------------------------------------------------------------
@dataclass
class Episodes:
    """n episodes of one design run side by side, as `simulate` returns them (numpy, float64)."""

    design: str                   # six-letter port code
    states: np.ndarray            # (n, T + 1, S) true states s_0 .. s_T
    obs: dict                     # noisy o_t = O(s_t) per module: body (n, T, 3), leg (n, T, L, 4), wheel (n, T, W, 1)
    actions: np.ndarray           # (n, T, A) a_t as applied: clipped to [-1, 1]
    flipped: np.ndarray           # (n,) bool, |pitch| > FLIP_PITCH at any step

    @property
    def distance_m(self) -> np.ndarray:
        """(n,) x_T - x_0: Sec. IV's metric when T = 200."""
        return self.states[:, -1, 0] - self.states[:, 0, 0]


def simulate(design: str | DesignGraph, act, n: int = 8, steps: int = 200, seed: int = 0) -> Episodes:
    """Run act(obs, state, t) -> (n, A) for `steps` control steps from n starts drawn from p(s).

    obs is the noisy per-module dict the policy sees, state the true (n, S)
    state (hand-crafted controllers may read it), t the control step from 0.
    The seed fixes the starts and the observation noise.  With steps = 200
    (16.7 s) this is the paper's evaluation (Sec. IV).
    """
    if steps < 1:
        raise ValueError(f"steps must be a positive number of control steps, got {steps}")
    world = World(design, n=n, max_steps=steps, seed=seed)
    obs, info = world.reset(seed=seed)
    states, observations, actions = [info["state"]], [], []
    terminated = np.zeros(n, dtype=bool)
    for t in range(steps):
        a = np.clip(act(obs, info["state"], t), -1.0, 1.0)         # (n, A)
        observations.append(obs)
        actions.append(a)
        obs, _, terminated, _, info = world.step(a)
        states.append(info["state"])
    return Episodes(design=world.graph.code, states=np.stack(states, 1),
                    obs={k: np.stack([o[k] for o in observations], 1) for k in ("body", "leg", "wheel")},
                    actions=np.stack(actions, 1),
                    flipped=terminated.copy())


# ----------------------------------------------------------------------------
# Rendering with matplotlib: side view, left limbs (ports 0-2) in front in
# dark colours, right limbs (ports 3-5) behind the body in light colours.
# ----------------------------------------------------------------------------
NEAR, FAR = {"leg": "#1f4e9c", "wheel": "#1b7a3a"}, {"leg": "#f0a040", "wheel": "#9fd39a"}
FAR_SHIFT = np.array([4.0, 3.0])   # cm, drawing offset of the far (right) side


def _draw_robot(ax, graph: DesignGraph, s: np.ndarray, wheel_angle: np.ndarray, alpha: float = 1.0):
    """Draw one robot in state s (S,) with wheel spoke angles (W,) on `ax` (cm); returns its artists."""
    import matplotlib.patches as mpatches
    drawn = []
    for near in (False, True):                 # far side first, then body, then near side
        colours = NEAR if near else FAR
        z = 3 if near else 1
        shift = 0.0 if near else FAR_SHIFT     # a hint of depth so overlapping limbs both show
        fk = {k: v[0] + shift for k, v in forward_kinematics(graph, s[None]).items()}
        for k, port in enumerate(graph.leg_ports):
            if (port < 3) != near:
                continue
            pts = np.stack([fk["hip"][k], fk["knee"][k], fk["foot"][k]])
            drawn += ax.plot(pts[:, 0], pts[:, 1], "-", lw=5, color=colours["leg"], alpha=alpha,
                             solid_capstyle="round", zorder=z)
            drawn.append(ax.add_patch(mpatches.Circle(pts[2], FOOT_RADIUS, color=colours["leg"], alpha=alpha,
                                                      zorder=z)))
        for k, port in enumerate(graph.wheel_ports):
            if (port < 3) != near:
                continue
            c = fk["axle"][k]
            drawn.append(ax.add_patch(mpatches.Circle(c, WHEEL_RADIUS, fill=False, lw=3, color=colours["wheel"],
                                                      alpha=alpha, zorder=z)))
            for da in (0.0, math.pi / 2):      # two spokes show the rotation
                d = WHEEL_RADIUS * np.array([math.cos(wheel_angle[k] + da), math.sin(wheel_angle[k] + da)])
                drawn += ax.plot([c[0] - d[0], c[0] + d[0]], [c[1] - d[1], c[1] + d[1]], lw=1.5,
                                 color=colours["wheel"], alpha=alpha, zorder=z)
    fk = {k: v[0] for k, v in forward_kinematics(graph, s[None]).items()}
    drawn.append(ax.add_patch(mpatches.Polygon(fk["corners"], closed=True, color="#555555", alpha=alpha,
                                               zorder=2)))
    return drawn


def _wheel_angles(graph: DesignGraph, states: np.ndarray) -> np.ndarray:
    """(T, W) wheel angles for drawing, integrated from the rates (not part of the state)."""
    rates = split_state(states, graph)["wheel"][..., 0] + states[:, 5:6]
    return np.concatenate([np.zeros((1, graph.n_wheels)), np.cumsum(rates[1:] * CONTROL_DT, 0)])


def _style_axes(ax, x_centre: float, width: float = 250.0, static: bool = True):
    """The view `width` cm wide centred on x_centre, ticks every 50 cm; static: also the parts
    that do not move (ground line, height range), which a GIF draws once."""
    lo, hi = x_centre - width / 2, x_centre + width / 2
    if static:
        ax.set_ylim(-8, 90)
        ax.set_aspect("equal")
        ax.axhline(0, color="k", lw=2)
        ax.set_yticks([])
        ax.set_xlabel("x (m)")
    ax.set_xlim(lo, hi)
    ticks = np.arange(math.ceil(lo / 50) * 50, hi + 1e-9, 50)             # every 50 cm, inside the view
    ax.set_xticks(ticks)
    ax.set_xticklabels([f"{t / 100:g}" for t in ticks])


def save_gif(graph: DesignGraph, states: np.ndarray, path: str, every: int = 1, title: str = ""):
    """Animate one robot's state trajectory (T+1, S), simulated or model-predicted."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.animation import PillowWriter
    graph = design_graph(graph)
    angles = _wheel_angles(graph, states)
    fig, ax = plt.subplots(figsize=(8, 3.4), dpi=80)
    _style_axes(ax, states[0, 0] / M_PER_CM)
    robot, writer = [], PillowWriter(fps=12 // every)
    with writer.saving(fig, path, dpi=fig.dpi):
        for t in range(0, len(states), every):              # per frame: move the view, redraw only the robot
            for artist in robot:
                artist.remove()
            _style_axes(ax, states[t, 0] / M_PER_CM, static=False)
            robot = _draw_robot(ax, graph, states[t], angles[t])
            ax.set_title(f"{title or graph.name}   t = {t * CONTROL_DT:4.1f} s   "
                         f"distance = {states[t, 0] - states[0, 0]:5.2f} m", fontsize=13)
            writer.grab_frame()                             # draws the figure once
    plt.close(fig)


def save_png(graph: DesignGraph, states: np.ndarray, path: str, poses: int = 6, title: str = ""):
    """Snapshots of one robot's trajectory (T+1, S): `poses` panels in a row, each centred on
    the robot at the scale of the GIF, so a 20 m run stays as legible as a 20 cm one."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    graph = design_graph(graph)
    angles = _wheel_angles(graph, states)
    times = np.linspace(0, len(states) - 1, poses).astype(int)
    fig, axes = plt.subplots(1, poses, figsize=(2.6 * poses, 2.5), dpi=100, squeeze=False)
    for ax, t in zip(axes[0], times):
        _style_axes(ax, states[t, 0] / M_PER_CM, width=160.0)
        _draw_robot(ax, graph, states[t], angles[t])
        ax.set_title(f"t = {t * CONTROL_DT:.1f} s, {states[t, 0] - states[0, 0]:.2f} m", fontsize=12)
    fig.suptitle(title or f"{graph.name} ({graph.code}): {states[-1, 0] - states[0, 0]:.2f} m "
                 f"in {(len(states) - 1) * CONTROL_DT:.1f} s", fontsize=14)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def atomic_write(path, write) -> None:
    """write(tmp_path) into a temporary file beside `path`, then rename it over `path`: a crash
    or a full disk never leaves half a file, and a reader sees the old file or the new one."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.stem}.", suffix=path.suffix)
    os.close(fd)
    try:
        write(tmp)
        os.chmod(tmp, 0o644)                     # mkstemp makes 0600 files
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)


class CliParser(argparse.ArgumentParser):
    """argparse, but bad input is one line on stderr and exit status 2 (no usage dump), and a
    negative number after a flag is that flag's value (argparse reads `--lr -1e-3` as two flags)."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message}\n")

    def parse_known_args(self, args=None, namespace=None):
        joined = []
        for arg in sys.argv[1:] if args is None else args:
            if joined and joined[-1].startswith("--") and "=" not in joined[-1] and _is_negative_number(arg):
                joined[-1] += "=" + arg                         # --lr -1e-3 -> --lr=-1e-3
            else:
                joined.append(arg)
        return super().parse_known_args(joined, namespace)


def _is_negative_number(text: str) -> bool:
    try:
        return text.startswith("-") and not math.isnan(float(text))
    except ValueError:
        return False


def main(argv=None) -> int:
    parser = CliParser(description="Run one robot in the planar world.")
    parser.add_argument("--design", default="hexapod", help="a name (%s) or a 6-letter code of l/w/n"
                        % ", ".join(NAMED_DESIGNS))
    parser.add_argument("--steps", type=int, default=200, help="control steps of 1/12 s (200 = 16.7 s)")
    parser.add_argument("--action", choices=("zero", "random"), default="zero",
                        help="zero: hold the pose; random: smooth random spline commands")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--gif", help="write an animation of the run to this path")
    parser.add_argument("--png", help="write six snapshots of the run to this path")
    args = parser.parse_args(argv)
    try:
        graph = design_graph(args.design)
    except ValueError as e:
        parser.error(str(e))
    if args.steps < 1:
        parser.error(f"--steps must be a positive number of control steps, got {args.steps}")
    rng = np.random.default_rng(args.seed)
    actions = (random_spline_actions(rng, 1, graph.action_dim, args.steps) if args.action == "random"
               else np.zeros((1, args.steps, graph.action_dim)))
    t0 = time.perf_counter()
    result = simulate(graph, lambda obs, s, t: actions[:, t], n=1, steps=args.steps, seed=args.seed)
    seconds = time.perf_counter() - t0
    s = result.states[0]
    print(f"design {graph.name} ({graph.code}): {graph.n_legs} legs, {graph.n_wheels} wheels, "
          f"{graph.action_dim} joints, state {graph.state_dim}")
    print(f"{args.steps} steps ({args.steps * CONTROL_DT:.1f} s simulated) in {seconds:.2f} s wall; "
          f"height {s[0, 1]:.3f} -> {s[-1, 1]:.3f} m, max |pitch| {np.abs(s[:, 2]).max():.3f} rad")
    if args.gif:
        save_gif(graph, s, args.gif)
        print(f"wrote {args.gif}")
    if args.png:
        save_png(graph, s, args.png)
        print(f"wrote {args.png}")
    print(f"action={args.action} seed={args.seed} distance_m={result.distance_m[0]:.4f} "
          f"flipped={int(result.flipped[0])}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
