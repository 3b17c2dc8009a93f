"""Faults a user meets with one run: two writers, a signal, a full disk, bad output paths and values.

Each ends in one line (exit 2 for bad input), loses nothing the user had, leaves no empty folder,
and, where the run had started, says what was kept and the command that continues it.
"""
import errno
import json
import shutil
import signal
import subprocess
import sys
import time

import pytest
import torch

import modular_rlil_minimal as rlil
import train
from experiments import run_folders

TINY = ["--train", "car", "--preset", "tiny", "--iters", "1", "--eval-steps", "30", "--eval-episodes", "2",
        "--model-steps", "100", "--policy-steps", "10", "--random-episodes", "4"]      # seconds, not tens


def one_line_error(args, capsys) -> str:
    """train.main(args) exits 2 with one line on stderr and no traceback; returns the line."""
    with pytest.raises(SystemExit) as exit_:
        train.main(args)
    err = capsys.readouterr().err
    assert exit_.value.code == 2 and err.count("\n") == 1 and "Traceback" not in err, (args, err)
    return err


def wait_for(condition, proc, seconds=60):
    deadline = time.time() + seconds
    while not condition() and time.time() < deadline and proc.poll() is None:
        time.sleep(0.02)


def test_two_runs_started_at_once_into_one_folder_one_is_refused_and_nothing_is_lost(tmp_path):
    """Two real processes, same --out, started together: exactly one trains, the other is refused in one
    line, and the folder holds the one that trained (its seed in metrics.json)."""
    out = tmp_path / "same"                     # 64 random episodes: seconds between the start and the first file
    procs = [subprocess.Popen([sys.executable, "train.py", *TINY, "--random-episodes", "64", "--seed", str(seed),
                               "--out", str(out)],
                              stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True) for seed in (0, 1)]
    errs = [p.communicate(timeout=120)[1] for p in procs]
    codes = [p.returncode for p in procs]
    assert sorted(codes) == [0, 2], (codes, errs)
    loser = codes.index(2)
    assert errs[loser].count("\n") == 1 and ("is being written by" in errs[loser]
                                             or "already holds a run" in errs[loser]), errs[loser]
    saved = json.loads((out / "metrics.json").read_text())
    assert saved["config"]["seed"] == 1 - loser


def test_a_held_folder_refuses_a_second_writer_in_one_line(tmp_path, capsys):
    out = tmp_path / "run"
    lock, created = run_folders.claim_run_dir(out)
    try:
        assert created
        err = one_line_error([*TINY, "--out", str(out)], capsys)
        assert f"{out} is being written by train.py (pid " in err
    finally:
        lock.close()
    lock, created = run_folders.claim_run_dir(out)        # let go: the next writer gets it
    lock.close()
    assert not created


@pytest.mark.parametrize("where", ["open", "getpid"])
def test_a_signal_while_claiming_leaves_no_folder_made_there(tmp_path, monkeypatch, where):
    """A signal that arrives while the folder is being claimed (the lock file made, the lock not
    yet written: the moment a busy machine's SIGTERM test once caught) removes the folder the claim
    made, and leaves one that was there before."""
    def interrupt(*args, **kwargs):
        raise KeyboardInterrupt
    if where == "getpid":
        monkeypatch.setattr(run_folders.os, "getpid", interrupt)
    else:
        monkeypatch.setattr("builtins.open", interrupt)
    with pytest.raises(KeyboardInterrupt):
        run_folders.claim_run_dir(tmp_path / "new")
    assert not (tmp_path / "new").exists()
    (tmp_path / "old").mkdir()
    with pytest.raises(KeyboardInterrupt):
        run_folders.claim_run_dir(tmp_path / "old")
    assert (tmp_path / "old").is_dir()


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_after_the_first_checkpoint_says_what_was_kept_and_the_command_continues(tmp_path, signum):
    """Ctrl-C or SIGTERM (a scheduler's time limit) after iteration 0's checkpoint: exit 128 + signal,
    one line on stderr naming what the run keeps and a command; that command resumes it to its end."""
    out = tmp_path / "run"
    args = [*TINY, "--policy-steps", "40", "--out", str(out)]
    proc = subprocess.Popen([sys.executable, "train.py", *args], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            text=True, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    wait_for(lambda: (out / "metrics.json").exists(), proc)
    proc.send_signal(signum)
    err = proc.communicate(timeout=60)[1]
    assert proc.returncode == 128 + signum and err.count("\n") == 1 and "Traceback" not in err, err
    assert f"({signal.Signals(signum).name}): {out} keeps iteration 0" in err and err.strip().endswith("--resume")
    command = err.split("continue with: ")[1].split()
    assert command[:2] == ["python", "train.py"]
    if signum == signal.SIGINT:                   # the same command as after SIGTERM: run it once
        return
    done = subprocess.run([sys.executable, *command[1:]], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert [r["iteration"] for r in json.loads((out / "metrics.json").read_text())["iterations"]] == [0, 1]


def test_sigterm_before_the_first_checkpoint_leaves_no_folder(tmp_path):
    out = tmp_path / "run"
    proc = subprocess.Popen([sys.executable, "train.py", *TINY, "--random-episodes", "64", "--out", str(out)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    wait_for(lambda: (out / run_folders.LOCK).exists(), proc)       # the folder is claimed: the run has begun
    assert not (out / "checkpoint.pt").exists()
    proc.send_signal(signal.SIGTERM)
    err = proc.communicate(timeout=60)[1]
    assert proc.returncode == 143 and err.count("\n") == 1, err
    assert "nothing was kept" in err and not out.exists()


def test_a_signal_inside_an_import_arrives_after_it(tmp_path, monkeypatch):
    """An exception raised inside an import can be lost (numpy.random's lazy import swallowed a SIGTERM,
    and the run ended with status 0): the signal waits until the import is done, then stops the run."""
    (tmp_path / "module_being_imported.py").write_text(
        "import os, signal, time\nos.kill(os.getpid(), signal.SIGTERM)\ntime.sleep(0.2)\nFINISHED = True\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    before = signal.signal(signal.SIGTERM, train.on_signal)
    try:
        with pytest.raises(run_folders.Interrupted):
            import module_being_imported    # noqa: F401
            time.sleep(5)
    finally:
        signal.signal(signal.SIGTERM, before)
        module = sys.modules.pop("module_being_imported", None)
    assert module is not None and module.FINISHED


def test_a_full_disk_keeps_the_last_checkpoint_and_says_how_to_resume(tmp_path, capsys, monkeypatch):
    """torch.save fails at iteration 1's checkpoint (as on a full disk): one line, exit 1, the checkpoint
    of iteration 0 intact, and the printed command finishes the run once there is room."""
    out = tmp_path / "run"
    save, calls = torch.save, []

    def full_disk(obj, path, *a, **k):
        calls.append(path)
        if len(calls) > 2:                       # policy.pt and checkpoint.pt of iteration 0 are written
            raise RuntimeError("[enforce fail at inline_container.cc] . PytorchStreamWriter failed writing file")
        return save(obj, path, *a, **k)
    monkeypatch.setattr(torch, "save", full_disk)
    assert train.main([*TINY, "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "cannot write" in err and f"{out} keeps iteration 0" in err, err
    assert torch.load(out / "checkpoint.pt", weights_only=False)["iteration"] == 0
    assert not list(out.glob(".*.pt")) and not list(out.glob(".*.json"))     # no half-written temporary file
    monkeypatch.setattr(torch, "save", save)
    assert train.main(err.split("continue with: python train.py ")[1].split()) == 0
    assert [r["iteration"] for r in json.loads((out / "metrics.json").read_text())["iterations"]] == [0, 1]


def test_an_io_error_on_metrics_is_one_line_too(tmp_path, capsys, monkeypatch):
    out = tmp_path / "run"

    def no_space(out_dir, cfg, metrics):
        raise OSError(errno.ENOSPC, "No space left on device")
    monkeypatch.setattr(train, "save_metrics", no_space)
    assert train.main([*TINY, "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "metrics.json (No space left on device)" in err and "--resume" in err, err


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    out = tmp_path_factory.mktemp("finished") / "run"
    train.run(rlil.preset("tiny", train=("car",), iters=1, eval_steps=30, eval_episodes=2, model_steps=100,
                          policy_steps=10, random_episodes=4), out, log=lambda m: None)
    return out


def test_eval_output_paths_are_checked_before_the_evaluation(finished, tmp_path, capsys, monkeypatch):
    def evaluated(*a, **k):
        raise AssertionError("evaluated before the outputs were checked")
    monkeypatch.setattr(rlil, "evaluate_policy", evaluated)
    (tmp_path / "folder.gif").mkdir()
    (tmp_path / "mine.gif").write_text("mine")
    for flag, path, says in (("--gif", tmp_path / "missing" / "a.gif", "no folder"),
                             ("--gif", "/proc/a.gif", "cannot write in /proc"),
                             ("--gif", tmp_path / "folder.gif", "is a folder"),
                             ("--gif", tmp_path / "a.txt", "name a .gif file"),
                             ("--png", tmp_path / "a.gif", "name a .png file"),
                             ("--gif", tmp_path / "mine.gif", "already exists")):
        err = one_line_error(["--eval", str(finished), "--design", "car", flag, str(path)], capsys)
        assert says in err, (path, err)
    assert (tmp_path / "mine.gif").read_text() == "mine"
    err = one_line_error(["--compare", str(finished), str(finished), "--gif", "/proc/c.gif"], capsys)
    assert "cannot write in /proc" in err


def test_eval_refuses_training_flags(finished, capsys):
    for extra in (["--train", "car"], ["--iters", "3"], ["--resume"]):
        err = one_line_error(["--eval", str(finished), "--design", "car", *extra], capsys)
        assert "--eval evaluates a saved run with its own settings" in err


def test_resume_of_a_policy_file_is_refused_in_one_line(finished, tmp_path, capsys):
    out = tmp_path / "copy"
    shutil.copytree(finished, out)
    shutil.copy(out / "policy.pt", out / "checkpoint.pt")
    err = one_line_error([*TINY, "--iters", "2", "--out", str(out), "--resume"], capsys)
    assert "is not a training checkpoint" in err and "a policy.pt?" in err


@pytest.mark.parametrize("flag, value, says", [
    ("--seed", str(2 ** 64), "seed must be from 0 to 9223372036854775807"),
    ("--seed", "-1", "seed must be from 0"),
    ("--il-weight", "nan", "il_weight must be a finite number, got nan"),
    ("--policy-lr", "inf", "policy_lr must be a finite number, got inf"),
    ("--policy-lr", "-1e-3", "policy_lr must be positive, got -0.001"),
])
def test_bad_values_name_the_field_and_what_is_accepted(tmp_path, capsys, flag, value, says):
    err = one_line_error([*TINY, flag, value, "--out", str(tmp_path / "run")], capsys)
    assert says in err and not (tmp_path / "run").exists()


def test_an_output_file_is_claimed_by_one_process_until_it_ends(tmp_path, capsys, monkeypatch):
    """A CSV a tool will write is held from its checks to its end: a second process naming the same
    file is refused in one line naming the holder, before any work (two probes once both passed the
    checks and the later overwrote the other's rows); once the holder ends, the file is free."""
    out = tmp_path / "probe.csv"
    holder = subprocess.Popen(
        [sys.executable, "-c", "import sys, time; from experiments import run_folders; "
         f"run_folders.claim_output_file({str(out)!r}, '.csv', '--out', False); print('held', flush=True); "
         "time.sleep(120)"], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        with pytest.raises(run_folders.UsageError, match=f"is being written by .*pid {holder.pid}"):
            run_folders.claim_output_file(out, ".csv", "--out", True)
        from experiments import flattery_curve

        def worked(*a, **k):
            raise AssertionError("worked before the output was claimed")
        monkeypatch.setattr(flattery_curve, "phase_rows", worked)
        with pytest.raises(SystemExit) as exit_:
            flattery_curve.main(["--seeds", "0", "--out", str(out)])
        assert exit_.value.code == 2 and f"pid {holder.pid}" in capsys.readouterr().err
    finally:
        holder.kill()
        holder.wait()
    run_folders.claim_output_file(out, ".csv", "--out", False)      # let go with its process: free
    run_folders.claim_output_file(out, ".csv", "--out", False)      # and this process may ask again
    assert not out.exists()


def test_an_output_file_whose_lock_cannot_be_made_is_one_line(tmp_path, monkeypatch):
    (tmp_path / "locks").write_text("a file where the lock folder would be")
    monkeypatch.setattr(run_folders, "OUTPUT_LOCKS", tmp_path / "locks" / "sub")
    with pytest.raises(run_folders.UsageError, match="cannot hold it, no lock in .*set TMPDIR"):
        run_folders.claim_output_file(tmp_path / "out.csv", ".csv", "--out", False)
