"""One policy phase from a stalled starting point, with one setting changed: does the policy move?

Issue #34, part 20.  Before a plain-RL seed of the walk takes off, its policy phases almost never
revert (the model's validation return never falls below the phase's start), yet the policy stays
where it is.  This takes plain RL's policy, model and T_train at the start of a policy phase
(`--after` finished iterations, then line 5's model fit: `gradient_check.starting_point`, the
run's own path), runs one policy phase (lines 7-26) with one setting changed, and measures the
result in the simulator by Sec. IV's metric (distance in `eval_steps` steps from the evaluation
starts, the mean action).  Each repeat starts from the same policy and model with draws of its own
(buffer, noise), so a variant's repeats show its spread.

    python experiments/phase_probe.py --preset walk --set policy_steps=120 batch=64 --seeds 0 --after 4   # every variant
    python experiments/phase_probe.py --preset walk --set policy_steps=120 batch=64 --seeds 1 25 --after 4 --variants K120 K480
    python experiments/phase_probe.py --preset walk --seeds 0 --after 4 --out probe.csv

(`--set policy_steps=120 batch=64` is the walk before part 21, the one every committed probe ran at.)

Variants (VARIANTS): K, the phase's steps; T, the horizon; the learning rate; where line 7
draws the buffer's initial states: from T_train (Algorithm 1) or from the simulator's start
distribution p(s) (`sim2d.sample_initial_states`), all or half of them; and (part 23, a policy
that already walks) the noise of L_RL's model roll-outs: none (the mean action, as the
evaluation runs it) or a lower floor under the policy's log-std for the phase; (part 25) a higher
floor; (part 29, a policy that has not taken off at the walk) four times the walk's steps; (part 30)
the phase on an ensemble of four models (`Ensemble`).

    python experiments/phase_probe.py --preset walk --seeds 1 4 5 7 --after 7 --variants own det floor25 T40 lr3e-4 K120_B16
"""
from __future__ import annotations

import contextlib
import copy
import dataclasses
import sys
from pathlib import Path
from unittest import mock

import numpy as np
import torch

if __package__ in (None, ""):              # run as a script: the stage files are one folder up
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import modular_rlil_minimal as rlil                                                          # noqa: E402
import sim2d                                                                                 # noqa: E402
from experiments.gradient_check import starting_point                                        # noqa: E402
from experiments.model_replay import with_settings                                           # noqa: E402
from experiments.run_folders import UsageError, claim_output_file                            # noqa: E402
from experiments.sweeps import write_rows_csv                                                # noqa: E402

COLUMNS = ["design", "seed", "after", "start_m", "variant", "repeat", "distance_m", "reverts", "validation_reward",
           "start_log_std",     # the starting policy's noise (`mean_log_std`; empty in the CSVs before part 23)
           "start_from"]        # whose policy: RL or RL+IL (`--demos`; empty in the CSVs before part 26)

# name: (Config fields changed, share of line 7's initial states drawn from p(s) instead of T_train)
VARIANTS = {
    "K120": ({"policy_steps": 120, "batch": 64}, 0.0),   # the phase at the defaults' K and batch
    "K240": ({"policy_steps": 240}, 0.0),
    "K480": ({"policy_steps": 480}, 0.0),
    "K480_B16": ({"policy_steps": 480, "batch": 16}, 0.0),   # 4x the steps at 1/4 of the batch
    "K480_B32": ({"policy_steps": 480, "batch": 32}, 0.0),
    "T10": ({"horizon": 10}, 0.0),
    "T40": ({"horizon": 40}, 0.0),
    "lr3e-3": ({"policy_lr": 3e-3}, 0.0),
    "B_ps": ({}, 1.0),
    "B_ps_half": ({}, 0.5),
    # part 23: a policy that walks
    "own": ({}, 0.0),                   # the run's own phase (at the walk: K = 480 on batches of 16)
    "K120_B16": ({"policy_steps": 120, "batch": 16}, 0.0),   # a quarter of the walk's phase
    "lr3e-4": ({"policy_lr": 3e-4}, 0.0),
    "det": ({}, 0.0),                   # L_RL's roll-outs take the mean action, no observation noise
    "floor25": ({}, 0.0),               # the policy's log-std floor at -2.5 (the defaults') for the phase
    # part 25: more noise than the walk's floor
    "floor05": ({}, 0.0),               # the policy's log-std floor at -0.5 for the phase (std >= 0.61)
    # part 29: a policy that has not taken off at the walk
    "K1920_B16": ({"policy_steps": 1920, "batch": 16}, 0.0),   # four times the walk's phase
    # part 30: the phase on an ensemble of models
    "ens4": ({}, 0.0),                  # the run's model and 3 more fitted afresh on T_train (`Ensemble`)
}
NOISE = {"det": "mean", "floor25": -2.5, "floor05": -0.5}   # the variants that change L_RL's noise (`phase_noise`)
ENSEMBLES = {"ens4": 4}             # the variants that optimise on an ensemble of this many models


class Ensemble:
    """Models as one: f(s, a) runs row b of the batch on member b mod E, so each of the phase's
    roll-outs (a row from line 9 to 15) stays on one member for its whole length (PETS'
    "TS-infinity", Chua et al. 2018; ME-TRPO's ensemble, Kurutach et al. 2018). A gait that only
    one member believes in gains on 1/E of the roll-outs; one that every member agrees on gains
    on all of them."""

    def __init__(self, members):
        self.members = list(members)

    def requires_grad_(self, flag: bool = True) -> "Ensemble":
        for m in self.members:
            m.requires_grad_(flag)
        return self

    def on_design(self, graph):
        fs = [m.on_design(graph) for m in self.members]

        def f(s, a):
            n, e = len(s), len(fs)
            order = torch.cat([torch.arange(j, n, e) for j in range(e)])          # rows as the members take them
            out = torch.cat([fj(s[j::e], a[j::e]) for j, fj in enumerate(fs)])
            return out[torch.argsort(order)]
        return f


def ensemble_at(model, traj, cfg: rlil.Config, size: int) -> Ensemble:
    """`model` and size - 1 more, each fitted afresh on T_train as line 5 fits the first model
    (`model_steps`, its own initial weights and mini-batches)."""
    members = [model]
    for j in range(1, size):
        torch.manual_seed(2000 + j)
        m = rlil.ModularModel(cfg.gnn)
        rlil.train_model(m, {traj.design: traj}, cfg, np.random.default_rng(2000 + j), first=True)
        members.append(m)
    return Ensemble(members)


@contextlib.contextmanager
def phase_noise(policy, name: str):
    """The roll-out noise of variant `name` for one phase: "det" makes `rlil.rl_loss`'s roll-outs
    deterministic (the mean action from noiseless observations); "floor25" lowers the policy's
    log-std floor (its log-std maps onto [-2.5, max] instead of [min, max]), "floor05" raises it
    (onto [-0.5, max]); otherwise nothing."""
    change = NOISE.get(name)
    if change == "mean":
        rollout = rlil.rollout
        with mock.patch.object(rlil, "rollout", lambda *a, **k: rollout(*a, **{**k, "deterministic": True})):
            yield
    elif change is not None:
        old = policy.cfg.log_std_min
        policy.cfg.log_std_min = change
        try:
            yield
        finally:
            policy.cfg.log_std_min = old
    else:
        yield


@torch.no_grad()
def mean_log_std(policy, model, traj, cfg: rlil.Config, n: int = 256) -> float:
    """The policy's mean log-std along deterministic T-step model roll-outs from n states of T_train
    (a fresh hidden state): how much noise L_RL's roll-outs carry."""
    graph = sim2d.design_graph(traj.design)
    pi, f = policy.on_design(graph), model.on_design(graph)
    s = rlil.sample_sim_states(traj, n, np.random.default_rng(0))
    h, values = policy.initial_hidden(n, graph), []
    for _ in range(cfg.horizon):
        mean, log_std, h = pi.step(sim2d.observe(s, graph), h)
        values.append(log_std.mean())
        s = f(s, mean)
    return float(torch.stack(values).mean())


def starts_from_p_s(share: float):
    """A stand-in for `rlil.sample_sim_states` that draws the first `share` of the n states from the
    simulator's start distribution p(s) and the rest from T_train as Algorithm 1 does."""
    from_data = rlil.sample_sim_states

    def sample(traj, n: int, rng: np.random.Generator) -> torch.Tensor:
        s = from_data(traj, n, rng)
        k = int(round(share * n))
        p_s = sim2d.sample_initial_states(sim2d.design_graph(traj.design), k, rng)
        s[:k] = torch.as_tensor(p_s, dtype=s.dtype)
        return s
    return sample


def distance(policy, design: str, cfg: rlil.Config) -> float:
    """Sec. IV's metric, as a run's evaluation row has it."""
    return float(rlil.evaluate_policy(policy, design, cfg, rlil.eval_seed(cfg)).distance_m.mean())


def probe_rows(design: str, seed: int, after: int, variants, repeats: int,
               base: rlil.Config | None = None, demos=()) -> list[dict]:
    """Every repeat's row (COLUMNS) for one design, seed and starting point. With `demos`, the
    starting point is RL+IL's (the run with those demonstrations); the phases are plain RL's."""
    cfg = dataclasses.replace(base or rlil.Config(), train=(sim2d.parse_design(design),),
                              demos=tuple(map(sim2d.parse_design, demos)), seed=seed)
    policy, model, traj, _ = starting_point(cfg, after, rlil.load_demos(cfg) if demos else None)
    start = copy.deepcopy(policy.state_dict())
    start_m = distance(policy, traj.design, cfg)
    start_log_std = mean_log_std(policy, model, traj, cfg)
    rows, ensembles = [], {}
    for name in variants:
        fields, share = VARIANTS[name]
        phase_cfg = dataclasses.replace(cfg, **fields)
        if name in ENSEMBLES and ENSEMBLES[name] not in ensembles:
            ensembles[ENSEMBLES[name]] = ensemble_at(model, traj, cfg, ENSEMBLES[name])
        phase_model = ensembles[ENSEMBLES[name]] if name in ENSEMBLES else model
        for r in range(repeats):
            policy.load_state_dict(start)
            torch.manual_seed(1000 + r)                  # the repeat's draws: the same for every variant
            swap = mock.patch.object(rlil, "sample_sim_states", starts_from_p_s(share)) if share else contextlib.nullcontext()
            with swap, phase_noise(policy, name):
                phase = rlil.optimize_policy(policy, phase_model, {traj.design: traj}, {}, 0.0, phase_cfg,
                                             np.random.default_rng(1000 + r))
            rows.append({"design": design, "seed": seed, "after": after, "start_m": start_m, "variant": name,
                         "repeat": r, "distance_m": distance(policy, traj.design, cfg),
                         "reverts": phase["reverts"], "validation_reward": phase["validation_reward"],
                         "start_log_std": start_log_std, "start_from": "RL+IL" if demos else "RL"})
    return rows


def by_point(rows: list[dict]):
    """The probe's rows grouped: the variants present (in VARIANTS' order), the starting points
    (design, seed, after, start_m) in the rows' order, and {(design, seed, after, variant): distances}."""
    variants = [v for v in VARIANTS if any(r["variant"] == v for r in rows)]
    points = list(dict.fromkeys((r["design"], int(r["seed"]), int(r["after"]), float(r["start_m"])) for r in rows))
    distances = {}
    for r in rows:
        distances.setdefault((r["design"], int(r["seed"]), int(r["after"]), r["variant"]), []).append(float(r["distance_m"]))
    return variants, points, distances


def summary(rows: list[dict]) -> str:
    """Markdown: per starting point, each variant's distances after one phase."""
    variants, points, distances = by_point(rows)
    lines = ["| design, seed, after (start, m) | " + " | ".join(variants) + " |",
             "|---|" + "---|" * len(variants)]
    for design, seed, after, start_m in points:
        cells = [", ".join(f"{x:.2f}" for x in distances.get((design, seed, after, v), [])) or "-" for v in variants]
        lines.append(f"| {design}, {seed}, {after} ({start_m:.2f}) | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def gains(rows: list[dict], reference: str = "own", walking_m: float = 10.0) -> str:
    """Markdown, part 23's rule: per variant, over the starting points at `walking_m` or more, the
    mean of (its mean distance over the repeats - `reference`'s) and at how many points it is above;
    and the starting points' log-std (`mean_log_std`)."""
    variants, _, distances = by_point(rows)

    def mean_at(point, v):
        d = distances.get((*point, v))
        return float(np.mean(d)) if d else None
    starts = {(r["design"], int(r["seed"]), int(r["after"])): (float(r["start_m"]), r.get("start_log_std") or "")
              for r in rows}
    walking = [p for p, (m, _) in starts.items() if m >= walking_m and mean_at(p, reference) is not None]
    ref = {p: mean_at(p, reference) for p in walking}
    lines = [f"Starting points at {walking_m:g} m or more: {len(walking)} of {len(starts)} ("
             + "; ".join(f"seed {p[1]} after {p[2]}: {m:.2f} m, log-std {float(ls):.2f}" if ls != "" else
                         f"seed {p[1]} after {p[2]}: {m:.2f} m" for p, (m, ls) in starts.items()) + ").",
             "",
             f"| variant | mean distance after one phase (m) | gain over {reference} (m) | points above {reference} |",
             "|---|---|---|---|"]
    for v in variants:
        at = [(p, mean_at(p, v)) for p in walking if mean_at(p, v) is not None]
        if not at:
            continue
        gain = np.mean([m - ref[p] for p, m in at])
        above = sum(m > ref[p] for p, m in at)
        lines.append(f"| {v} | {np.mean([m for _, m in at]):.2f} | {gain:+.2f} | "
                     + ("-" if v == reference else f"{above} of {len(at)}") + " |")
    return "\n".join(lines) + "\n"


def takeoff(rows: list[dict], reference: str = "own", line_m: float = 2.0, above_m: float = 1.0) -> str:
    """Markdown, part 29's rule for stalled starting points: per point, each variant's mean distance
    over the repeats; per variant, the points where it walks (a mean of `line_m` or more) and is at
    least `above_m` above `reference`'s mean."""
    variants, points, distances = by_point(rows)
    mean = {(p, v): float(np.mean(distances[(*p[:3], v)])) for p in points for v in variants if (*p[:3], v) in distances}
    lines = ["| design, seed, after (start, m) | " + " | ".join(f"{v}: mean (m)" for v in variants) + " |",
             "|---|" + "---|" * len(variants)]
    for p in points:
        lines.append(f"| {p[0]}, {p[1]}, {p[2]} ({p[3]:.2f}) | "
                     + " | ".join(f"{mean[p, v]:.2f}" if (p, v) in mean else "-" for v in variants) + " |")

    def counted(v: str) -> str:
        both = [p for p in points if (p, v) in mean and (p, reference) in mean]
        walks = [p for p in both if mean[p, v] >= max(line_m, mean[p, reference] + above_m)]
        return "-" if v == reference else f"{len(walks)} of {len(both)}"
    lines.append(f"| points where it walks ({line_m:g} m or more) and is {above_m:g} m or more above {reference} | "
                 + " | ".join(map(counted, variants)) + " |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = sim2d.CliParser(description=__doc__.split("\n")[0])
    parser.add_argument("--preset", default="default", help="Algorithm 1's budget (walk: panel (a)'s)")
    parser.add_argument("--design", default="hexapod")
    parser.add_argument("--demos", nargs="+", default=[], metavar="DESIGN",
                        help="start from RL+IL's policy with these demonstrations (the phases stay plain RL's)")
    parser.add_argument("--seeds", nargs="+", type=int, default=[0], metavar="S")
    parser.add_argument("--set", nargs="+", default=[], metavar="FIELD=VALUE",
                        help="Config fields of the run that makes the starting point, e.g. policy_steps=120")
    parser.add_argument("--after", nargs="+", type=int, default=[4], metavar="N",
                        help="starting points: after N finished iterations of plain RL (default 4)")
    parser.add_argument("--variants", nargs="+", default=list(VARIANTS), metavar="NAME",
                        help=f"one or more of {', '.join(VARIANTS)} (default: all)")
    parser.add_argument("--repeats", type=int, default=3, help="phases per variant and starting point (default 3)")
    parser.add_argument("--out", type=Path, help="also write every repeat's row to this CSV")
    parser.add_argument("--force", action="store_true", help="replace an existing --out file")
    args = parser.parse_args(argv)
    try:
        design = sim2d.design_name(sim2d.parse_design(args.design))
        for d in args.demos:
            sim2d.parse_design(d)
        base = with_settings(rlil.preset(args.preset), args.set)
        rlil.validate_config(base)
        claim_output_file(args.out, ".csv", "--out", args.force)
    except (ValueError, UsageError) as e:
        parser.error(str(e))
    unknown = [v for v in args.variants if v not in VARIANTS]
    if unknown:
        parser.error(f"unknown variant {unknown[0]!r}: use one or more of {', '.join(VARIANTS)}")
    for name, values, lo, hi in (("--after", args.after, 0, 50), ("--seeds", args.seeds, 0, rlil.MAX_SEED),
                                 ("--repeats", [args.repeats], 1, 100)):
        if any(not lo <= v <= hi for v in values):
            parser.error(f"{name} takes {lo} to {hi}")
    rows = []
    for seed in args.seeds:
        for after in args.after:
            rows += probe_rows(design, seed, after, args.variants, args.repeats, base, args.demos)
            print(f"{design} seed {seed} after {after}: done", flush=True)
    print(summary(rows))
    if "own" in args.variants:
        print(gains(rows))
    if args.out:
        write_rows_csv(args.out, COLUMNS, rows)
        print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
