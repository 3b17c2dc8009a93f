"""Tests of the zero-shot transfer table and the side-by-side drawing (experiments/transfer.py, train.py --transfer/--compare).

Two tiny runs on the car, RL (seed 0) and RL+IL with hexapod demos (seed 1), made once for the module;
their seeds differ so that their evaluation starts differ.
"""
import csv
import subprocess
import sys

import numpy as np
import pytest
from PIL import Image

import modular_rlil_minimal as rlil
import sim2d
import train
from experiments import transfer


def tiny(**kw) -> rlil.Config:
    """The tiny preset, one iteration with short evaluations: plumbing, not learning."""
    return rlil.preset("tiny", train=("car",), iters=1, eval_steps=30, policy_steps=6, bc_steps=10, **kw)


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    root, cache = tmp_path_factory.mktemp("runs"), tmp_path_factory.mktemp("demo_cache")
    quiet = lambda *a: None                                          # noqa: E731
    train.run(tiny(seed=0), root / "rl", log=quiet, cache_dir=cache)
    train.run(tiny(seed=1, demos=("hexapod",)), root / "rlil", log=quiet, cache_dir=cache)
    return root / "rl", root / "rlil"


def test_transfer_table_own_design_equals_eval_seen_flags_and_ratio(runs, tmp_path, capsys, monkeypatch):
    """train.py --transfer on car + hexapod (+ one held-out code): the car entry of each run is what
    --eval returns and prints for it; car is seen, the others (hexapod: RL+IL's demo design) unseen;
    ratio = distance / demonstrator distance, the demonstrator from the run's own starts."""
    monkeypatch.setattr(transfer, "read_held_out", lambda: ["llllww"])
    out = tmp_path / "table"
    assert train.main(["--transfer", *map(str, runs), "--designs", "car", "hexapod", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "| seen | 1 |" in printed and "| unseen | 2 |" in printed
    assert all((out / f).stat().st_size > 0 for f in transfer.OUTPUTS)
    rows = list(csv.DictReader(open(out / "transfer.csv")))
    designs = ("wnwwnw", "llllll", "llllww")                                # car, hexapod, held out
    assert [(r["run"], r["design"]) for r in rows] == [(str(run), d) for run in runs for d in designs]
    for r in rows:
        assert r["seen"] == str(r["design"] == "wnwwnw")
        assert float(r["ratio"]) == float(r["distance_m"]) / float(r["demo_distance_m"])
    for run in runs:
        own = next(r for r in rows if r["run"] == str(run) and r["design"] == "wnwwnw")
        assert float(own["distance_m"]) == train.evaluate_run(run, "car")
        assert f"design=wnwwnw distance_m={float(own['distance_m']):.4f}" in capsys.readouterr().out
    demo_car = {r["run"]: float(r["demo_distance_m"]) for r in rows if r["design"] == "wnwwnw"}
    assert demo_car[str(runs[0])] != demo_car[str(runs[1])]          # each run's own starts, not the first run's


def test_the_demonstrator_starts_where_the_policy_starts(runs):
    trained = transfer.load_trained(runs[1])
    policy, demo = transfer.policy_episodes(trained, "hexapod"), transfer.demonstrator_episodes("hexapod", trained.cfg)
    assert demo.states.shape == policy.states.shape
    assert np.array_equal(demo.states[:, 0], policy.states[:, 0])


def test_summary_mean_ci_median_and_fraction_at_0_6():
    rows = [{"run": "r", "method": "RL", "seed": 0, "iteration": 1, "trained": "car", "seen": seen, "ratio": ratio}
            for seen, ratio in ((True, 0.9), (False, 0.5), (False, 0.6), (False, 1.3))]
    seen, unseen = transfer.summary(rows)
    assert (seen["designs"], seen["n"], seen["mean"], seen["good"]) == ("seen", 1, 0.9, 1)
    assert (unseen["designs"], unseen["n"], unseen["median"], unseen["good"]) == ("unseen", 3, 0.6, 2)
    assert unseen["mean"] == pytest.approx(0.8) and 0.5 <= unseen["ci"][0] < 0.8 < unseen["ci"][1] <= 1.3
    assert "| 2/3 (67 %) |" in transfer.summary_markdown(rows)


def test_group_table_averages_seeds_marks_seen_and_uses_only_held_out_designs(tmp_path):
    held = transfer.read_held_out()[:2]
    rows = []
    for seed, (car_m, ratios) in enumerate(((10.0, (0.4, 0.6)), (12.0, (1.0, 1.0)))):   # 0.6: counts as >= 0.6
        for code, dist, ratio, seen in (("wnwwnw", car_m, car_m / 16, True), ("llllll", 1.0, 0.06, False),
                                        *((h, 16 * r, r, False) for h, r in zip(held, ratios))):
            rows.append({"run": f"r{seed}", "method": "RL", "seed": seed, "iteration": 5, "trained": "car",
                         "demos": "", "design": code, "name": sim2d.design_name(code), "seen": seen,
                         "distance_m": dist, "demo_distance_m": 16.0, "ratio": ratio})
    transfer.write_csv(rows, tmp_path / "t.csv")
    assert transfer.read_csv(tmp_path / "t.csv") == rows                       # the committed CSV reads back
    line = transfer.group_table(rows).splitlines()[3]
    # car 11 m (seen), hexapod 1 m; held-out mean ratio (0.5 + 1.0) / 2, not counting the hexapod's 0.06;
    # designs at >= 0.6: 1 of 2 for seed 0 (0.6 itself), 2 of 2 for seed 1
    assert line.startswith("| RL | car | - | 2 | 1.00 | 11.00* |") and "| 0.75 [" in line and line.endswith("| 75 % |")


def test_generalist_table_compares_the_same_seeds_at_the_named_iterations():
    generalist = [{"run": f"g{seed}", "method": "RL+IL", "seed": seed, "iteration": 5, "design": code, "seen": True,
                   "distance_m": dist + seed} for seed in (0, 1) for code, dist in (("wnwwnw", 10.0), ("llllll", 4.0))]
    figure3 = [{"train": train, "method": method, "seed": seed, "iteration": k, "distance_m": 100 * k + seed}
               for train in ("car", "hexapod") for method in ("RL", "RL+IL") for seed in (0, 1, 2) for k in range(6)]
    text = transfer.generalist_table(generalist, figure3, {"generalist": 99_600, 4: 106_800, 5: 119_600})
    car = next(line for line in text.splitlines() if line.startswith("| car |"))
    assert car.startswith("| car | 10.50 [10.00, 11.00] | 400.50 [400.00, 401.00] | 500.50 [500.00, 501.00] |")
    assert "(99,600 steps)" in text and "iteration 4 (106,800 steps for the 2)" in text and text.startswith("2 seeds (0, 1)")


def test_held_out_file_is_what_the_generator_draws_and_no_figure3_design():
    assert transfer.HELD_OUT_FILE.read_text() == transfer.held_out_text()
    codes = transfer.read_held_out()
    assert len(codes) == len(set(codes)) == 50
    assert not set(codes) & set(sim2d.NAMED_DESIGNS.values())
    assert all(transfer.is_demonstrable(c) for c in codes)


def test_compare_draws_both_policies_from_one_start(runs, tmp_path):
    gif, png = tmp_path / "ab.gif", tmp_path / "ab.png"
    a_states, b_states = transfer.compare(*runs, str(gif), png=str(png))
    a, b = transfer.load_trained(runs[0]), transfer.load_trained(runs[1])
    assert np.array_equal(a_states[0], b_states[0])                              # one start
    assert np.array_equal(a_states, transfer.policy_episodes(a, "car").states[0])   # --eval's first start of a
    assert not np.array_equal(transfer.policy_episodes(b, "car").states[0, 0], b_states[0])   # not b's own
    assert len(a_states) == len(b_states) == a.cfg.eval_steps + 1
    assert Image.open(gif).n_frames == len(range(0, a.cfg.eval_steps + 1, 2))       # every second step drawn
    assert png.stat().st_size > 0


def test_bad_input_exits_2_with_one_line_and_writes_nothing(runs, tmp_path, capsys):
    rl, rlil_run = map(str, runs)
    kept = tmp_path / "kept"
    kept.mkdir()
    (kept / "transfer.md").write_text("mine")
    (tmp_path / "mine.gif").write_text("mine")
    gif = str(tmp_path / "new.gif")
    for args in (["--transfer", str(tmp_path / "nope")], ["--transfer", rl, "--designs", "spider"],
                 ["--transfer", rl, "--designs", "lnnnnl"], ["--transfer", rl, "--design", "car"], ["--transfer", rl, "--out", str(kept)],
                 ["--transfer", rl, "--gif", gif], ["--transfer", rl, "--compare", rl, rlil_run],
                 ["--compare", rl, str(tmp_path / "nope"), "--gif", gif], ["--compare", rl, rlil_run],
                 ["--compare", rl, rlil_run, "--gif", gif, "--design", "spider"],
                 ["--compare", rl, rlil_run, "--gif", gif, "--design", "car", "hexapod"],
                 ["--compare", rl, rlil_run, "--gif", str(tmp_path / "mine.gif")],
                 ["--compare", rl, rlil_run, "--gif", str(tmp_path / "no_folder" / "x.gif")],
                 ["--eval", rl, "--design", "car", "hexapod"]):
        with pytest.raises(SystemExit) as exit_:
            train.main(args)
        err = capsys.readouterr().err
        assert exit_.value.code == 2 and err.count("\n") == 1 and "Traceback" not in err, (args, err)
    assert (kept / "transfer.md").read_text() == "mine" and (tmp_path / "mine.gif").read_text() == "mine"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["kept", "mine.gif"]
    out = subprocess.run([sys.executable, "train.py", "--transfer", str(tmp_path / "nope")],   # the real process
                         capture_output=True, text=True)
    assert out.returncode == 2 and out.stderr.count("\n") == 1 and "no run directory" in out.stderr, out.stderr
