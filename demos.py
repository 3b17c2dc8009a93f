"""Hand-crafted demonstrations: the dataset T_demo of (observation, action) pairs.

Paper (Whitman & Choset, "Learning Modular Robot Locomotion from
Demonstrations"): Sec. III-D "Gather demonstration datasets" (eqn. 2: per demo
design, L trajectories of H steps of (o_t, a_t)) and Sec. IV "Experiments"
(hexapod: alternating tripod gait; car: all wheels driving; 50 randomly
perturbed initial states, 100 control steps each, closed loop).
The paper steers body yaw to zero by modulating left/right step size and wheel
speed.  Our world is a side view with no yaw, so the controllers correct what
the plane has: step size and wheel speed track one target forward speed for
every design, and the legs' stance depth holds body height and pitch.

    python demos.py --design hexapod            # builds 50 x 100 steps in under 1 s, then cached
    python demos.py --design car --gif car.gif
    python demos.py --design leg_leg_wheel --episodes 10 --steps 50 --seed 3
"""
from __future__ import annotations

import hashlib
import json
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

import sim2d

DEFAULT_CACHE_DIR = Path(__file__).resolve().parent / "cache"


# ----------------------------------------------------------------------------
# Config
# ----------------------------------------------------------------------------
@dataclass(frozen=True)
class DemoConfig:
    """Settings of the hand-crafted controllers (dataset sizes and seed are arguments)."""

    target_speed: float = 1.0
    """m/s, forward speed every design aims for (0.5-1.1): one value for all
    designs so that hexapod and car demos move alike (the car tops out at 1.19)."""
    gait_period: float = 0.5
    """s, one tripod cycle, half stance and half swing (0.4-0.7); 0.5 s is 6
    control steps and needs a 12.5 cm half stride for 1 m/s."""
    step_lift: float = 4.0
    """cm, how high a swing foot rises above its stance depth (3-10).  4 cm
    walks the hexapod at 1.01 m/s, 6 cm at 0.90 m/s (a higher swing lands
    later, shortening the stride)."""
    max_half_stride: float = 16.0
    """cm, largest foot travel either side of the hip (10-17; the leg reaches 36)."""
    start_ramp: float = 0.5
    """s, time over which the target speed rises from 0 (0-1): a gentle first step."""
    speed_gain: float = 1.0
    """m/s of extra commanded speed per m/s the robot is too slow (0-2)."""
    filter_time: float = 0.25
    """s, time constant of the low-pass estimate of height, pitch and speed the
    feedback acts on (0.1-0.5): it averages over one tripod step's ripple."""
    height_gain: float = 0.1
    """cm of extra stance depth per cm the body sags below nominal (0-0.25;
    0.25 and more made the body bounce, measured)."""
    pitch_gain: float = 0.25
    """fraction of each hip's pitch-induced height offset taken out of its
    stance depth (0-0.5; 1.0 overcorrected and flipped a robot, measured)."""
    tracking_gain: float = 1.0
    """fraction of the joint-angle error closed in one control step (0.5-1; 1
    commands the rate that reaches the reference exactly, kp = 12 /s)."""
    execution_noise: float = 0.15
    """std of smooth random noise (sim2d.random_spline_actions) added to the actions
    the robot executes, not to the actions recorded (0-0.3).  The recorded
    action is the demonstrator's answer in the state the noise led to, so the
    dataset shows recoveries as well as the gait (DART, Laskey et al. 2017).
    0 = the paper's noiseless demonstrations; 0.15 = what training uses
    (modular_rlil_minimal.Config.demo_noise)."""
    wheel_pitch_backoff: float = 0.5
    """rad of |pitch| at which the wheels stop driving (0.3-1.0); linear below."""


TRIPOD_B = (1, 3, 5)   # ports of the second tripod, half a period behind {0, 2, 4}
FRONT_PORTS, REAR_PORTS = (0, 5), (2, 3)
LEG_LENGTH = sim2d.THIGH + sim2d.SHIN                               # cm, 36: two equal links
LEG_REACH = 0.98 * LEG_LENGTH                                       # cm, longest hip-foot distance asked for
STANCE_DEPTH = LEG_LENGTH * np.cos(sim2d.HIP_NOMINAL)              # cm, ~31.6: hip to foot, nominal pose


# ----------------------------------------------------------------------------
# Small pure helpers: gait timing, foot path, inverse kinematics, feedback
# ----------------------------------------------------------------------------
def tripod_phase(t: int, ports: tuple[int, ...], period: float) -> np.ndarray:
    """(L,) gait phase in [0, 1) of each leg at control step t: [0, .5) stance, [.5, 1) swing.

    >>> tripod_phase(0, (0, 1, 2, 3, 4, 5), 0.5)      # tripods {0,2,4} and {1,3,5}
    array([0. , 0.5, 0. , 0.5, 0. , 0.5])
    """
    offset = np.array([0.5 if p in TRIPOD_B else 0.0 for p in ports])
    return (t * sim2d.CONTROL_DT / period + offset) % 1.0


def foot_path(phase, half_stride, depth, lift):
    """Foot position (cm) relative to the hip in the body frame; arrays broadcast.

    Stance (phase < 0.5): the foot moves back in a straight line from
    +half_stride to -half_stride at depth `depth`, pushing the body forward.
    Swing: it returns to +half_stride on a raised cosine arc `lift` high.
    >>> fx, fy = foot_path(np.array([0.0, 0.25, 0.75]), 10.0, 30.0, 6.0)
    >>> fx.round(6) + 0.0, fy          # start of stance, mid stance, top of swing
    (array([10.,  0.,  0.]), array([-30., -30., -24.]))
    """
    u = np.where(phase < 0.5, phase, phase - 0.5) / 0.5           # progress through this half
    stance_x = half_stride * (1 - 2 * u)
    swing_x = -half_stride + half_stride * (1 - np.cos(np.pi * u))
    fx = np.where(phase < 0.5, stance_x, swing_x)
    fy = -depth + np.where(phase < 0.5, 0.0, lift * np.sin(np.pi * u))
    return fx, fy


def leg_inverse_kinematics(fx, fy):
    """Hip and knee angles (rad) that put the foot at (fx, fy) cm from the hip (body frame).

    Two equal links: the knee bends by -2 acos(d / 2L); the hip points at the
    foot and turns forward by half that bend (the knee stays behind the foot line).
    >>> [round(float(q), 3) for q in leg_inverse_kinematics(0.0, -STANCE_DEPTH)]   # nominal pose
    [0.5, -1.0]
    """
    d = np.minimum(np.hypot(fx, fy), LEG_REACH)
    bend = np.arccos(d / LEG_LENGTH)
    return np.arctan2(fx, -fy) + bend, -2.0 * bend


def ramped_target_speed(t: int, cfg: DemoConfig) -> float:
    """v*(t), m/s: the target forward speed, ramped up from 0 over cfg.start_ramp seconds."""
    if cfg.start_ramp <= 0:
        return cfg.target_speed
    return cfg.target_speed * min(1.0, t * sim2d.CONTROL_DT / cfg.start_ramp)


def low_pass(estimate: np.ndarray, state: np.ndarray, cfg: DemoConfig) -> np.ndarray:
    """One step of the demonstrator's low-pass estimate of [y, pitch, vx], (N, 3).

    The feedback acts on this average, not on the raw state: a tripod stance
    lasts only 3 control steps, and feeding back the within-step ripple of
    height and pitch made the robots bounce and flip (measured).
    """
    alpha = sim2d.CONTROL_DT / (cfg.filter_time + sim2d.CONTROL_DT)
    return estimate + alpha * (state[:, [1, 2, 3]] - estimate)


def commanded_speed(v_star: float, vx: np.ndarray, cfg: DemoConfig) -> np.ndarray:
    """m/s, like vx: the target speed plus a correction proportional to the speed error."""
    return np.clip(v_star + cfg.speed_gain * (v_star - vx), 0.0, None)


def modulated_step_size(v_star: float, vx: np.ndarray, cfg: DemoConfig) -> np.ndarray:
    """Half stride (cm), like vx: the step size that walks at the commanded speed.

    A stance foot sweeps 2 * half_stride in half a gait period, so walking at
    v needs half_stride = v * period / 4.
    >>> float(modulated_step_size(1.0, np.array(1.0), DemoConfig()))   # on target: 1 m/s, 0.5 s
    12.5
    """
    v = commanded_speed(v_star, vx, cfg)
    return np.clip(v / sim2d.M_PER_CM * cfg.gait_period / 4, 0.0, cfg.max_half_stride)


def stance_depth(y: np.ndarray, pitch: np.ndarray, hip_x: np.ndarray, y_nominal: float,
                  cfg: DemoConfig) -> np.ndarray:
    """Hip-to-foot depth (cm) per leg, (N, 1) x (L,) -> (N, L): holds body height and pitch.

    A sagging body (y below nominal, m) gets longer legs; a nose-up pitch
    raises a hip at hip_x cm along the body by hip_x * sin(pitch), so front
    legs shorten and rear legs lengthen by pitch_gain times that.
    """
    return (STANCE_DEPTH + cfg.height_gain * (y_nominal - y) / sim2d.M_PER_CM
            - cfg.pitch_gain * hip_x * np.sin(pitch))


# ----------------------------------------------------------------------------
# The demonstrators: tripod gait for legs, forward drive for wheels
# ----------------------------------------------------------------------------
def tripod_gait_actions(graph: sim2d.DesignGraph, state: np.ndarray, t: int, estimate: np.ndarray,
                        cfg: DemoConfig) -> np.ndarray:
    """(N, 2L) normalised [hip, knee] commands of the alternating tripod gait.

    Legs on ports {0, 2, 4} and {1, 3, 5} step half a period apart.  Closed
    loop on the filtered body estimate [y, pitch, vx] (N, 3), the plane's
    stand-in for the paper's yaw steering: step size tracks v*(t), and each
    leg's stance depth corrects body height and, by the leg's place along the
    body, pitch.  The joints track the inverse kinematics of the next step's
    foot target, through the same velocity-command interface the policy uses.
    """
    legs = sim2d.split_state(state, graph)["leg"]                           # (N, L, 4)
    y, pitch, vx = estimate[:, 0:1], estimate[:, 1:2], estimate[:, 2:3]     # (N, 1) each
    hip_x = np.array([sim2d.PORT_X[min(p, 5 - p)] for p in graph.leg_ports])  # (L,) cm
    half_stride = modulated_step_size(ramped_target_speed(t, cfg), vx, cfg)       # (N, 1) cm
    depth = stance_depth(y, pitch, hip_x, sim2d.nominal_state(graph)[1], cfg)    # (N, L) cm
    phase = tripod_phase(t + 1, graph.leg_ports, cfg.gait_period)           # (L,) reference at t+1
    fx, fy = foot_path(phase, half_stride, depth, cfg.step_lift)           # (N, L) cm, body frame
    hip_ref, knee_ref = leg_inverse_kinematics(fx, fy)
    q_ref = np.stack([np.clip(hip_ref, *sim2d.HIP_LIMITS), np.clip(knee_ref, *sim2d.KNEE_LIMITS)], -1)
    # The joint rate that closes tracking_gain of the error in one control step.
    rate = cfg.tracking_gain * (q_ref - legs[..., :2]) / sim2d.CONTROL_DT   # (N, L, 2) rad/s
    return (rate / sim2d.LEG_MAX_SPEED).reshape(len(state), -1)


def wheel_drive_actions(graph: sim2d.DesignGraph, state: np.ndarray, t: int, estimate: np.ndarray,
                        cfg: DemoConfig) -> np.ndarray:
    """(N, W) normalised wheel commands: every wheel drives forward (negative rate).

    Closed loop: the rim speed is the commanded speed (v*(t) plus the speed
    correction), backed off linearly to zero as |pitch| nears
    cfg.wheel_pitch_backoff (a reflex on the raw pitch: a wheelie or a nose
    dive is not driven further).
    """
    rim_speed = commanded_speed(ramped_target_speed(t, cfg), estimate[:, 2], cfg)              # (N,) m/s
    backoff = np.clip(1 - np.abs(state[:, 2]) / cfg.wheel_pitch_backoff, 0.0, 1.0)      # (N,)
    rate = -rim_speed / (sim2d.WHEEL_RADIUS * sim2d.M_PER_CM) * backoff                       # (N,) rad/s
    return np.repeat((rate / sim2d.WHEEL_MAX_SPEED)[:, None], graph.n_wheels, axis=1)


def demo_actions(graph: sim2d.DesignGraph, state: np.ndarray, t: int, estimate: np.ndarray,
                 cfg: DemoConfig) -> np.ndarray:
    """(N, A) the demonstrator's action a_t, clipped to [-1, 1] as the World applies it."""
    parts = [tripod_gait_actions(graph, state, t, estimate, cfg),
             wheel_drive_actions(graph, state, t, estimate, cfg)]
    return np.clip(np.concatenate(parts, axis=1), -1.0, 1.0)


def check_demonstrable(graph: sim2d.DesignGraph) -> None:
    """Raise a one-line ValueError unless the limbs hold up both body ends at every phase.

    A wheel always supports; a leg supports in its stance half, and the two
    tripods alternate, so an end (front ports 0/5, rear ports 2/3) is held up
    throughout only by a wheel or by legs on both of its ports.  Otherwise that
    end drops every step.  The rule is sufficient, not necessary: over all
    728 designs the accepted ones all walk, and some rejected ones would too
    (nwwwwn rolls on its middle and rear axles); docs/world.md has the counts.
    """
    def held(ports):
        return any(graph.code[p] == "w" for p in ports) or all(graph.code[p] == "l" for p in ports)
    missing = [end for end, ports in (("front", FRONT_PORTS), ("rear", REAR_PORTS)) if not held(ports)]
    if missing:
        raise ValueError(
            f"design {graph.code} cannot be demonstrated: nothing holds up its {' and '.join(missing)} "
            "at every gait phase (needs a wheel, or legs on both ports, at front 0/5 and rear 2/3)")


class Demonstrator:
    """The hand-crafted expert of one design, act(obs, state, t) -> (N, A), with its filter.

    It reads the true state (a hand-crafted controller may; the policy gets
    only obs).  Call it once per control step from the reset on, e.g. with
    sim2d.simulate(design, Demonstrator(design)); make a new one per episode.
    """

    def __init__(self, design: str | sim2d.DesignGraph, cfg: DemoConfig = DemoConfig()):
        self.graph = sim2d.design_graph(design)
        check_demonstrable(self.graph)
        self.cfg, self.estimate = cfg, None

    def __call__(self, obs: dict, state: np.ndarray, t: int) -> np.ndarray:
        if self.estimate is None:
            self.estimate = state[:, [1, 2, 3]]                  # (N, 3) y, pitch, vx at reset
        else:
            self.estimate = low_pass(self.estimate, state, self.cfg)
        return demo_actions(self.graph, state, t, self.estimate, self.cfg)   # (N, A)


# ----------------------------------------------------------------------------
# The dataset T^i of one demo design, cached on disk
# ----------------------------------------------------------------------------
def demo_seed(code: str, seed: int) -> int:
    """The World seed of (design, seed): stable across runs and processes, different per design."""
    return int.from_bytes(hashlib.sha256(f"demos:{code}:{seed}".encode()).digest()[:4], "little")


def source_hash() -> str:
    """Hash of the world's and this demonstrator's source: a change to either invalidates the cache."""
    h = hashlib.sha256()
    for path in (Path(sim2d.__file__), Path(__file__)):
        h.update(path.read_bytes())
    return h.hexdigest()[:12]


@dataclass
class DemoData:
    """T^i for one design: E trajectories of T (observation, action) pairs (eqn. 2)."""

    design: str                     # six-letter port code
    obs: dict[str, np.ndarray]      # noisy o_t = O(s_t): body (E, T, 3), leg (E, T, L, 4), wheel (E, T, W, 1)
    actions: np.ndarray             # (E, T, A) a_t, normalised, clipped to [-1, 1] as applied
    states: np.ndarray              # (E, T + 1, S) true states s_0..s_T, metres
    distance_m: np.ndarray          # (E,) x_T - x_0
    flipped: np.ndarray             # (E,) bool, |pitch| > pi/2 at any step
    meta: dict = field(default_factory=dict)   # seed, episodes, steps, config, source hash

    def save(self, path: Path | str) -> None:
        """Write an .npz atomically (sim2d.atomic_write)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)

        def write(tmp):
            with open(tmp, "wb") as f:
                np.savez(f, design=self.design, actions=self.actions, states=self.states,
                         distance_m=self.distance_m, flipped=self.flipped, meta=json.dumps(self.meta),
                         **{f"obs_{k}": v for k, v in self.obs.items()})
        sim2d.atomic_write(path, write)

    @classmethod
    def load(cls, path: Path | str) -> "DemoData":
        """Read a file written by `save`."""
        with np.load(path) as z:
            return cls(design=str(z["design"]), actions=z["actions"], states=z["states"],
                       distance_m=z["distance_m"], flipped=z["flipped"],
                       obs={k[len("obs_"):]: z[k] for k in z.files if k.startswith("obs_")},
                       meta=json.loads(str(z["meta"])))


def validate_request(design: str, episodes: int, steps: int) -> sim2d.DesignGraph:
    """The design graph, or a one-line ValueError for a bad name, count or design."""
    if episodes < 1 or steps < 1:
        raise ValueError(f"episodes and steps must be positive, got episodes={episodes} steps={steps}")
    graph = sim2d.design_graph(design)
    check_demonstrable(graph)
    return graph


def collect_demos(design: str, episodes: int = 50, steps: int = 100, seed: int = 0,
                  cfg: DemoConfig = DemoConfig()) -> DemoData:
    """Run the demonstrator on `episodes` perturbed robots at once for `steps` control steps."""
    graph = validate_request(design, episodes, steps)
    demonstrator, labels = Demonstrator(graph, cfg), []
    noise = (sim2d.random_spline_actions(np.random.default_rng(demo_seed(graph.code, seed) + 1), episodes,
                                         graph.action_dim, steps, std=cfg.execution_noise)   # (E, T, A)
             if cfg.execution_noise else np.zeros((episodes, steps, graph.action_dim)))

    def act(obs, state, t):                                      # executes a_t + noise, records a_t
        labels.append(demonstrator(obs, state, t))
        return labels[-1] + noise[:, t]

    run = sim2d.simulate(graph, act, n=episodes, steps=steps,
                         seed=demo_seed(graph.code, seed))       # perturbed initial states, p(s)
    return DemoData(
        design=graph.code,
        obs=run.obs,                                             # o_t: what the policy sees, (E, T, ...)
        actions=np.stack(labels, 1),                             # a_t: what it should do, (E, T, A)
        states=run.states,                                       # (E, T + 1, S)
        distance_m=run.distance_m,                               # (E,)
        flipped=run.flipped,                                     # (E,) sticky: flipped at any step
        meta={"seed": seed, "episodes": episodes, "steps": steps, "config": asdict(cfg),
              "source": source_hash()})


def cache_path(design: str, episodes: int, steps: int, seed: int,
               cache_dir: Path | str = DEFAULT_CACHE_DIR, cfg: DemoConfig = DemoConfig()) -> Path:
    """The file a dataset is cached in, named by everything that determines it.

    Design code, episodes, steps and seed are in the name; the last part hashes
    the source of sim2d.py and demos.py with the controller config, so a change
    to the world or the demonstrator never serves a stale dataset.
    """
    code = sim2d.design_graph(design).code
    key = hashlib.sha256(f"{source_hash()}:{sorted(asdict(cfg).items())}".encode()).hexdigest()[:12]
    return Path(cache_dir) / f"demos_{code}_e{episodes}_t{steps}_s{seed}_{key}.npz"


def load_or_make_demos(design: str, episodes: int = 50, steps: int = 100, seed: int = 0,
                       cache_dir: Path | str = DEFAULT_CACHE_DIR, cfg: DemoConfig = DemoConfig()) -> DemoData:
    """T^i for one demo design: the cached dataset if its key matches, else build and cache it."""
    validate_request(design, episodes, steps)
    path = cache_path(design, episodes, steps, seed, cache_dir, cfg)
    if path.exists():
        return DemoData.load(path)
    data = collect_demos(design, episodes, steps, seed, cfg)
    data.save(path)
    return data


def demo_quality(data: DemoData) -> dict:
    """Flat metrics: distance per trajectory (mean, min), mean speed, max |pitch|, flipped robots."""
    seconds = (data.states.shape[1] - 1) * sim2d.CONTROL_DT
    return {"mean_distance_m": float(data.distance_m.mean()), "min_distance_m": float(data.distance_m.min()),
            "speed_m_s": float(data.distance_m.mean() / seconds),
            "max_abs_pitch": float(np.abs(data.states[..., 2]).max()), "flips": int(data.flipped.sum())}


# ----------------------------------------------------------------------------
# Command line
# ----------------------------------------------------------------------------
def main(argv: list[str] | None = None) -> None:
    parser = sim2d.CliParser(description="Build (or load) and measure a demonstration dataset.")
    parser.add_argument("--design", required=True,
                        help="hexapod, car, leg_leg_wheel, leg_none_wheel or six letters like lnwwnl")
    parser.add_argument("--episodes", type=int, default=50, help="trajectories (paper: 50)")
    parser.add_argument("--steps", type=int, default=100, help="control steps per trajectory (paper: 100)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--cache-dir", default=str(DEFAULT_CACHE_DIR), help="where datasets are cached")
    parser.add_argument("--gif", help="draw episode 0 to this GIF (sim2d.save_gif)")
    args = parser.parse_args(argv)
    try:
        path = cache_path(args.design, args.episodes, args.steps, args.seed, args.cache_dir)
        cached = path.exists()
        start = time.perf_counter()
        data = load_or_make_demos(args.design, args.episodes, args.steps, args.seed, args.cache_dir)
    except ValueError as e:                        # bad name, count or undemonstrable design
        parser.error(str(e))
    elapsed = time.perf_counter() - start
    q = demo_quality(data)
    print(f"design={sim2d.design_name(data.design)} ({data.design}) episodes={args.episodes} "
          f"steps={args.steps} seed={args.seed}")
    print(f"{'loaded' if cached else 'built'} in {elapsed:.2f} s: {path}")
    if args.gif:
        sim2d.save_gif(sim2d.design_graph(data.design), data.states[0], args.gif)
        print(f"wrote {args.gif}")
    print(f"speed_m_s={q['speed_m_s']:.3f} max_abs_pitch={q['max_abs_pitch']:.3f} "
          f"mean_distance_m={q['mean_distance_m']:.3f} min_distance_m={q['min_distance_m']:.3f} "
          f"flips={q['flips']}")


if __name__ == "__main__":
    main()
