"""Break one line at a time and watch the test meant to catch it go red.

Each entry below is a deliberate bug: a line of a stage file replaced by a
broken one (a step skipped, a sign flipped, a term dropped) and the test that
must fail because of it.  For each, the repository is copied to a scratch
directory, the one line is changed there (never here), and only that test is
run.  The table it prints (and writes to results/mutations.md, which
docs/cli.md shows) says whether every test went red.

    python tools/mutations.py            # all of them, about 5 minutes on 2 cores
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
     "LEVEL = 0.95", "LEVEL = 0.80",
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
]


def copy_repo(dest: Path) -> None:
    """The working tree's Python files, tools, experiments, tests, results and docs (no runs, caches or .git)."""
    for item in ROOT.iterdir():
        if item.suffix == ".py" or item.name in ("tools", "experiments", "tests", "results", "docs", "README.md"):
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
