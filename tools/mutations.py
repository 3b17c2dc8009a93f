"""Break one line at a time and watch the test meant to catch it go red.

Each entry below is a deliberate bug: a line of a stage file replaced by a
broken one (a step skipped, a sign flipped, a term dropped) and the test that
must fail because of it.  For each, the repository is copied to a scratch
directory, the one line is changed there (never here), and only that test is
run.  The table it prints (and writes to results/mutations.md, which
docs/cli.md shows) says whether every test went red.

    python tools/mutations.py            # every entry, one pytest run each
    python tools/mutations.py --only 3   # one entry, by number
"""
from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

# (what breaks, file, the line as it is, the broken line, the test that must go red)
MUTATIONS = [
    ("Algorithm 1 line 1 skipped (no behavioural cloning)", "modular_rlil_minimal.py",
     "if demo_data and cfg.bc_steps:", "if False:",
     "tests/test_rlil.py::test_algorithm1_starts_from_behavioural_cloning_when_demos_are_given"),
    ("BC takes no step", "modular_rlil_minimal.py",
     "        loss, _ = il_loss(policy, demo_data, cfg, rng)\n        opt.zero_grad()\n        loss.backward()\n"
     "        opt.step()",
     "        loss, _ = il_loss(policy, demo_data, cfg, rng)\n        opt.zero_grad()\n        loss.backward()\n",
     "tests/test_rlil.py::test_behavioural_cloning_lowers_the_il_loss"),
    ("line 5: the model takes no step", "modular_rlil_minimal.py",
     "model_loss(model, design, flat[design], cfg.model_batch, rng)\n        opt.zero_grad()\n        loss.backward()\n"
     "        opt.step()",
     "model_loss(model, design, flat[design], cfg.model_batch, rng)\n        opt.zero_grad()\n        loss.backward()\n",
     "tests/test_rlil.py::test_model_fit_beats_predicting_no_change"),
    ("line 16: the RL loss's sign flipped", "modular_rlil_minimal.py",
     "loss = loss - R.mean()", "loss = loss + R.mean()",
     "tests/test_rlil.py::test_rl_phase_teaches_the_car_to_drive"),
    ("eqn. (IL_loss): the log-likelihood's sign flipped", "modular_rlil_minimal.py",
     "loss = loss - log_prob.mean()", "loss = loss + log_prob.mean()",
     "tests/test_rlil.py::test_il_loss_equals_hand_computation"),
    ("Sec. III-J: the entropy penalty dropped", "modular_rlil_minimal.py",
     "loss_il + cfg.entropy_weight * entropy, il_weight)", "loss_il, il_weight)",
     "tests/test_rlil.py::test_entropy_penalty_makes_the_policy_more_certain_on_demo_observations"),
    ("lines 22-24: the buffer never refreshed", "modular_rlil_minimal.py",
     "refresh_buffer(buffer, policy, model, data[design], cfg, rng)", "pass",
     "tests/test_rlil.py::test_policy_phase_refreshes_the_buffer_every_update_rate_steps"),
    ("Sec. III-J: the validation revert never fires", "modular_rlil_minimal.py",
     "if value < self.start or not math.isfinite(value):", "if False:",
     "tests/test_rlil.py::test_validation_revert_goes_back_to_the_last_passed_check"),
    ("line 28: the noisy roll-outs without noise", "modular_rlil_minimal.py",
     "PolicyActor(policy, design, n, noise)", "PolicyActor(policy, design, n)",
     "tests/test_rlil.py::test_noisy_policy_rollouts_add_correlated_noise_to_the_clean_policy"),
    ("line 29 a no-op: policy data collected, not added to T_train", "modular_rlil_minimal.py",
     "data[design] = data[design] + traj                                         # line 29", "pass",
     "tests/test_rlil.py::test_algorithm1_adds_the_policy_data_to_T_train_and_refits_the_model_on_it"),
    ("not in the paper: the clone's roll-outs never added (--clone-data)", "modular_rlil_minimal.py",
     "run.kept_return = add_clone_rollouts(policy, data, cfg, rng)", "run.kept_return = 0.0",
     "tests/test_rlil.py::test_clone_data_adds_the_clones_rollouts_before_the_first_model_fit"),
    ("not in the paper: the improvement check keeps every policy (--keep-better)", "modular_rlil_minimal.py",
     "keep = run.kept_return is None or value >= run.kept_return - cfg.improvement_margin", "keep = True",
     "tests/test_rlil.py::test_improvement_check_keeps_the_previous_policy_when_the_new_one_returns_less"),
    ("line 30: lambda never decays", "modular_rlil_minimal.py",
     "return il_weight * cfg.il_decay", "return il_weight",
     "tests/test_rlil.py::test_tiny_run_writes_every_output_and_decays_lambda"),
    ("GNN: the body sums limb messages as a mean", "gnn.py",
     "inbox = torch.bmm(limbs, w.up).sum(0, keepdim=True)", "inbox = torch.bmm(limbs, w.up).mean(0, keepdim=True)",
     "tests/test_gnn.py::test_batched_path_equals_the_node_by_node_computation"),
    ("PPO: the clipping of eqn. 7 disabled", "ppo_minimal.py",
     "ratio.clamp(1 - cfg.clip_coef, 1 + cfg.clip_coef) * adv", "ratio * adv",
     "tests/test_ppo.py::test_ppo_loss_is_eqn_9_with_the_clipped_surrogate_of_eqn_7"),
    ("PPO: trains on the steps after a flip", "ppo_minimal.py",
     "keep = batch.valid.flatten()", "keep = torch.ones_like(batch.valid.flatten())",
     "tests/test_ppo.py::test_steps_after_a_flip_are_simulated_but_not_trained_on"),
    ("PPO: the update takes no step", "ppo_minimal.py",
     "            torch.nn.utils.clip_grad_norm_(params, cfg.max_grad_norm)\n            opt.step()",
     "            torch.nn.utils.clip_grad_norm_(params, cfg.max_grad_norm)",
     "tests/test_ppo.py::test_ppo_teaches_the_car_to_drive"),
    ("check_physics: one figure printed under another's key", "tools/check_physics.py",
     "max_penetration_cm={result['max_penetration_cm']:.2f}", "max_penetration_cm={result['max_joint_gap_cm']:.2f}",
     "tests/test_sim2d.py::test_check_physics_command_line_ends_with_one_summary_line"),
    ("statistics: an 80 % interval instead of 95 %", "experiments/stats.py",
     "\nLEVEL = 0.95", "\nLEVEL = 0.80",
     "tests/test_sweeps.py::test_bootstrap_intervals_of_hand_computed_cases"),
    ("statistics: ties count as wins in P(X > Y)", "experiments/stats.py",
     "p = ((x > y) + 0.5 * (x == y))", "p = ((x >= y) + 0.0 * (x == y))",
     "tests/test_sweeps.py::test_probability_of_improvement_is_the_pair_count_and_mann_whitney_u"),
    ("sweeps: parallel runs keep several threads", "experiments/sweeps.py",
     "threads=1 if jobs > 1 else base.threads)", "threads=base.threads)",
     "tests/test_rlil.py::test_figure3_reuses_finished_runs_and_writes_plot_and_csv"),
    ("PPO+IL: the imitation term dropped", "ppo_minimal.py",
     "loss = rlil_loss(loss, loss_il + cfg.entropy_weight * entropy, il_weight)", "loss = loss",
     "tests/test_ppo.py::test_ppo_il_term_lowers_the_il_loss_and_lambda_decays_per_iteration"),
    ("PPO+IL: no BC pre-training", "ppo_minimal.py",
     "if demo_data and cfg.bc_steps:", "if False:",
     "tests/test_ppo.py::test_ppo_il_starts_from_behavioural_cloning"),
    ("sweeps, local launcher: every run started with seed 1", "experiments/sweeps.py",
     'futures = {pool.submit(run_one, run_command(r), str(r["dir"])): r for r in todo}',
     'futures = {pool.submit(run_one, run_command(r) + ["--seed", "1"], str(r["dir"])): r for r in todo}',
     "tests/test_sweeps.py::test_plan_commands_run_anywhere_and_collect_into_the_local_csv"),
    ("sweeps, Ray launcher: every task started with seed 1", "experiments/sweeps.py",
     'pending = {remote.remote(run_command(r), str(r["dir"])): r for r in todo}',
     'pending = {remote.remote(run_command(r) + ["--seed", "1"], str(r["dir"])): r for r in todo}',
     "tests/test_sweeps.py::test_ray_launcher_gives_the_local_launchers_metrics"),
    ("sweeps, plan: an interrupted run's line without --resume", "experiments/sweeps.py",
     "['python', *run_command(r)[1:]]", "['python', *[a for a in run_command(r)[1:] if a != '--resume']]",
     "tests/test_sweep_faults.py::test_plan_resumes_an_interrupted_run_with_its_own_seed_and_config"),
    ("sweeps, plan: every run's line with seed 0", "experiments/sweeps.py",
     "['python', *run_command(r)[1:]]", "['python', *run_command(r)[1:], '--seed', '0']",
     "tests/test_sweep_faults.py::test_plan_resumes_an_interrupted_run_with_its_own_seed_and_config"),
    ("sweeps, --collect: a run of another config taken as it is", "experiments/sweeps.py",
     "    if other and not accept:\n", "    if False:\n",
     "tests/test_sweep_faults.py::test_collect_refuses_a_run_of_another_design_seed_or_budget_copied_in"),
    ("sweeps, --collect: a null distance taken as a figure", "experiments/sweeps.py",
     "        if saved is None or null_figure(saved):\n            continue\n        cpu",
     "        if saved is None:\n            continue\n        cpu",
     "tests/test_sweep_faults.py::test_collect_names_unreadable_metrics_and_nulls_as_failed_runs"),
    ("keep_metrics: a DEST run of another config or more iterations replaced", "experiments/sweeps.py",
     "        why = None if force or not target.exists() else replacing(target, saved)\n", "        why = None\n",
     "tests/test_sweep_faults.py::test_keep_metrics_never_replaces_a_run_of_another_config_or_more_iterations"),
    ("sweeps: SIGTERM not passed on to the runs", "experiments/sweeps.py",
     "        stop_processes(procs, signum, grace, hurry)\n", "        pass\n",
     "tests/test_sweep_faults.py::test_sigterm_stops_the_sweeps_runs_and_says_how_to_continue"),
    ("sweeps: --ray-address not tried before ray.init", "experiments/sweeps.py",
     "        check_ray(ray_address)\n    made = not out.exists()\n", "        pass\n    made = not out.exists()\n",
     "tests/test_sweep_faults.py::test_an_unreachable_ray_address_fails_in_one_line_within_15_s"),
    ("sweeps: --out not checked before the sweep", "experiments/sweeps.py",
     "    check_writable(out)\n    if collect is None and launcher == \"ray\":\n        check_ray(ray_address)\n"
     "    made = not out.exists()\n    out.mkdir(parents=True, exist_ok=True)\n    if collect is None:\n"
     "        try:\n            launch_runs(runs, last",
     "    if collect is None and launcher == \"ray\":\n        check_ray(ray_address)\n"
     "    made = not out.exists()\n    out.mkdir(parents=True, exist_ok=True)\n    if collect is None:\n"
     "        try:\n            launch_runs(runs, last",
     "tests/test_sweep_faults.py::test_an_output_folder_that_cannot_be_written_is_refused_before_any_work"),
    ("tables: a CSV row of too few cells read as it is", "experiments/tables.py",
     "            if None in row or None in row.values():\n", "            if False:\n",
     "tests/test_sweep_faults.py::test_tables_check_names_a_csv_cut_mid_row_in_one_line"),
    ("tables: the generalist's single-design runs of different lengths not named", "experiments/tables.py",
     "    if len(single[short]) != len(single[0]):\n", "    if False:\n",
     "tests/test_sweep_faults.py::test_tables_check_names_a_bad_run_metrics_json_in_one_line"),
    ("line 2: the spline knots drawn with std 1 whatever --random-action-std", "sim2d.py",
     "values = rng.normal(0.0, std, (n, knots, action_dim))", "values = rng.normal(0.0, 1.0, (n, knots, action_dim))",
     "tests/test_sim2d.py::test_spline_actions_pass_through_their_knots_drawn_with_the_given_std"),
    ("evaluation: other starts at every iteration", "modular_rlil_minimal.py",
     "results = {d: evaluate_policy(policy, d, cfg, eval_seed(cfg)) for d in designs}",
     "results = {d: evaluate_policy(policy, d, cfg, eval_seed(cfg) + i) for d in designs}",
     "tests/test_rlil.py::test_every_iteration_is_evaluated_from_the_same_starts_and_seeds_differ"),
    ("statistics: converged at 80 % of the best final mean, not 90 %", "experiments/sweeps.py",
     "0.9 * max(finals) if finals", "0.8 * max(finals) if finals",
     "tests/test_sweeps.py::test_the_convergence_rule_and_the_area_under_the_curve_on_made_up_curves"),
    ("claims: Sec. V's 'same distance' judged as 'RL+IL ahead' (its margin dropped)", "experiments/tables.py",
     "| {verdict(same, SAME_DISTANCE_M)} |", "| {verdict(same)} |",
     "tests/test_sweeps.py::test_verdicts_and_the_claims_table_of_a_made_up_sweep"),
    ("transfer table: a held-out design at exactly 0.6 of its demonstrator not counted", "experiments/transfer.py",
     "(per_run >= GOOD_RATIO).mean()", "(per_run > GOOD_RATIO).mean()",
     "tests/test_transfer.py::test_group_table_averages_seeds_marks_seen_and_uses_only_held_out_designs"),
    ("run folder: no lock, a second writer is let in", "experiments/run_folders.py",
     "        fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)\n    except OSError:\n        lock.seek(0)\n",
     "        pass\n    except OSError:\n        lock.seek(0)\n",
     "tests/test_faults.py::test_a_held_folder_refuses_a_second_writer_in_one_line"),
    ("SIGTERM kills a run without a word", "train.py",
     "        signal.signal(signal.SIGTERM, on_signal)", "        pass",
     "tests/test_faults.py::test_sigterm_before_the_first_checkpoint_leaves_no_folder"),
    ("a signal inside an import is raised there, where it can be lost", "train.py",
     "    if swallowed_there(frame):", "    if frame is not None and \"pymunk\" in frame.f_code.co_filename:",
     "tests/test_faults.py::test_a_signal_inside_an_import_arrives_after_it"),
    ("a failed write is a traceback, not the resume line", "experiments/run_folders.py",
     "    except (OSError, RuntimeError) as e:\n        reason", "    except ZeroDivisionError as e:\n        reason",
     "tests/test_faults.py::test_a_full_disk_keeps_the_last_checkpoint_and_says_how_to_resume"),
    ("Gymnasium env: a flip never terminates the episode", "interfaces/gymnasium_env.py",
     "float(reward[0]), bool(terminated[0]),", "float(reward[0]), False,",
     "tests/test_interfaces.py::test_a_flip_terminates_exactly_where_the_world_says_so"),
    ("statistics: the bootstrap resamples all runs but the last", "experiments/stats.py",
     "x[rng.integers(len(x), size=(resamples, len(x)))]", "x[rng.integers(len(x) - 1, size=(resamples, len(x)))]",
     "tests/test_interfaces.py::test_our_bootstrap_ci_and_probability_of_improvement_match_rliable"),
    ("lesson grader: any answer of the right shape passes", "lesson/grade.py",
     "return a.shape == b.shape and bool(torch.allclose(a, b, rtol=tol, atol=tol, equal_nan=True))",
     "return a.shape == b.shape",
     "tests/test_lesson.py::test_a_typical_mistake_fails_with_a_message_that_names_it"),
    ("sample efficiency: the SB3 PPO runs' CSVs not collected", "experiments/sweeps.py",
     'rows = sample_efficiency_rows(runs) + sb3_rows((collect or out) / "sb3_ppo_runs")',
     "rows = sample_efficiency_rows(runs)",
     "tests/test_ppo.py::test_sample_efficiency_runs_every_method_and_writes_plot_csv_and_summary"),
    ("line 2 ignores --random-waves (splines always)", "modular_rlil_minimal.py",
     "if cfg.random_waves:", "if False:",
     "tests/test_rlil.py::test_line2_draws_waves_with_random_waves_on_and_the_papers_splines_off"),
    ("an output file: no lock, a second process writes it too", "experiments/run_folders.py",
     "        fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)\n    except OSError:\n        lock.seek(0)\n",
     "        pass\n    except OSError:\n        lock.seek(0)\n",
     "tests/test_faults.py::test_an_output_file_is_claimed_by_one_process_until_it_ends"),
]


def copy_repo(dest: Path) -> None:
    """The working tree's Python files, tools, experiments, interfaces, lesson, tests, results and docs
    (no runs, caches or .git)."""
    for item in ROOT.iterdir():
        if item.suffix == ".py" or item.name in ("tools", "experiments", "interfaces", "lesson", "tests", "results", "docs",
                                                   "README.md"):
            (shutil.copytree if item.is_dir() else shutil.copy)(item, dest / item.name)


def run_one(what: str, file: str, old: str, new: str, test: str) -> dict:
    with tempfile.TemporaryDirectory(prefix="mutation-") as tmp:
        tmp = Path(tmp)
        copy_repo(tmp)
        text = (tmp / file).read_text()
        if text.count(old) != 1:
            return {"what": what, "test": test, "result": f"NOT APPLIED: the line occurs {text.count(old)} times"}
        (tmp / file).write_text(text.replace(old, new))
        t0 = time.perf_counter()
        done = subprocess.run([sys.executable, "-m", "pytest", "-q", "-x", "-p", "no:cacheprovider", test],
                              cwd=tmp, capture_output=True, text=True)
        seconds = time.perf_counter() - t0
    if done.returncode == 1:
        result = "red"
    elif done.returncode == 0:
        result = "STILL GREEN"
    else:
        result = f"ERROR (pytest exit {done.returncode}): {done.stdout.strip().splitlines()[-1:]}"
    return {"what": what, "test": test, "result": result, "seconds": seconds}


def table(rows: list[dict]) -> str:
    lines = ["| # | break this | file | this test goes red | result |", "|---|---|---|---|---|"]
    for i, (row, m) in enumerate(zip(rows, MUTATIONS), 1):
        file, test = m[1], row["test"].split("::")
        lines.append(f"| {i} | {row['what']} | `{file}` | `{test[0].split('/')[-1]}::{test[1]}` | {row['result']} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--only", type=int, nargs="+", help="entries to run, by number (default all)")
    args = parser.parse_args(argv)
    picked = args.only or range(1, len(MUTATIONS) + 1)
    if any(not 1 <= i <= len(MUTATIONS) for i in picked):
        parser.exit(2, f"tools/mutations.py: error: --only takes numbers 1-{len(MUTATIONS)}\n")
    rows = []
    for i in picked:
        row = run_one(*MUTATIONS[i - 1])
        print(f"{i:2d}. {row['result']:12s} {row.get('seconds', 0):5.1f} s  {row['what']}  ->  {row['test']}",
              flush=True)
        rows.append(row)
    if not args.only:
        (ROOT / "results" / "mutations.md").write_text(table(rows))
        print(f"wrote {ROOT / 'results' / 'mutations.md'}")
    return 0 if all(r["result"] == "red" for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
