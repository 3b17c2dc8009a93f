"""Tests of the lesson (lesson/, docs/lesson.md): the grader and the notebook script.

For every exercise the grader must pass the project's own function, fail the
shipped stub as "not written yet", pass a student's answer written from scratch
(the stub with its YOUR CODE HERE parts filled in), and fail the typical wrong
answers, each a one-line change of that answer, with the message that names the
mistake.  The answers are files in a pytest tmp_path, graded with --file.  The
lesson script runs end to end at the tiny budget as a subprocess.
"""
import subprocess
import sys
from pathlib import Path

import pytest

from lesson import grade

ROOT = Path(__file__).resolve().parent.parent
STUB = 'raise NotImplementedError("YOUR CODE HERE")'

# What a student writes in place of each stub's `raise NotImplementedError("YOUR CODE HERE")`, in order.
ANSWERS = {
    "ex1": ["""progress = s_next[..., 0] - s[..., 0]
    pitch = sim2d.W_PITCH * s_next[..., 2] ** 2
    effort = sim2d.W_EFFORT * (a ** 2).mean(-1)
    r = progress - pitch - effort
    if graph.n_legs:
        legs = sim2d.split_state(s_next, graph)["leg"]
        hip, knee = legs[..., 0] - sim2d.HIP_NOMINAL, legs[..., 1] - sim2d.KNEE_NOMINAL
        r = r - sim2d.W_POSE * (hip ** 2 + knee ** 2).mean(-1) / 2
    return r"""],
    "ex2": ["""kinds = [kind for kind, _ in graph.nodes]
    z = []
    for (kind, port), xi in zip(graph.nodes, x):
        p = nets.body.ports.weight[port] if port is not None else 0.0
        z.append(torch.tanh(nets[kind].encode(xi) + p))
    for _ in range(rounds):
        inbox = 0.0
        for kind, zi in zip(kinds[1:], z[1:]):
            inbox = inbox + nets[kind].up(zi)
        body = z[0] + torch.tanh(nets.body.own(z[0]) + inbox)
        z = [body] + [zi + torch.tanh(nets[kind].own(zi) + nets[kind].down(body)) for kind, zi in zip(kinds[1:], z[1:])]
    if h is not None:
        h = [nets[kind].gru(zi, hi) for kind, zi, hi in zip(kinds, z, h)]
        z = h
    return [nets[kind].head(zi) if "head" in nets[kind] else None for kind, zi in zip(kinds, z)], h"""],
    "ex3": ["""pi, f = policy.on_design(graph), model.on_design(graph)
    s, h, R = s0, h0, 0.0
    for t in range(horizon):
        noise = None if deterministic else sim2d.obs_noise_like(s, graph)
        a, h = pi.act(sim2d.observe(s, graph, noise), h, deterministic=deterministic)
        s_next = f(s, a)
        R = R + sim2d.reward(s, a, s_next, graph)
        s = s_next
    return -R.mean(), s, h"""],
    "ex4": ["""log_prob, ent = policy.sequence_log_prob(obs, actions, graph)
        loss = loss - log_prob.mean()
        entropy = entropy + ent.mean()""",
            "return loss_rl + il_weight * (loss_il + entropy_weight * entropy)"],
    "ex5": ["""self.policy.load_state_dict(self.saved[0])
        self.opt.load_state_dict(self.saved[1])
        self.lr *= self.lr_drop
        for group in self.opt.param_groups:
            group["lr"] = self.lr
        self.reverts += 1""",
            """import math
        if value < self.start or not math.isfinite(value):
            self.revert()
        else:
            self.last = value
            self.snapshot()"""],
    "ex6": ["""def auc(rows):
        d = [row["distance_m"] for row in rows if row["iteration"] >= 1]
        return sum(d) / len(d)
    return auc(read_iterations(rlil_run)) - auc(read_iterations(rl_run))"""],
}

# (exercise, a line of the answer, the wrong line, what the grader must say)
MISTAKES = [
    ("ex1", "    return r", "    return -r", "sign"),
    ("ex1", "progress = s_next[..., 0] - s[..., 0]", "progress = s[..., 0] - s_next[..., 0]",
     "progress has the wrong sign"),
    ("ex1", "r = r - sim2d.W_POSE", "r = r - 0 * sim2d.W_POSE", "missing the pose penalty"),
    ("ex1", "(a ** 2).mean(-1)", "(a ** 2).sum(-1)", "sums a^2"),
    ("ex1", "s_next[..., 2] ** 2", "s[..., 2] ** 2", "pitch penalty uses s"),
    ("ex1", "(a ** 2)", "(a.clip(-1, 1) ** 2)", "sees clipped actions"),
    ("ex1", "if graph.n_legs:", "if True:", "NaN on a design without legs"),
    ("ex1", "(a ** 2).mean(-1)", "sim2d.torch.mean(a ** 2, -1)", "not on numpy arrays"),
    ("ex2", "for _ in range(rounds):", "for _ in range(rounds + 1):", "off by one round"),
    ("ex2", "nets.body.own(z[0]) + inbox)", "nets.body.own(z[0]) + inbox / len(z[1:]))", "averages"),
    ("ex2", "nets[kind].down(body))", "nets[kind].down(z[0]))", "before this round's update"),
    ("ex2", "nets[kind].encode(xi) + p)", "nets[kind].encode(xi))", "port vectors"),
    ("ex2", "        z = h\n", "", "read out from z"),
    ("ex2", "gru(zi, hi)", "gru(hi, zi)", "swapped"),
    ("ex3", "return -R.mean(), s, h", "return R.mean(), s, h", "sign"),
    ("ex3", "range(horizon)", "range(horizon - 1)", "off by one step"),
    ("ex3", "range(horizon)", "range(horizon + 1)", "off by one step"),
    ("ex3", "s, h, R = s0, h0, 0.0", "s, h, R = s0, torch.zeros_like(h0), 0.0", "zero hidden states"),
    ("ex3", "noise = None if deterministic else sim2d.obs_noise_like(s, graph)", "noise = None",
     "without observation noise"),
    ("ex3", "return -R.mean(), s, h", "return -R.sum(), s, h", "sums over the batch"),
    ("ex3", "return -R.mean(), s, h", "return -R, s, h", "shape (5,)"),
    ("ex3", "s_next = f(s, a)", "s_next = f(s, a.detach())", "detached"),
    ("ex3", "return -R.mean(), s, h", "return -R.mean().item(), s, h", "no gradient"),
    ("ex4", "loss = loss - log_prob.mean()", "loss = loss + log_prob.mean()", "sign"),
    ("ex4", "loss = loss - log_prob.mean()", "loss = loss - log_prob.sum()", "sums over the pairs"),
    ("ex4", "loss = loss - log_prob.mean()", "loss = -log_prob.mean()", "last design only"),
    ("ex4", "(loss_il + entropy_weight * entropy)", "loss_il", "missing entropy penalty"),
    ("ex4", "(loss_il + entropy_weight * entropy)", "(loss_il - entropy_weight * entropy)", "rewarded, not penalised"),
    ("ex4", "il_weight * (loss_il + entropy_weight * entropy)", "il_weight * loss_il + entropy_weight * entropy",
     "outside lambda"),
    ("ex5", "value < self.start", "value < self.last", "below the last check (1.5) but not below"),
    ("ex5", " or not math.isfinite(value)", "", "NaN"),
    ("ex5", "            self.snapshot()", "            pass", "phase's start, not to the last passed check"),
    ("ex5", "        self.opt.load_state_dict(self.saved[1])\n", "", "Adam's state"),
    ("ex5", """for group in self.opt.param_groups:
            group["lr"] = self.lr""", "pass", "Adam steps at"),
    ("ex5", "self.lr *= self.lr_drop", "self.lr = self.lr", "did not drop"),
    ("ex6", '>= 1]', '>= 0]', "iteration 0 is counted"),
    ("ex6", "return sum(d) / len(d)", "return sum(d)", "sum over iterations"),
    ("ex6", "auc(read_iterations(rlil_run)) - auc(read_iterations(rl_run))",
     "auc(read_iterations(rl_run)) - auc(read_iterations(rlil_run))", "sign"),
]


def answer_source(key: str) -> str:
    """The shipped stub of `key` with every YOUR CODE HERE raise replaced by ANSWERS[key], in order."""
    text = (grade.EXERCISES_DIR / grade.EXERCISES[key].file).read_text()
    assert text.count(STUB) == len(ANSWERS[key]), key
    for code in ANSWERS[key]:
        text = text.replace(STUB, code, 1)
    return text


def graded(capsys, *argv) -> tuple[int, str]:
    status = grade.main(list(argv))
    out = capsys.readouterr()
    return status, out.out + out.err


@pytest.mark.parametrize("key", sorted(grade.EXERCISES))
def test_the_project_passes_the_stub_is_not_written_and_a_written_answer_passes(tmp_path, capsys, key):
    assert graded(capsys, key, "--solution") == (0, "pass\n")
    status, out = graded(capsys, key)
    assert status == 1 and out.startswith("not written yet:"), out
    path = tmp_path / f"{key}_answer.py"
    path.write_text(answer_source(key))
    status, out = graded(capsys, key, "--file", str(path))
    assert status == 0 and out.startswith("pass"), out


@pytest.mark.parametrize("key, line, wrong, message", MISTAKES,
                         ids=[f"{k}-{m.split()[0]}-{i}" for i, (k, _, _, m) in enumerate(MISTAKES)])
def test_a_typical_mistake_fails_with_a_message_that_names_it(tmp_path, capsys, key, line, wrong, message):
    source = answer_source(key)
    assert line in source, line
    path = tmp_path / f"{key}_wrong.py"
    path.write_text(source.replace(line, wrong, 1))
    status, out = graded(capsys, key, "--file", str(path))
    assert status == 1, out
    lines = out.splitlines()
    assert len(lines) == 2 and lines[0].startswith("fail: ") and lines[1].startswith("hint: "), out
    assert message in lines[0], out


def test_an_answer_that_does_not_import_or_raises_is_one_line_and_a_hint(tmp_path, capsys):
    path = tmp_path / "broken.py"
    path.write_text("def reward(s, a, s_next, graph)\n    return 0\n")
    status, out = graded(capsys, "ex1", "--file", str(path))
    assert status == 1 and "does not import: SyntaxError" in out and len(out.splitlines()) == 2, out
    path.write_text("def reward(s, a, s_next, graph):\n    return s.nope\n")
    status, out = graded(capsys, "ex1", "--file", str(path))
    assert status == 1 and "reward raised AttributeError" in out and "--traceback" in out, out
    path.write_text("x = 1\n")
    status, out = graded(capsys, "ex1", "--file", str(path))
    assert status == 1 and "has no reward" in out, out


@pytest.mark.parametrize("argv, said", [(["ex9"], "unknown exercise 'ex9': use one of ex1, ex2, ex3, ex4, ex5, ex6"),
                                        ([], "name an exercise: use one of ex1"),
                                        (["ex1", "--file", "no/such.py"], "no such file"),
                                        (["ex1", "--file", "x.py", "--solution"], "not allowed with")])
def test_bad_usage_is_exit_2_and_one_line(capsys, argv, said):
    status, out = graded(capsys, *argv)
    assert status == 2 and said in out and len(out.splitlines()) == 1, out


def test_exercise_names_may_be_given_as_number_stem_or_file_name(capsys):
    for name in ("3", "ex3_rl_loss", "ex3_rl_loss.py", "lesson/exercises/ex3_rl_loss.py"):
        assert grade.exercise_key(name) == "ex3"
    assert grade.exercise_key("ex7") is None


def test_the_grade_command_and_an_exercise_file_run_as_scripts():
    """`python lesson/grade.py ex1 --solution` and `python lesson/exercises/ex1_reward.py` from the
    project folder, as docs/lesson.md has them."""
    ok = subprocess.run([sys.executable, "lesson/grade.py", "ex1", "--solution"], cwd=ROOT,
                        capture_output=True, text=True)
    assert (ok.returncode, ok.stdout) == (0, "pass\n"), ok.stderr
    stub = subprocess.run([sys.executable, "lesson/exercises/ex1_reward.py"], cwd=ROOT, capture_output=True, text=True)
    assert stub.returncode == 1 and stub.stdout.startswith("not written yet"), stub.stdout + stub.stderr
    assert "lesson/exercises/ex1_reward.py" in stub.stdout


def test_the_experiment_report_prints_both_curves_and_the_committed_differences(tmp_path, capsys):
    """ex6's `__main__` with two runs: the committed class-demo differences are RL+IL - RL, seeds 0-4."""
    import json
    runs = []
    for name, curve in (("rl", [2.42, 9.83, 9.83]), ("rlil", [8.52, 9.21, 9.47])):
        (tmp_path / name).mkdir()
        (tmp_path / name / "metrics.json").write_text(json.dumps(
            {"iterations": [{"iteration": i, "distance_m": d} for i, d in enumerate(curve)]}))
        runs.append(str(tmp_path / name))
    assert grade.experiment_report(grade.project_auc_difference, "RL higher", *runs) == 0
    out = capsys.readouterr().out
    assert "your prediction: RL higher" in out and "2.42 9.83 9.83" in out
    assert "-0.49" in out and "seed 0: -0.49" in out, out
    assert grade.experiment_report(grade.project_auc_difference, "", str(tmp_path / "none"), runs[1]) == 2


def test_the_lesson_script_runs_end_to_end_at_the_tiny_budget(tmp_path):
    """`python lesson/lesson.py --out DIR`: every part, the figures in DIR, nothing else written
    (measured 8 s on a busy 2-core machine)."""
    before = sorted(p.name for p in (ROOT / "lesson").rglob("*") if "__pycache__" not in p.parts)
    done = subprocess.run([sys.executable, "lesson/lesson.py", "--out", str(tmp_path)], cwd=ROOT,
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    assert "all six parts" in done.stdout
    assert sorted(p.name for p in tmp_path.glob("*.png")) == [
        "lesson-1-reward.png", "lesson-2-design-graphs.png", "lesson-3-model.png", "lesson-4-cloning.png",
        "lesson-6-experiment.png"]
    assert sorted(p.name for p in (ROOT / "lesson").rglob("*") if "__pycache__" not in p.parts) == before
    refused = subprocess.run([sys.executable, "lesson/lesson.py", "--out", "results"], cwd=ROOT,
                             capture_output=True, text=True)
    assert refused.returncode != 0 and "inside the project" in refused.stderr
    assert len(refused.stderr.strip().splitlines()) == 1, refused.stderr


def test_the_lesson_script_is_a_notebook_in_jupytexts_percent_format():
    jupytext = pytest.importorskip("jupytext")            # requirements-lesson.txt, optional
    nb = jupytext.read(ROOT / "lesson" / "lesson.py")
    kinds = [cell.cell_type for cell in nb.cells]
    assert kinds.count("markdown") == 7 and kinds.count("code") == 7, kinds
    assert all(f"## Part {k}" in "".join(c.source for c in nb.cells) for k in range(1, 7))
