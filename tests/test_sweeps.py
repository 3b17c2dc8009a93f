"""Tests of experiments/: the sweeps' launchers, the plan and collect path, the statistics over seeds, and
the results tables (no committed table is typed by hand).

The committed results/*.md and every README.md / docs/*.md block between
`<!-- begin: results/NAME.md -->` and `<!-- end: results/NAME.md -->` must be
what the tables command makes from the committed CSVs, and a changed CSV must
change them (so the check can fail).  Figure 3's reuse of finished runs is
tested in test_rlil.py, the sample-efficiency sweep in test_ppo.py.
"""
import csv
import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

import modular_rlil_minimal as rlil
from experiments import run_folders, stats, sweeps, tables


def test_committed_tables_and_readme_blocks_are_the_regenerated_ones():
    """What `python experiments/tables.py --check` checks, in-process: nothing differs."""
    assert tables.tables(tables.ROOT, check=True) == []
    readme = (tables.ROOT / "README.md").read_text()
    assert tables.BEGIN.format("figure3_claims") in readme           # the check covers a README block


def test_every_committed_table_has_a_generator_and_losing_one_turns_the_check_red(monkeypatch, capsys):
    """A committed results table that tables.py no longer makes would otherwise be shown, unchanged,
    from the committed file: --check names it and exits 1 (tools writing a table are listed)."""
    unmade = []
    assert tables.tables(tables.ROOT, check=True, unmade=unmade) == [] and unmade == []
    regenerate, lost = tables.regenerate_tables, tables.ROOT / "results" / "bc500_lr2_panel_d.md"
    assert lost in regenerate(tables.ROOT)
    monkeypatch.setattr(tables, "regenerate_tables", lambda root: {p: t for p, t in regenerate(root).items() if p != lost})
    assert tables.main(["--check"]) == 1
    out = capsys.readouterr().out.splitlines()
    assert out == [f"no generator: results/bc500_lr2_panel_d.md is committed, but experiments/tables.py does not make "
                   "it (nor does WRITTEN_ELSEWHERE name the tool that writes it)"]


def copy_of_repo(tmp_path):
    """results/*.csv and *.md (and those of tables.SWEEPS_OF_THEIR_OWN, each a folder of results/),
    README.md and docs/ (if any) under tmp_path."""
    paths = [*tables.ROOT.glob("results/*.csv"), *tables.ROOT.glob("results/*.md")]
    for sweep in tables.SWEEPS_OF_THEIR_OWN:
        (tmp_path / "results" / sweep).mkdir(parents=True)
        paths += [*tables.ROOT.glob(f"results/{sweep}/*.csv"), *tables.ROOT.glob(f"results/{sweep}/*.md")]
    for p in paths:
        shutil.copy(p, tmp_path / p.relative_to(tables.ROOT))
    shutil.copy(tables.ROOT / "README.md", tmp_path / "README.md")
    if (tables.ROOT / "docs").exists():
        shutil.copytree(tables.ROOT / "docs", tmp_path / "docs")
    return tmp_path


def test_a_changed_csv_changes_the_tables_and_the_readme_block(tmp_path, monkeypatch, capsys):
    root = copy_of_repo(tmp_path)
    path = root / "results" / "figure3.csv"
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    final = next(r for r in rows if r["panel"] == "a" and r["method"] == "RL+IL" and r["iteration"] == "5")
    final["distance_m"] = "99.0"                                     # one seed's final distance
    sweeps.write_rows_csv(path, sweeps.FIGURE3_COLUMNS, rows)
    before = {p: p.read_text() for p in (root / "README.md", root / "results" / "figure3.md",
                                         root / "results" / "figure3_iterations.md")}
    before_claims = (root / "results" / "figure3_claims.md").read_text()
    stale = tables.tables(root, check=True)
    assert set(stale) >= set(before)                                 # and the other tables made from it
    assert all(p.read_text() == text for p, text in before.items())     # --check writes nothing
    monkeypatch.setattr(tables, "ROOT", root)
    assert tables.main(["--check"]) == 1
    assert "differs: README.md" in capsys.readouterr().out

    assert tables.main([]) == 0
    table = (root / "results" / "figure3.md").read_text()
    assert table != before[root / "results" / "figure3.md"] and "99.00" in table      # its final max
    assert " - 99.00 |" in (root / "results" / "figure3_iterations.md").read_text()        # its max at iteration 5
    readme, claims = (root / "README.md").read_text(), (root / "results" / "figure3_claims.md").read_text()
    begin, end = tables.BEGIN.format("figure3_claims"), tables.END.format("figure3_claims")
    assert readme.split(begin + "\n")[1].split(end)[0] == claims     # the block is the new claims table
    assert claims != before_claims
    assert tables.tables(root, check=True) == []
    assert tables.main(["--check"]) == 0


def test_class_demo_csv_gets_its_per_iteration_table_and_a_missing_one_is_skipped(tmp_path):
    root = copy_of_repo(tmp_path)
    (root / "results" / "class_demo.csv").unlink(missing_ok=True)
    (root / "results" / "class_demo.md").unlink(missing_ok=True)
    (root / "README.md").write_text("no blocks\n")
    assert tables.tables(root) == []                                 # no class_demo.csv: nothing to make
    assert not (root / "results" / "class_demo.md").exists()
    rows = [{"panel": "a", "train": "car", "demos": "", "method": "RL", "seed": s, "iteration": i,
             "distance_m": 1.0 + i + s} for s in (0, 1) for i in (0, 1)]
    sweeps.write_rows_csv(root / "results" / "class_demo.csv", sweeps.FIGURE3_COLUMNS, rows)
    assert tables.tables(root) == [root / "results" / "class_demo.md"]
    assert (root / "results" / "class_demo.md").read_text().splitlines()[2:] == [
        "| (a) car | RL | 0 | 2 | 1.50 | [1.00, 2.00] | 1.00 - 2.00 |", "| (a) car | RL | 1 | 2 | 2.50 | [2.00, 3.00] | 2.00 - 3.00 |"]


def test_a_block_naming_a_missing_table_is_a_one_line_error_exit_2(tmp_path, monkeypatch, capsys):
    root = copy_of_repo(tmp_path)
    readme = root / "README.md"
    readme.write_text(readme.read_text() + "\n" + tables.BEGIN.format("nothing") + "\nold\n"
                      + tables.END.format("nothing") + "\n")
    with pytest.raises(run_folders.UsageError):
        tables.tables(root, check=True)
    monkeypatch.setattr(tables, "ROOT", root)
    with pytest.raises(SystemExit) as e:
        tables.main([])
    err = capsys.readouterr().err
    assert e.value.code == 2 and len(err.strip().splitlines()) == 1 and "results/nothing.md" in err
    assert "old" in readme.read_text()                               # nothing was written


# ----------------------------------------------------------------------------
# Statistics over seeds: hand-computed small cases
# ----------------------------------------------------------------------------
def test_bootstrap_intervals_of_hand_computed_cases():
    # [0, 1]: resampled means 0, 0.5, 1 with probabilities 1/4, 1/2, 1/4: the central 95 % is (0, 1)
    assert stats.bootstrap_ci([0.0, 1.0]) == (0.0, 1.0)
    assert stats.bootstrap_ci([2.0, 2.0, 2.0]) == (2.0, 2.0)                       # no spread, no interval
    # [0, 0, 0, 1] (n = 4): P(mean = 0) = (3/4)^4 = 0.316 > 2.5 %, P(mean = 1) = (1/4)^4 = 0.004 < 2.5 %,
    # P(mean >= 3/4) = 13/256 = 0.051 > 2.5 %: the interval is (0, 0.75)
    assert stats.bootstrap_ci([0.0, 0.0, 0.0, 1.0]) == (0.0, 0.75)
    # five 0s and five 1s: the mean is Binomial(10, 1/2) / 10, whose cumulative probabilities pass
    # 2.5 % at 0.2 (0.055) and 97.5 % at 0.8 (0.989; at 0.7 only 0.945): the interval is (0.2, 0.8)
    assert stats.bootstrap_ci([0.0] * 5 + [1.0] * 5) == (0.2, 0.8)
    assert stats.bootstrap_diff_ci([3.0, 3.0], [1.0, 1.0]) == (2.0, 2.0)
    lo, hi = stats.bootstrap_diff_ci([1.0, 2.0, 3.0], [1.0, 2.0, 3.0])
    assert lo < 0 < hi and lo == pytest.approx(-hi, abs=0.34)                    # symmetric about 0
    assert stats.bootstrap_ci([0.0, 1.0], np.median) == (0.0, 1.0)
    assert stats.bootstrap_ci([5.0, 1.0, 3.0], seed=1) == stats.bootstrap_ci([5.0, 1.0, 3.0], seed=1)


def test_a_proportions_wilson_interval_and_the_binomial_chance_of_a_count_by_hand():
    # 13 of 20: centre (0.65 + 1.96^2 / 40) / (1 + 1.96^2 / 20) = 0.6258, half-width
    # 1.96 sqrt(0.65 x 0.35 / 20 + 1.96^2 / 1600) / 1.1921 = 0.1930 (statsmodels' "wilson": the same)
    assert stats.wilson_interval(13, 20) == pytest.approx((0.4329, 0.8188), abs=1e-4)
    lo, hi = stats.wilson_interval(0, 10)                                        # no success: from 0, not a point
    assert lo == pytest.approx(0.0, abs=1e-12) and hi == pytest.approx(0.2775, abs=1e-4)
    # 8, 9 or 10 of 10 at p = 0.65: 45 p^8 q^2 + 10 p^9 q + p^10 = 0.1757 + 0.0725 + 0.0135
    assert stats.chance_of_at_least(8, 10, 0.65) == pytest.approx(0.2616, abs=1e-4)
    assert stats.chance_of_at_least(0, 10, 0.3) == pytest.approx(1.0)
    assert stats.chance_of_at_least(10, 10, 0.95) == pytest.approx(0.95 ** 10)


def test_the_interquartile_mean_drops_a_quarter_of_the_runs_at_each_end():
    assert stats.iqm([0.0, 1.0, 2.0, 3.0, 100.0]) == 2.0                 # int(5 / 4) = 1 run cut at each end
    assert stats.iqm([7.0, 1.0, 3.0]) == 11 / 3                          # int(3 / 4) = 0: the mean
    assert stats.iqm([10.0, 0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 9.0, -50.0]) == 3.5    # 10 seeds: 2 cut, mean of 1..6
    batch = np.array([[4.0, 0.0, 1.0, 2.0], [8.0, 8.0, 0.0, 8.0]])               # a row per bootstrap resample
    assert stats.iqm(batch).tolist() == [1.5, 8.0]
    assert stats.bootstrap_diff_ci([3.0, 3.0, 3.0, 9.0], [1.0, 1.0, 1.0, 1.0], stats.iqm)[0] == 2.0


def test_probability_of_improvement_is_the_pair_count_and_mann_whitney_u():
    # x = [1, 2, 3], y = [2, 2]: pairs (1,2) (1,2) (2,2) (2,2) (3,2) (3,2) score 0, 0, 1/2, 1/2, 1, 1
    assert stats.probability_of_improvement([1, 2, 3], [2, 2]) == 0.5
    assert stats.probability_of_improvement([5, 6], [1, 2, 3]) == 1.0
    assert stats.probability_of_improvement([1, 2, 3], [5, 6]) == 0.0
    rng = np.random.default_rng(0)
    x, y = rng.integers(0, 5, 7).astype(float), rng.integers(0, 5, 9).astype(float)
    ranks = np.argsort(np.argsort(np.concatenate([x, y]))) + 1.0                  # U from mid-ranks, by hand
    both = np.concatenate([x, y])
    mid = np.array([ranks[both == v].mean() for v in both])
    u = mid[:len(x)].sum() - len(x) * (len(x) + 1) / 2
    assert stats.probability_of_improvement(x, y) == pytest.approx(u / (len(x) * len(y)))
    assert stats.probability_of_improvement_ci([5, 6], [1, 2, 3]) == (1.0, 1.0)
    lo, hi = stats.probability_of_improvement_ci(x, y)
    assert 0.0 <= lo <= stats.probability_of_improvement(x, y) <= hi <= 1.0


def test_the_convergence_rule_and_the_area_under_the_curve_on_made_up_curves():
    """Converged = the first iteration at 90 % of the panel's best final mean; a run that never gets
    there counts iters + 1; area = the mean over iterations 1..iters, None for an unfinished run."""
    rows = [{"panel": "a", "method": m, "seed": s, "iteration": i, "distance_m": d}
            for m, curves in (("RL+IL", [[4, 9, 10], [5, 10, 10]]), ("RL", [[0, 1, 8.9], [0, 9.1, 9.5]]))
            for s, curve in enumerate(curves) for i, d in enumerate(curve)]
    runs, _, mean, threshold = sweeps.panel_curves(rows, "a", 2)
    assert threshold == pytest.approx(9.0) and mean["RL+IL"][2] == 10          # 0.9 x the best final mean
    assert [stats.iterations_to_converge(c, threshold, 2) for c in runs["RL+IL"].values()] == [1, 1]
    assert [stats.iterations_to_converge(c, threshold, 2) for c in runs["RL"].values()] == [3, 1]   # 8.9: never
    assert stats.area_under_curve({0: 4, 1: 9, 2: 10}, 2) == 9.5 and stats.area_under_curve({0: 4, 1: 9}, 2) is None
    per = sweeps.per_run((runs, {}, mean, threshold), 2)
    assert per["RL"] == {"converge": [3, 1], "auc": [4.95, 9.3], "final": [8.9, 9.5]}


def test_verdicts_and_the_claims_table_of_a_made_up_sweep():
    assert [stats.verdict(ci) for ci in ((0.1, 2.0), (-1.0, 1.0), (-2.0, -0.1))] == ["holds", "not settled", "fails"]
    assert [stats.verdict(ci, 1.0) for ci in ((-0.5, 0.9), (-1.5, 0.5), (1.2, 3.0))] == ["holds", "not settled", "fails"]
    rows = []                                      # panel (d): RL+IL walks at once, RL from iteration 3 on
    for method, curve in (("RL+IL", [5, 20, 20]), ("RL", [0, 0, 20])):
        for seed in range(4):
            rows += [{"panel": "d", "train": "leg_none_wheel", "demos": "hexapod+car", "method": method, "seed": seed,
                      "iteration": i, "distance_m": d + 0.1 * seed} for i, d in enumerate(curve)]
    table = tables.summarize_claims(rows, iters=2, seeds=4)
    assert "| (d) leg_none_wheel | RL+IL converges in fewer iterations | mean iterations to converge, " \
           "RL − RL+IL (2.0 − 1.0) | 1.00 | [1.00, 1.00] | holds |" in table
    faster = next(line for line in table.splitlines() if "RL+IL learns faster" in line)
    # areas per seed: RL+IL 20 + 0.1 s, RL 10 + 0.1 s; the IQM of 4 seeds is the mean of the middle two
    assert "P(RL+IL > RL) = 1.00 [1.00, 1.00]; IQM RL+IL − RL = 10.00 [" in faster and "] | 10.00 |" in faster
    assert faster.endswith("| holds |")
    assert "| RL+IL lowers the variance of convergence |" in table and table.count("not settled") == 1
    # Sec. V's "the same distance": final distances 20 + 0.1 s for both methods, a difference of 0 whose
    # CI (each method's seeds resampled apart) spans at most the seeds' spread of 0.3 m: within 1 m
    same = next(line for line in table.splitlines() if "same distance" in line)
    assert same.startswith("| (d) leg_none_wheel | both methods converge to the same distance (Sec. V) | distance at "
                           "iteration 2, RL+IL − RL (20.15 − 20.15), same within 1 m | 0.00 | [") and same.endswith("| holds |")
    apart = tables.summarize_claims([dict(r, distance_m=r["distance_m"] - 3 * (r["method"] == "RL" and r["iteration"] == 2))
                                     for r in rows], iters=2, seeds=4)   # RL ends 3 m short
    same = next(line for line in apart.splitlines() if "same distance" in line)
    assert "| 3.00 | [" in same and same.endswith("| fails |")
    # a sweep still running: RL+IL's seed 3 stopped at iteration 1 and seed 4 is RL's alone; the claims
    # compare seeds 0-2, which both methods finished
    rows = [r for r in rows if not (r["method"] == "RL+IL" and r["seed"] == 3 and r["iteration"] == 2)]
    rows += [dict(r, seed=4, distance_m=99.0) for r in rows if r["method"] == "RL" and r["seed"] == 0]
    assert tables.paired_claims(rows) == tables.summarize_claims([r for r in rows if r["seed"] < 3], iters=2, seeds=3)


def test_variant_table_counts_falls_from_iteration_1_and_compares_with_the_paper():
    """Issue #23's tables: a fall is a loss between consecutive iterations from iteration 1 on (the
    clone's 0 -> 1 does not count), the exploitation column is the largest mean |model - simulator|,
    and "- paper" is the variant's area under the curve minus the paper's, same method."""
    assert tables.largest_fall({0: 10, 1: 2, 2: 9, 3: 5}, 3) == 4 and tables.largest_fall({0: 1, 1: 2}, 1) == 0
    rows = []
    for variant, rlil_curve, rl_curve in (("paper", [9, 20, 10, 20], [0, 5, 10, 15]),
                                          ("keep_better", [9, 20, 20, 20], [0, 5, 10, 16])):
        for method, curve in (("RL+IL", rlil_curve), ("RL", rl_curve)):
            for seed in range(3):
                rows += [{"variant": variant, "panel": "d", "method": method, "seed": seed, "iteration": i,
                          "distance_m": d, "model_progress_m": 1.0 + 0.5 * seed if i else None,
                          "sim_progress_m": 1.0 if i else None, "seconds": 1.0} for i, d in enumerate(curve)]
    table = tables.summarize_variants(rows, {"paper": tables.SCREEN["paper"], "keep_better": tables.SCREEN["keep_better"]})
    line = {(c[1].strip(), c[4].strip()): c for c in (row.split("|") for row in table.splitlines()[2:])}
    assert line[("paper", "RL+IL")][8].strip() == "3 (10.00)" and line[("keep_better", "RL+IL")][8].strip() == "0 (0.00)"
    assert line[("paper", "RL+IL")][9].strip() == "0.50"                   # mean of |0|, |0.5|, |1.0|
    assert line[("keep_better", "RL+IL")][10].strip() == "20.00"
    assert line[("keep_better", "RL+IL")][11].strip() == "3.33 [3.33, 3.33]"   # 20 - mean(20, 10, 20)
    assert line[("keep_better", "RL")][11].strip() == "0.33 [0.33, 0.33]"
    assert line[("paper", "RL+IL")][12].strip() == "6.67 [6.67, 6.67]"      # 16.67 - 10
    against = tables.summarize_variants(rows, {"paper": ((), None), "keep_better": ((), None)}, baseline="keep_better")
    line = {(c[1].strip(), c[4].strip()): c for c in (row.split("|") for row in against.splitlines()[2:])}
    assert "− keep_better in area" in against and line[("keep_better", "RL+IL")][11].strip() == ""
    assert line[("paper", "RL+IL")][11].strip() == "-3.33 [-3.33, -3.33]"   # the other way round
    targets = {c[1].strip()[:2]: c[4].strip() + " | " + c[5].strip()
               for c in (row.split("|") for row in tables.summarize_targets(rows, "paper").splitlines()[2:])}
    assert targets["1."] == "RL+IL 3 (largest 10.00 m), RL 0 (largest 0.00 m) | missed"
    assert targets["4."] == "6.67 [6.67, 6.67] | met" and targets["5."] == "seeds 0, 1, 2 below | missed"


# ----------------------------------------------------------------------------
# Launchers: local processes, Ray, and a plan any scheduler runs, then --collect
# ----------------------------------------------------------------------------
def quiet(*args, **kw):
    pass


TINY_SWEEP = dict(iters=1, eval_steps=30, policy_steps=6, bc_steps=10, model_steps=50, demo_episodes=4)


def without_seconds(path):
    with open(path, newline="") as f:
        return [{k: v for k, v in row.items() if k != "seconds"} for row in csv.DictReader(f)]


@pytest.fixture(scope="module")
def local_sweep(tmp_path_factory):
    """Panel (b), RL+IL and RL, seed 0, with the local launcher: its figure3.csv."""
    out = tmp_path_factory.mktemp("local")
    assert sweeps.figure3(out, rlil.preset("tiny", **TINY_SWEEP), 1, 2, log=quiet, panels="b") == []
    return out / "figure3.csv"


def test_ray_launcher_gives_the_local_launchers_metrics(local_sweep, tmp_path, monkeypatch):
    pytest.importorskip("ray")                       # .ci/run installs requirements-ray.txt
    monkeypatch.setenv("RAY_worker_niceness", "0")   # Ray runs tasks at nice 15: on a busy machine they starve
    out = tmp_path / "ray"
    assert sweeps.figure3(out, rlil.preset("tiny", **TINY_SWEEP), 1, 2, log=quiet, panels="b", launcher="ray") == []
    assert without_seconds(out / "figure3.csv") == without_seconds(local_sweep)
    assert len(without_seconds(local_sweep)) == 4                   # 2 runs x iterations 0, 1


def test_plan_commands_run_anywhere_and_collect_into_the_local_csv(local_sweep, tmp_path):
    base = rlil.preset("tiny", **TINY_SWEEP)
    lines = sweeps.plan_lines(sweeps.figure3_runs(tmp_path / "runs", base, 1, 2, "b"), base.iters)
    assert len(lines) == 2 and all(line.startswith("mkdir -p ") for line in lines)
    jobs = [subprocess.Popen(["bash", "-c", line], cwd="/") for line in lines]   # as a SLURM array would
    assert [job.wait() for job in jobs] == [0, 0]
    assert sweeps.plan_lines(sweeps.figure3_runs(tmp_path / "runs", base, 1, 2, "b"), base.iters) == []  # all done
    problems = sweeps.figure3(tmp_path / "out", base, 1, 2, log=quiet, panels="b", collect=tmp_path / "runs")
    assert problems == [] and without_seconds(tmp_path / "out" / "figure3.csv") == without_seconds(local_sweep)
    assert sweeps.keep_metrics(tmp_path / "runs", tmp_path / "kept") == ["car-car-seed0", "car-rl-seed0"]
    assert sweeps.plan_lines(sweeps.figure3_runs(tmp_path / "kept", base, 1, 2, "b"), base.iters) == []
    sweeps.figure3(tmp_path / "kept", base, 1, 2, log=quiet, panels="b", collect=tmp_path / "kept")
    assert without_seconds(tmp_path / "kept" / "figure3.csv") == without_seconds(local_sweep)   # metrics suffice
    shutil.rmtree(tmp_path / "runs" / "car-rl-seed0")                 # a missing run is named, not hidden
    problems = sweeps.figure3(tmp_path / "out", base, 1, 2, log=quiet, panels="b", collect=tmp_path / "runs")
    assert len(problems) == 1 and "(b) RL seed 0: 0 of 1 iterations" in problems[0]
    assert "Missing or failed runs" in (tmp_path / "out" / "figure3.md").read_text()


def write_run(run_dir: Path, rows: list) -> None:
    """A made-up run folder: run_dir/metrics.json holding `rows` as its iterations."""
    run_dir.mkdir(parents=True)
    (run_dir / "metrics.json").write_text(json.dumps({"iterations": rows}))


def test_the_30_iteration_table_counts_seeds_at_10_m_and_skips_unfinished_runs(tmp_path):
    """tables.plain_rl_30_table (issue #34, part 4) on made-up runs: seed s walks s + 0.5 m per iteration."""
    for seed, iters in ((0, 30), (1, 30), (2, 20)):                  # seed 2 stopped at 20: left out
        rows = [{"iteration": i, "distance_m": (seed + 0.5) * i, "seconds": 2.0} for i in range(iters + 1)]
        write_run(tmp_path / f"hexapod-rl-seed{seed}", rows)
    table = tables.plain_rl_30_table(tmp_path).splitlines()
    assert table[2] == "| 0 | 7.50 | 10.00 | 12.50 | 15.00 | 30 |" and table[3].startswith("| 1 | 22.50 |")
    assert table[4] == "| 2 seeds: at 10 m | 1 of 2 | 2 of 2 | 2 of 2 | 2 of 2 | |"
    assert table[5] == "| mean | 15.00 | 20.00 | 25.00 | 30.00 | |" and len(table) == 6
    assert tables.plain_rl_30_table(tmp_path / "none") == ""


def test_the_same_cpu_table_compares_on_shared_finished_seeds(tmp_path):
    """tables.plain_rl_same_cpu_table (issue #34, parts 5-6) on made-up runs: only seeds that both the
    variant and the baseline finished (15 iterations) count, and a clear gain reads "holds"."""
    def run(variant, seed, final, iters=15):
        rows = [{"iteration": i, "distance_m": final * i / iters} for i in range(iters + 1)]
        write_run(tmp_path / variant / f"hexapod-rl-seed{seed}", rows)
    for seed, final in enumerate((1.0, 2.0, 3.0)):
        run("base", seed, final)
    run("base", 3, 50.0, iters=10)                                   # unfinished: left out
    for seed, final in enumerate((11.0, 12.0, 13.0, 14.0)):         # seed 3 has no finished baseline
        run("up", seed, final)
    run("apart", 7, 9.0)                                             # no seed in common: no row
    for seed, final in enumerate((9.0, 12.0, 3.0)):                 # one of three at 10 m
        run("mixed", seed, final)
    assert tables.plain_rl_same_cpu_table(tmp_path, ("mixed",), "base").splitlines()[2].startswith(
        "| mixed | 3 (0-2) | 1 of 3, base 0 | 8.00 [")
    table = tables.plain_rl_same_cpu_table(tmp_path, ("up", "apart"), "base").splitlines()
    assert len(table) == 3 and table[2].startswith("| up | 3 (0-2) | 3 of 3, base 0 | 12.00 [")
    assert "| 2.00 [" in table[2] and "| +10.00 [" in table[2] and "| holds | 1.00 [1.00, 1.00] |" in table[2]
    assert tables.plain_rl_same_cpu_table(tmp_path, ("apart",), "base") == ""
    short = tables.plain_rl_same_cpu_table(tmp_path, ("up",), "base", seeds_needed=10).splitlines()[2]
    assert "| not decided (3 of 10 seeds) |" in short and "holds" not in short         # a rule over 10 seeds
    assert "| holds |" in tables.plain_rl_same_cpu_table(tmp_path, ("up",), "base", seeds_needed=3)


def test_the_il0_table_pairs_finished_seeds_and_leaves_out_another_line_1(tmp_path):
    """tables.il0_table (issue #34, part 27) on made-up runs: seed s of RL+IL walks to 20 + s m,
    lambda = 0 to 18 + s m; seed 2's lambda = 0 run starts elsewhere (another line 1): listed, left
    out of the means; an unfinished run has no row."""
    def run(folder, seed, start, final, iters=15):
        rows = [{"iteration": i, "distance_m": start + (final - start) * i / 15} for i in range(iters + 1)]
        write_run(tmp_path / folder / f"hexapod-hexapod-seed{seed}", rows)
    for seed in range(3):
        run("rlil", seed, 5.0, 20.0 + seed)
        run("il0", seed, 5.0 if seed < 2 else 6.0, 18.0 + seed)
    run("rlil", 3, 5.0, 30.0)
    run("il0", 3, 5.0, 30.0, iters=10)                                # unfinished: no row
    table = tables.il0_table(tmp_path / "il0", tmp_path / "rlil").splitlines()
    assert table[2] == "| 0 | 5.00 | 10.00 / 20.00 | 9.33 / 18.00 | -2.00 |"
    assert table[4] == "| 2 | differ: 5.00 / 6.00, left out | 10.67 / 22.00 | 10.67 / 20.00 | -2.00 |"
    assert table[5].startswith("| mean at 15, 2 seeds | | 20.50 [") and table[5].endswith("| -2.00 [-2.00, -2.00] |")
    assert len(table) == 6 and tables.il0_table(tmp_path / "none", tmp_path / "rlil") == ""


def test_the_takeoff_table_reads_each_seed_from_its_first_iteration_at_10_m(tmp_path):
    """tables.takeoff_aligned_table (issue #34, part 28) on made-up runs: seed 0 walks 0.5 m more per
    iteration (never 10 m: counted, not read), seed 1 2 m (10 m at iteration 5), seed 2 1 m (at 10);
    a later step past iteration 15 has fewer seeds; an unfinished run is left out."""
    def run(seed, per_iteration, iters=15):
        rows = [{"iteration": i, "distance_m": per_iteration * i} for i in range(iters + 1)]
        write_run(tmp_path / f"hexapod-rl-seed{seed}", rows)
    for seed, per_iteration in enumerate((0.5, 2.0, 1.0)):
        run(seed, per_iteration)
    run(3, 5.0, iters=10)                                                  # unfinished: left out
    table = tables.takeoff_aligned_table([("RL", tmp_path, "hexapod-rl"), ("none", tmp_path, "hexapod-hexapod")])
    assert table.splitlines()[2:] == ["| RL | 3 | 2 | 7.5 (5-10) | 17.50 | 10.00 (2) | 14.50 (2) | 22.00 (1) | 28.00 (1) |"]
    assert tables.takeoff_aligned_table([("none", tmp_path, "hexapod-hexapod")]) == ""


def test_the_early_takeoff_table_reads_part_31s_rule_over_four_seeds(tmp_path):
    """tables.early_takeoff_table (issue #34, part 31) on made-up 8-iteration runs: the baseline walks
    1 m per iteration (area 4.5 m, 10 m never by 8); a candidate 2 m (area 9, 10 m at iteration 5) on
    all four seeds passes, one that walks on two seeds only does not, and three finished seeds are
    not decided."""
    def run(folder, seed, per_iteration, iters=8):
        rows = [{"iteration": i, "distance_m": per_iteration * i, "kept_new": i % 2 == 0, "seconds": 60.0,
                 "model_progress_m": 1.5, "sim_progress_m": 0.5} for i in range(iters + 1)]
        write_run(tmp_path / folder / f"hexapod-rl-seed{seed}", rows)
    for seed in range(4):
        run("base", seed, 1.0, iters=15)
        run("fast", seed, 2.0)
        run("half", seed, 2.0 if seed < 2 else 1.0)
        if seed < 3:
            run("short", seed, 2.0)
    run("short", 3, 2.0, iters=5)                                          # unfinished: left out
    table = tables.early_takeoff_table(tmp_path / "fast", tmp_path / "base").splitlines()
    assert table[2] == "| 0 | 9.00, 4.50 | 5, - | 16.00, 8.00 | +1.00, +1.00 | 57%, 57% | 9, 9 |"
    assert table[6] == "| mean of 4 | 9.00, 4.50 (+4.50) | | 4 and 0 of 4 at 10 m | | | |"
    assert "**passes (" in table[-1]
    assert "**does not pass (" in tables.early_takeoff_table(tmp_path / "half", tmp_path / "base")
    assert "**not decided (3 of 4 seeds)**" in tables.early_takeoff_table(tmp_path / "short", tmp_path / "base")
    assert tables.early_takeoff_table(tmp_path / "none", tmp_path / "base") == ""


def test_the_plain_rl_targets_table_reads_flattery_kept_policies_and_falls(tmp_path):
    """tables.plain_rl_targets_table on made-up 15-iteration runs: seed 0 is flattered by 1 m at
    iteration 1 and 0.2 m after, keeps every second new policy and falls 4 m from iteration 14 to 15;
    seed 1 is flattered by 0.2 m throughout, keeps none and falls 3.5 m from iteration 0 to 1; an
    unfinished run is left out."""
    def run(seed, flattery, kept, fall_at=None, iters=15, start=0.0, where="v/hexapod-rl"):
        rows = [{"iteration": 0, "distance_m": start}]
        for i in range(1, iters + 1):
            d = i - (5.0 if fall_at is not None and i > fall_at else 0.0)
            rows.append({"iteration": i, "distance_m": d, "sim_progress_m": 0.5,
                         "model_progress_m": 0.5 + flattery(i), "kept_new": kept(i)})
        write_run(tmp_path / f"{where}-seed{seed}", rows)
    run(0, lambda i: 1.0 if i == 1 else 0.2, lambda i: i % 2 == 0, fall_at=14)
    run(1, lambda i: 0.2, lambda i: False, start=4.5)
    run(2, lambda i: 9.0, lambda i: True, iters=10)                     # unfinished: left out
    table = tables.plain_rl_targets_table(tmp_path, ("v", "none")).splitlines()
    assert len(table) == 3 and table[2] == "| v | 2 | +0.60 | +0.60 (1) | 25% | 4.00 | 0, 1 |"
    assert tables.plain_rl_targets_table(tmp_path, ("none",)) == ""
    run(0, lambda i: 0.1, lambda i: True, where="walk/hexapod-hexapod")  # `more`: runs of one name in a folder
    run(1, lambda i: 9.0, lambda i: True, where="walk/hexapod-rl")       # another run name: left out
    table = tables.plain_rl_targets_table(tmp_path, ("v",), more=[("walk RL+IL", tmp_path / "walk", "hexapod-hexapod")])
    assert table.splitlines()[3] == "| walk RL+IL | 1 | +0.10 | +0.10 (1) | 100% | 0.00 | none |"


def test_the_same_seed_area_table_pairs_seeds_and_skips_unfinished_runs(tmp_path):
    """tables.same_seed_area_table on made-up 5-iteration runs: the candidate walks 1 m more at
    every iteration on seeds 0 and 1; the baseline's seed 2 is unfinished and left out."""
    def run(folder, seed, shift, iters=5):
        rows = [{"iteration": i, "distance_m": i + shift, "seconds": 10.0} for i in range(iters + 1)]
        write_run(tmp_path / folder / f"x-seed{seed}", rows)
    for seed in (0, 1, 2):
        run("new", seed, seed + 1.0)
    run("old", 0, 0.0), run("old", 1, 1.0), run("old", 2, 2.0, iters=3)
    table = tables.same_seed_area_table(tmp_path / "new", tmp_path / "old").splitlines()
    assert table[2] == "| 0 | 4.00 | 3.00 | +1.00 | 3.00, 2.00 | 60, 60 |"
    assert table[3] == "| 1 | 5.00 | 4.00 | +1.00 | 4.00, 3.00 | 60, 60 |"
    assert table[4].startswith("| mean of 2 | 4.50 | 3.50 | +1.00 [") and table[4].endswith("| 3.00, 2.00 (lowest) | 60, 60 |")
    assert len(table) == 5 and tables.same_seed_area_table(tmp_path / "new", tmp_path / "none") == ""


def test_the_panel_c_budget_table_counts_convergence_on_the_committed_line(tmp_path):
    """tables.panel_c_budget_table on made-up 5-iteration runs: RL+IL's final mean is 20 m, so the
    line is 18 m; the defaults cross it at iteration 3 on seed 0 only, the walk at iteration 1 on
    both seeds and data16 never; data16's seed 1 is unfinished and left out of its row; a
    candidate (walk_wheel_splines) is compared with its ablation row (walk_amd), and the RL+IL
    runs in its folder are left out of its (plain RL) row."""
    def run(folder, name, seed, curve):
        rows = [{"iteration": i, "distance_m": d, "seconds": 10.0} for i, d in enumerate(curve)]
        write_run(tmp_path / "results" / folder / f"{name}-seed{seed}", rows)
    for seed in (0, 1):
        run("figure3_runs", "leg_leg_wheel-hexapod_car", seed, [5, 20, 20, 20, 20, 20])
        run("walk_panel_c_runs", "leg_leg_wheel-rl", seed, [0, 19, 19, 19, 19, 19])
    run("figure3_runs", "leg_leg_wheel-rl", 0, [0, 1, 2, 18, 18, 18])
    run("figure3_runs", "leg_leg_wheel-rl", 1, [0, 1, 2, 17.9, 17.9, 17.9])
    run("walk_ablation_runs/data16_c", "leg_leg_wheel-rl", 0, [0, 1, 1, 1, 1, 1])
    run("walk_ablation_runs/data16_c", "leg_leg_wheel-rl", 1, [0, 1, 1])
    for seed in (0, 1):
        run("panel_c_candidates/walk_amd", "leg_leg_wheel-rl", seed, [0, 1, 1, 1, 1, 17])
        run("panel_c_candidates/walk_wheel_splines", "leg_leg_wheel-rl", seed, [0, 1, 1, 1, 18, 18 + seed])
        run("panel_c_candidates/walk_wheel_splines", "leg_leg_wheel-hexapod_car", seed, [20] * 6)  # RL+IL: not a row
    table = tables.panel_c_budget_table(tmp_path).splitlines()
    assert table[0].startswith("Converged: the first iteration at 18.00 m")
    assert table[4].startswith("| defaults | none: Figure 3's committed runs | 2 | 3, never | 1 of 2 | 17.95 [")
    assert table[5].startswith("| data16 | ") and "| 1 | never | 0 of 1 | 1.00 [" in table[5]
    assert table[6].startswith("| walk | ") and "| 2 | 1, 1 | 2 of 2 | 19.00 [" in table[6]
    assert "| +1.05 [" in table[6] and "| +18.00 [" in table[6] and table[6].endswith("] |  | 60 |")
    assert table[7].startswith("| walk_amd | ") and "| 0 of 2 |" in table[7] and table[7].endswith("] |  | 60 |")
    assert table[8].startswith("| walk_wheel_splines | ") and "| 4, 4 | 2 of 2 | 18.50 [" in table[8]
    assert table[8].endswith("| +1.50 [1.00, 2.00] | 60 |")
    assert len(table) == 9
    shutil.rmtree(tmp_path / "results" / "figure3_runs")
    assert tables.panel_c_budget_table(tmp_path) == ""


def test_the_seed_rate_table_counts_converged_fallen_and_falling_seeds_with_their_chance(tmp_path):
    """tables.seed_rate_table on made-up 5-iteration runs: the line is 18 m (RL+IL's final 20 m); of
    the walk's three runs one converges; of the main command's, seed 1 is under 15 m at iteration 2
    and seed 0 only at iteration 1, which #33's rule does not count, while both fall by more than
    3 m (seed 0 from iteration 0 to 1, which #34's mark counts)."""
    def run(folder, name, seed, curve):
        rows = [{"iteration": i, "distance_m": d, "seconds": 10.0} for i, d in enumerate(curve)]
        write_run(tmp_path / folder / f"{name}-seed{seed}", rows)
    run("figure3_runs", "leg_leg_wheel-hexapod_car", 0, [5, 20, 20, 20, 20, 20])
    run("figure3_runs", "leg_leg_wheel-rl", 0, [0, 1, 1, 1, 1, 1])
    run("walk_panel_c_runs", "leg_leg_wheel-rl", 0, [0, 1, 1, 1, 1, 17.99])
    run("walk_panel_c_runs", "leg_leg_wheel-rl", 1, [0, 1, 1, 1, 18, 17])           # converged at 4, fell after
    run("seed_rate_runs/walk_panel_c", "leg_leg_wheel-rl", 10, [0, 1, 1, 1, 1, 1])
    run("figure3_runs", "leg_none_wheel-hexapod_car", 0, [18, 14, 20, 20, 20, 20])  # falls 4 m at iteration 1
    run("figure3_runs", "leg_none_wheel-hexapod_car", 1, [5, 20, 14.99, 20, 20, 20])
    run("seed_rate_runs/main_command", "leg_none_wheel-hexapod_car", 10, [5, 20, 20, 20])   # unfinished: left out
    table = tables.seed_rate_table(tmp_path).splitlines()
    assert table[0] == ("**the walk at K = 120, plain RL, leg_leg_wheel: a seed converges by iteration 5 (panel (c)'s line, "
                        "18.00 m)** (the mark: #34: 8 or more of 10)")
    assert table[4].endswith("(`results/walk_panel_c_runs`) | 0-1 | 1 | 1 of 2: 0.50 [0.09, 0.91] | 0.05 |")
    assert table[5].endswith("(`results/seed_rate_runs/walk_panel_c`) | 10 | none | 0 of 1: 0.00 [0.00, 0.79] | 0.00 |")
    assert table[6] == "| all | 3 runs | 1 | 1 of 3: 0.33 [0.06, 0.79] | 0.00 |"
    assert table[8].startswith("**the main command") and "#33's rule: none of 10" in table[8]
    assert table[12].endswith("(`results/figure3_runs`) | 0-1 | 1 | 1 of 2: 0.50 [0.09, 0.91] | 0.00 |")
    assert table[13] == "| all | 2 runs | 1 | 1 of 2: 0.50 [0.09, 0.91] | 0.00 |"
    assert "falls by more than 3 m" in table[15] and table[20] == "| all | 2 runs | 2 | 2 of 2: 1.00 [0.34, 1.00] | 0.00 |"
    assert len(table) == 21 and tables.seed_rate_table(tmp_path / "nothing") == ""
    run("seed_rate_runs/walk_panel_a", "hexapod-rl", 10, [0] * 15 + [10.0])     # panel (a): 10 m at 15
    run("seed_rate_runs/walk_panel_a", "hexapod-rl", 11, [0] * 9 + [12] + [9.99] * 6)   # not at 15
    run("seed_rate_runs/walk_panel_a", "hexapod-rl", 12, [0] * 15)                 # unfinished: left out
    table = tables.seed_rate_table(tmp_path).splitlines()
    assert table[22] == ("**the walk at K = 120, plain RL, hexapod: a seed is at 10 m or more at iteration 15 (panel (a))** "
                         "(the mark: #34: 7 or more of 10)")
    assert table[26].endswith("(`results/seed_rate_runs/walk_panel_a`) | 10-11 | 10 | 1 of 2: 0.50 [0.09, 0.91] | 0.17 |")
    assert len(table) == 28


def test_the_walk_rlil_ablation_pairs_each_seed_with_its_own_cpus_walk_run(tmp_path):
    """tables.walk_rlil_ablation_table on made-up 15-iteration runs: seed 0's walk run comes from
    Figure 3's walk runs, seed 1's from walk_rlil_avx512, which replaces Figure 3's where both exist;
    seed 2 has no data16 run and is left out."""
    def run(folder, seed, final, cpu="AVX2"):
        (tmp_path / folder / f"hexapod-hexapod-seed{seed}").mkdir(parents=True)
        rows = [{"iteration": i, "distance_m": final if i == 15 else 1.0} for i in range(16)]
        (tmp_path / folder / f"hexapod-hexapod-seed{seed}" / "metrics.json").write_text(
            json.dumps({"iterations": rows, "config": {"versions": {"cpu_capability": cpu}}}))
    for seed, final in ((0, 20.0), (1, 99.0), (2, 21.0)):
        run("figure3_walk_runs", seed, final)
    run("walk_ablation_runs/walk_rlil_avx512", 1, 18.0, "AVX512")
    run("walk_ablation_runs/data16_rlil", 0, 19.0)
    run("walk_ablation_runs/data16_rlil", 1, 19.0, "AVX512")
    table = tables.walk_rlil_ablation_table(tmp_path).splitlines()
    assert table[2:4] == ["| 0 | AVX2 | 20.00 | 19.00 | +1.00 |", "| 1 | AVX512 | 18.00 | 19.00 | -1.00 |"]
    assert table[4].startswith("| mean of 2 | | 19.00 [") and "| +0.00 [" in table[4] and len(table) == 5
    assert tables.walk_rlil_ablation_table(tmp_path / "nothing") == ""


def test_the_walk_preset_is_the_config_of_the_committed_walking_runs():
    """`--preset walk` (README: the budget of Figure 3's panel (a)) must be the config every committed
    run of that budget records, with the flags its folder names, so that the docs' commands
    reproduce them; fails when the preset and the runs part (a changed field, a switch left out)."""
    root = sweeps.ROOT / "results"
    k120 = {"policy_steps": 120, "batch": 64}       # the walk before part 21 of the diagnosis
    folders = {"plain_rl_budget_runs/data16_waves_stdmin10": k120, "figure3_walk_runs": k120,
               "walk_panel_c_runs": {**k120, "iters": 5}, "panel_a_candidates/walk_avx512": k120,
               "panel_a_candidates/walk_amd": k120, "panel_c_candidates/walk_amd": {**k120, "iters": 5},
               "seed_rate_runs/walk_panel_c": {**k120, "iters": 5},
               "panel_a_candidates/walk_k480b16": {}, "panel_c_candidates/walk_k480b16": {"iters": 5},
               "figure3_walk_k480b16_runs": {}, "panel_a_candidates/walk_t40": {"horizon": 40}}
    for folder, flags in folders.items():
        paths = sorted(root.glob(f"{folder}/*-seed*/metrics.json"))
        assert len(paths) >= (10 if folder in ("figure3_walk_runs", "walk_panel_c_runs", "panel_a_candidates/walk_k480b16",
                                               "panel_c_candidates/walk_k480b16") else 0), folder
        for path in paths:
            saved, why = sweeps.read_metrics(path.parent)
            assert why is None, f"{path}: {why}"
            cfg = saved["cfg"]
            assert cfg == rlil.preset("walk", train=cfg.train, demos=cfg.demos, seed=cfg.seed, threads=1, **flags), path


def test_the_committed_main_command_runs_are_the_defaults():
    """The runs that seed_rate_table adds to the main command at the defaults (#33's rule) must
    record the defaults' config: fails when one ran with another setting.  (The budget screen's
    earlier defaults record a scratch setting at its off value; see its report.)"""
    root = sweeps.ROOT / "results"
    for folder in ("seed_rate_runs/main_command",):
        for path in sorted(root.glob(f"{folder}/*-seed*/metrics.json")):
            saved, why = sweeps.read_metrics(path.parent)
            assert why is None, f"{path}: {why}"
            cfg = saved["cfg"]
            assert cfg == rlil.preset("default", train=("lnwwnl",), demos=("llllll", "wnwwnw"), seed=cfg.seed,
                                      threads=1), path


def test_the_flattery_curve_table_reads_each_variants_seed_csvs(tmp_path):
    """tables.flattery_curve_table (issue #34, part 12) on made-up CSVs: two seeds of one variant
    averaged per policy step; a variant without CSVs left out; no CSV at all gives ""."""
    from experiments import flattery_curve, sweeps as sw
    for seed, flat in ((0, 1.0), (1, 2.0)):
        rows = [{"design": "hexapod", "seed": seed, "after": 0, "step": k, "model_progress_m": flat * k / 20,
                 "sim_progress_m": 0.0, "flattery_m": flat * k / 20, "validation_reward": 0.0, "lr": ""}
                for k in (0, 20)]
        sw.write_rows_csv(tmp_path / f"walk_hexapod_seed{seed}.csv", flattery_curve.COLUMNS, rows)
    table = tables.flattery_curve_table(tmp_path)
    assert table.startswith("**walk_hexapod**") and "offset10" not in table
    assert "| hexapod | 0 | 20 | 2 | +1.50 | +0.00 | +1.50, +1.00 - +2.00 |" in table
    assert tables.flattery_curve_table(tmp_path / "none") == ""


def test_panel_a_pairing_table_reads_how_much_the_seeds_pair(tmp_path):
    """tables.panel_a_pairing_table: a candidate that moves every seed of the baseline by the same
    metres pairs perfectly (correlation +1, no spread of the differences, no seeds needed beyond
    what any screen has); one that reverses the seeds' order pairs against them, and the seeds a
    screen needs follow from the differences' spread: (1.96 x 10 m / 2 m)^2, rounded up = 97."""
    def write(variant, finals):
        for seed, final in enumerate(finals):
            path = tmp_path / variant / f"hexapod-rl-seed{seed}" / "metrics.json"
            path.parent.mkdir(parents=True)
            path.write_text(json.dumps({"iterations": [{"iteration": i, "distance_m": final * i / 15} for i in range(16)]}))
    write("walk_amd", [5.0, 10.0, 15.0])
    write("walk_noise06", [6.0, 11.0, 16.0])
    write("walk_critic", [15.0, 10.0, 5.0])
    rows = {line.split(" | ")[0].strip("| "): line.split(" | ") for line in tables.panel_a_pairing_table(tmp_path).splitlines()[2:]}
    assert set(rows) == {"walk_noise06", "walk_critic"}
    assert rows["walk_noise06"][2:] == ["+1.00", "5.00", "5.00", "0.00", "0 |"]
    assert rows["walk_critic"][2:] == ["-1.00", "5.00", "5.00", "10.00", "97 |"]
