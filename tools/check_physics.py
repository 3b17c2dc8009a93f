"""How far contacts and joints of sim2d's world give under aggressive legal actions.

Robots of each design run bang-bang actions (every joint at +-1, signs redrawn
every 3 control steps) and random spline actions (sim2d.random_spline_actions)
through the world's physics, and three errors are measured, worst case over
all robots and steps: the deepest reach of any shape below the ground
(penetration_cm), the widest gap between a pivot joint's two anchors
(joint_gap_cm) and the largest joint angle beyond its RotaryLimitJoint range
(limit_violation_rad); targets 2 cm / 1 cm / 0.05 rad (sim2d's physics
constants quote what each setting gave).  They are measured after every pymunk
step, not once per control step: a foot can tunnel into the ground and come
back, or a joint open and close, between two control steps (5 x
PHYSICS_SUBSTEPS pymunk steps).  So this file drives the robots itself, through
the same calls as sim2d.World.step (clip, scale to motor rates, set the rates,
step the space), one pymunk step at a time.

    python tools/check_physics.py               # the four named designs + 20 random codes, CPU, 15-25 s
    python tools/check_physics.py --design hexapod car --random-codes 0 --robots 4 --steps 100

Prints a table (one row per design and action kind, then the random codes'
maxima) and one summary line of key=value pairs, the maxima over every row.
"""
from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import numpy as np
import pymunk
import pymunk.batch
import torch

if __package__ in (None, ""):              # run as a script: the stage files are one folder up
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import sim2d                                                                                 # noqa: E402
from sim2d import (FLIP_PITCH, NAMED_DESIGNS, PHYSICS_SUBSTEPS, STEPS_PER_ACTION, CliParser, World,  # noqa: E402
                   all_designs, design_graph, design_name, parse_design, random_spline_actions)

# ----------------------------------------------------------------------------
# Contacts and joints under any legal actions, measured after
# every physics step: a foot can tunnel and come back between control steps.
# ----------------------------------------------------------------------------
CHECK_SEED = 11        # seed of check_physics: its random codes, starts and actions
CHECK_KINDS = ("bang-bang", "spline")
MAX_ROBOTS, MAX_STEPS = 256, 10_000      # the most --robots and --steps the command takes


def check_codes(designs=tuple(NAMED_DESIGNS), random_codes: int = 20, seed: int = CHECK_SEED) -> list[str]:
    """The codes check_physics runs: the given designs, then `random_codes` others drawn
    without replacement from all_designs() (minus the given ones) with rng `seed`."""
    codes = list(dict.fromkeys(parse_design(d) for d in designs))
    others = [c for c in all_designs() if c not in codes]
    return codes + [str(c) for c in np.random.default_rng(seed).choice(others, random_codes, replace=False)]


def bang_bang_actions(rng: np.random.Generator, n: int, action_dim: int, steps: int, hold: int = 3) -> np.ndarray:
    """(n, steps, action_dim) actions of +-1 on every joint, signs redrawn every `hold` steps."""
    signs = rng.choice([-1.0, 1.0], (n, -(-steps // hold), action_dim))
    return np.repeat(signs, hold, axis=1)[:, :steps]


def robot_geometry(space: pymunk.Space) -> dict:
    """What check_physics measures in a robot's Space, by body index in pymunk.batch order.

    "points": (P, 4) [body, x, y, radius] in the body's frame: circle centres,
    segment ends and polygon corners, whose lowest reach is y - radius;
    "pivots": (J, 6) [body a, body b, anchor a x, y, anchor b x, y];
    "limits": (K, 4) [body a, body b, min, max] of b.angle - a.angle;
    "surface": the top of the ground (cm).
    """
    index = {b: i for i, b in enumerate(space.bodies)}
    points, surface = [], -math.inf
    for shape in space.shapes:
        if shape.body not in index:                                   # the ground
            surface = max(surface, shape.cache_bb().top)
        elif isinstance(shape, pymunk.Circle):
            points.append([index[shape.body], *shape.offset, shape.radius])
        elif isinstance(shape, pymunk.Segment):
            points += [[index[shape.body], *p, shape.radius] for p in (shape.a, shape.b)]
        else:
            points += [[index[shape.body], *p, shape.radius] for p in shape.get_vertices()]
    pivots = [[index[c.a], index[c.b], *c.anchor_a, *c.anchor_b]
              for c in space.constraints if isinstance(c, pymunk.PivotJoint)]
    limits = [[index[c.a], index[c.b], c.min, c.max]
              for c in space.constraints if isinstance(c, pymunk.RotaryLimitJoint)]
    return {"points": np.array(points), "pivots": np.array(pivots).reshape(-1, 6),
            "limits": np.array(limits).reshape(-1, 4), "surface": surface}


def contact_and_joint_errors(raw: np.ndarray, geometry: dict) -> dict:
    """Worst errors over poses raw (K, bodies, 3) [x, y, angle] (cm, rad) of one robot kind.

    penetration_cm: deepest reach of any shape below the ground's surface;
    joint_gap_cm: largest distance between a pivot's two anchors in the world;
    limit_violation_rad: largest joint angle beyond its RotaryLimitJoint range.
    """
    def world(body, local):                                           # (n,), (n, 2) -> (K, n, 2)
        p, a = raw[:, body, :2], raw[:, body, 2]
        c, s = np.cos(a), np.sin(a)
        return p + np.stack([local[:, 0] * c - local[:, 1] * s, local[:, 0] * s + local[:, 1] * c], -1)

    pts, piv, lim = geometry["points"], geometry["pivots"], geometry["limits"]
    lowest = world(pts[:, 0].astype(int), pts[:, 1:3])[..., 1] - pts[:, 3]          # (K, P) cm
    gap = np.linalg.norm(world(piv[:, 0].astype(int), piv[:, 2:4])
                         - world(piv[:, 1].astype(int), piv[:, 4:6]), axis=-1)      # (K, J) cm
    q = raw[:, lim[:, 1].astype(int), 2] - raw[:, lim[:, 0].astype(int), 2]         # (K, L) rad
    over = np.maximum(q - lim[:, 3], lim[:, 2] - q)
    return {"penetration_cm": max(0.0, float((geometry["surface"] - lowest).max())),
            "joint_gap_cm": float(gap.max(initial=0.0)),
            "limit_violation_rad": max(0.0, float(over.max(initial=0.0)))}


def check_physics(designs=tuple(NAMED_DESIGNS), random_codes: int = 20, n: int = 8, steps: int = 200,
                  kinds=CHECK_KINDS, seed: int = CHECK_SEED) -> dict:
    """Drive robots with aggressive legal actions and measure how far contacts and joints give.

    For each code of check_codes(designs, random_codes, seed) and each action
    kind ("bang-bang": every joint at +-1, signs redrawn every 3 control steps;
    "spline": random_spline_actions), n robots from the perturbed starts of
    World.reset run `steps` control steps through the physics of World.step
    (the same clip, motor rates and pymunk steps), and every pymunk step is
    measured (contact_and_joint_errors).  A robot counts as flipped once its
    |pitch| exceeds FLIP_PITCH after a control step (sticky, as
    World.terminated).  Returns {"rows": one dict per (code, kind) with the
    three errors and the flips, "max_penetration_cm", "max_joint_gap_cm",
    "max_limit_violation_rad"}.
    """
    rows, fields = [], pymunk.batch.BodyFields.POSITION | pymunk.batch.BodyFields.ANGLE
    for code in check_codes(designs, random_codes, seed):
        graph = design_graph(code)
        scale = sim2d.joint_speed_scale(graph)
        for kind in kinds:
            rng = np.random.default_rng(seed)
            actions = (bang_bang_actions(rng, n, graph.action_dim, steps) if kind == "bang-bang"
                       else random_spline_actions(rng, n, graph.action_dim, steps))
            world = World(graph, n=n, max_steps=steps, seed=seed)
            world.reset(seed=seed)                                    # the starts; its spaces and motors
            poses, buf = [], pymunk.batch.Buffer()                    # bytes of (bodies + 1, 3) per pymunk step
            flipped = np.zeros(n, dtype=bool)
            for t in range(steps):
                rates = (np.clip(actions[:, t], -1.0, 1.0) * scale).tolist()
                for space, motors, rate in zip(world.spaces, world._motor_ptrs, rates):
                    sim2d.set_motor_rates(motors, rate)
                    for _ in range(STEPS_PER_ACTION * PHYSICS_SUBSTEPS):
                        sim2d.step_space(space, 1)
                        buf.clear()
                        pymunk.batch.get_space_bodies(space, fields, buf)
                        poses.append(bytes(buf.float_buf()))
                flipped |= np.abs(world.read_state()[:, 2]) > FLIP_PITCH
            raw = np.frombuffer(b"".join(poses)).reshape(len(poses), -1, 3)[:, :-1]   # drop the static body
            errors = contact_and_joint_errors(raw, robot_geometry(world.spaces[0]))
            rows.append({"code": code, "actions": kind, **errors, "flips": int(flipped.sum()),
                         "pymunk_steps": len(poses) // n})
    return {"rows": rows, **{f"max_{k}": max(r[k] for r in rows)
                             for k in ("penetration_cm", "joint_gap_cm", "limit_violation_rad")}}


def main(argv=None) -> int:
    """`python tools/check_physics.py [--design D ...]`: the table of check_physics and one summary line."""
    parser = CliParser(prog="tools/check_physics.py",
                       description="Measure ground penetration, joint gaps and limit overshoot under "
                                   "bang-bang and random spline actions, after every physics step.")
    parser.add_argument("--design", nargs="+", action="extend",
                        help="names or codes to check (default: the four named designs)")
    parser.add_argument("--random-codes", type=int, default=20,
                        help="how many other codes of the 728 to add, drawn with --seed (0: none)")
    parser.add_argument("--robots", type=int, default=8, help="perturbed starts per design and action kind")
    parser.add_argument("--steps", type=int, default=200, help="control steps per run")
    parser.add_argument("--seed", type=int, default=CHECK_SEED, help="seed of the codes, starts and actions")
    args = parser.parse_args(argv)
    if not 1 <= args.robots <= MAX_ROBOTS or not 1 <= args.steps <= MAX_STEPS:
        parser.error(f"--robots takes 1 to {MAX_ROBOTS} and --steps 1 to {MAX_STEPS}, got {args.robots} and {args.steps}")
    if not 0 <= args.seed < 2 ** 63:
        parser.error(f"--seed takes 0 to 2^63 - 1, got {args.seed}")
    try:
        designs = [parse_design(d) for d in (args.design or NAMED_DESIGNS)]
    except ValueError as e:
        parser.error(str(e))
    others = len(all_designs()) - len(set(designs))
    if not 0 <= args.random_codes <= others:
        parser.error(f"--random-codes takes 0 to {others} (the {len(all_designs())} codes less the "
                     f"{len(set(designs))} given), got {args.random_codes}")
    torch.set_num_threads(1)
    t0 = time.perf_counter()
    result = check_physics(designs, args.random_codes, args.robots, args.steps, seed=args.seed)
    print(f"{'design':15s} {'actions':9s} {'penetration_cm':>14s} {'joint_gap_cm':>12s} "
          f"{'limit_rad':>9s} {'flips':>5s}")
    for r in result["rows"]:
        print(f"{design_name(r['code']):15s} {r['actions']:9s} {r['penetration_cm']:14.2f} "
              f"{r['joint_gap_cm']:12.2f} {r['limit_violation_rad']:9.3f} {r['flips']:5d}")
    random_rows = [r for r in result["rows"] if r["code"] not in designs]
    for kind in CHECK_KINDS:
        rows = [r for r in random_rows if r["actions"] == kind]
        if rows:
            label = f"{len(rows)} random code{'s' if len(rows) > 1 else ''}"
            print(f"{label:15s} {kind:9s} {max(r['penetration_cm'] for r in rows):14.2f} "
                  f"{max(r['joint_gap_cm'] for r in rows):12.2f} "
                  f"{max(r['limit_violation_rad'] for r in rows):9.3f} {sum(r['flips'] for r in rows):5d}  (max, flips summed)")
    print(f"{args.robots} robots x {args.steps} control steps x {result['rows'][0]['pymunk_steps'] // args.steps} "
          f"pymunk steps, each measured, per design and action kind; seed {args.seed}; "
          f"{time.perf_counter() - t0:.1f} s")
    print(f"max_penetration_cm={result['max_penetration_cm']:.2f} max_joint_gap_cm={result['max_joint_gap_cm']:.2f} "
          f"max_limit_violation_rad={result['max_limit_violation_rad']:.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
