"""Faults a sweep must survive: run folders of other configs, unreadable metrics, bad flags and
paths, an unreachable Ray cluster, SIGTERM, and --keep-metrics / tables.py --check over bad data.

Each case is one line of error (exit status 2, or a UsageError in the code) or a named missing
run, with nothing written, lost or left behind.  The runs here are fake finished ones (a
metrics.json with the run's config) except in the SIGTERM test, which stops two real train.py
processes.
"""
import dataclasses
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

import modular_rlil_minimal as rlil
import train
from experiments import run_folders, sweeps, tables
from tools import check_physics

REPO = Path(__file__).resolve().parents[1]
TINY_SWEEP = dict(iters=1, eval_steps=30, policy_steps=6, bc_steps=10, model_steps=50, demo_episodes=4)
TINY_FLAGS = ["--preset", "tiny", "--iters", "1", "--eval-steps", "30", "--policy-steps", "6", "--bc-steps", "10",
              "--model-steps", "50", "--demo-episodes", "4"]          # TINY_SWEEP on the command line


def quiet(*args, **kw):
    pass


def write_run(run_dir: Path, cfg, iterations: int | None = None, distance=1.0) -> None:
    """A finished run's metrics.json (iterations 0..cfg.iters unless given), made with `cfg`."""
    run_dir.mkdir(parents=True, exist_ok=True)
    rows = [{"iteration": i, "distance_m": distance + i, "sim_steps": 100 * (i + 1), "seconds": 1.0}
            for i in range((cfg.iters if iterations is None else iterations) + 1)]
    (run_dir / "metrics.json").write_text(json.dumps({"config": run_folders.config_to_dict(cfg), "iterations": rows}))


def panel_b(out: Path, base=None, edit=None) -> list[dict]:
    """Panel (b)'s two runs (car RL+IL and RL, seed 0) under `out`, finished, each made with its own
    config (or edit(config))."""
    runs = sweeps.figure3_runs(out, base or rlil.preset("tiny", **TINY_SWEEP), 1, 2, "b")
    for r in runs:
        write_run(r["dir"], edit(r["cfg"]) if edit else r["cfg"])
    return runs


def cli(capsys, argv, main=train.main):
    """(exit status, stderr lines) of a command line run in-process."""
    try:
        code = main([str(a) for a in argv])
    except SystemExit as e:
        code = e.code
    return code, capsys.readouterr().err.strip().splitlines()


@pytest.fixture
def nothing_runs(monkeypatch):
    monkeypatch.setattr(sweeps, "run_one", lambda *a: pytest.fail("a run was launched"))


# ----------------------------------------------------------------------------
# A run folder is reused only with the config the sweep asks for
# ----------------------------------------------------------------------------
def test_a_sweep_reuses_a_run_only_with_the_config_it_asks_for(tmp_path, capsys, nothing_runs):
    base = rlil.preset("tiny", **TINY_SWEEP)
    runs = panel_b(tmp_path)
    before = {r["dir"]: (r["dir"] / "metrics.json").read_text() for r in runs}
    with pytest.raises(run_folders.UsageError) as e:
        sweeps.figure3(tmp_path, dataclasses.replace(base, policy_steps=7), 1, 2, log=quiet, panels="b")
    message = str(e.value)
    assert "\n" not in message and "car-car-seed0 was made with policy_steps=6; this sweep asks policy_steps=7" in message
    assert "(and 1 more run)" in message and "--accept-other-configs" in message
    assert not (tmp_path / "figure3.csv").exists()                  # nothing written
    code, err = cli(capsys, ["--figure3", *TINY_FLAGS, "--policy-steps", "7", "--panels", "b", "--seeds", "1",
                             "--out", tmp_path, "--plan"])
    assert code == 2 and len(err) == 1 and "policy_steps=6" in err[0] and "car-car-seed0" in err[0]
    lines = []                                                       # asked to, it uses them as they are
    assert sweeps.figure3(tmp_path, dataclasses.replace(base, policy_steps=7), 1, 2, log=lines.append, panels="b",
                          accept_other_configs=True) == []
    warning = [line for line in lines if line.startswith("warning")]
    assert len(warning) == 1 and "2 runs made with other settings" in warning[0] and "car-rl-seed0" in warning[0]
    assert {r["dir"]: (r["dir"] / "metrics.json").read_text() for r in runs} == before

    # the budget: a shorter recorded one is what a resume continues, a longer one is another config
    longer = sweeps.figure3_runs(tmp_path, dataclasses.replace(base, iters=2), 1, 2, "b")
    sweeps.check_reuse(longer)
    assert len(sweeps.plan_lines(longer, 2)) == 2                    # both to be continued
    with pytest.raises(run_folders.UsageError, match="was made with iters=1; this sweep asks iters=0"):
        sweeps.check_reuse(sweeps.figure3_runs(tmp_path, dataclasses.replace(base, iters=0), 1, 2, "b"))


def test_a_sweep_names_an_unreadable_metrics_json_before_it_runs_anything(tmp_path, nothing_runs):
    runs = panel_b(tmp_path)
    (runs[1]["dir"] / "metrics.json").write_text('{"config": {}, "iter')
    with pytest.raises(run_folders.UsageError, match=r"car-rl-seed0/metrics.json is not JSON .*: move that run"):
        sweeps.figure3(tmp_path, rlil.preset("tiny", **TINY_SWEEP), 1, 2, log=quiet, panels="b")
    assert not (tmp_path / "figure3.csv").exists()


@pytest.mark.parametrize("other, named", [(dict(train=("hexapod",)), "train=hexapod"), (dict(seed=1), "seed=1"),
                                          (dict(policy_steps=9), "policy_steps=9")])
def test_collect_refuses_a_run_of_another_design_seed_or_budget_copied_in(tmp_path, other, named):
    runs = panel_b(tmp_path / "runs")
    rl = runs[1]                                                     # car RL seed 0
    write_run(rl["dir"], dataclasses.replace(rl["cfg"], **other))     # another run's metrics.json copied in
    with pytest.raises(run_folders.UsageError) as e:
        sweeps.figure3(tmp_path / "out", rlil.preset("tiny", **TINY_SWEEP), 1, 2, log=quiet, panels="b",
                       collect=tmp_path / "runs")
    assert f"car-rl-seed0 was made with {named};" in str(e.value) and "\n" not in str(e.value)
    assert not (tmp_path / "out").exists()                            # nothing left behind


@pytest.mark.parametrize("content, why", [
    ("{not json", "metrics.json is not JSON"),
    ("[1, 2]", "metrics.json is not a train.py metrics.json"),
    (None, "metrics.json holds distance_m=null at iteration 1"),          # train.py's form of a non-finite figure
])
def test_collect_names_unreadable_metrics_and_nulls_as_failed_runs(tmp_path, capsys, content, why):
    runs = panel_b(tmp_path)
    path = runs[1]["dir"] / "metrics.json"
    if content is None:
        saved = json.loads(path.read_text())
        saved["iterations"][1]["distance_m"] = None
        content = json.dumps(saved)
    path.write_text(content)
    problems = sweeps.figure3(tmp_path / "out", rlil.preset("tiny", **TINY_SWEEP), 1, 2, log=quiet, panels="b",
                              collect=tmp_path)
    assert len(problems) == 1 and problems[0].startswith(f"(b) RL seed 0: {why}"), problems
    csv_text = (tmp_path / "out" / "figure3.csv").read_text()
    assert ",RL+IL," in csv_text and ",RL," not in csv_text           # the bad run is left out
    assert why in (tmp_path / "out" / "figure3.md").read_text()
    code, _ = cli(capsys, ["--figure3", *TINY_FLAGS, "--panels", "b", "--seeds", "1", "--collect", tmp_path,
                           "--out", tmp_path / "out2"])
    assert code == 1                                                  # a run is missing: exit 1, no traceback


def test_plan_resumes_an_interrupted_run_with_its_own_seed_and_config(tmp_path):
    """What every launcher runs (run_command): the run's own arguments, --resume once it has a checkpoint."""
    base = rlil.preset("tiny", **dict(TINY_SWEEP, iters=2))
    runs = sweeps.figure3_runs(tmp_path, base, 2, 2, "b")
    stopped = next(r for r in runs if r["method"] == "RL" and r["seed"] == 1)
    write_run(stopped["dir"], stopped["cfg"], iterations=1)            # iteration 1 of 2, then stopped
    (stopped["dir"] / "checkpoint.pt").write_bytes(b"not read here")
    sweeps.check_reuse(runs)
    lines = sweeps.plan_lines(runs, base.iters)
    assert len(lines) == 4
    line = next(line for line in lines if "car-rl-seed1 " in line)
    assert line.endswith(f"--out {stopped['dir']} --resume >> {stopped['dir'] / 'train.log'} 2>&1")
    received = train.config_from_args(train.build_parser().parse_args(line.split(" && ")[1].split(" >> ")[0]
                                                                      .split()[2:-1]))
    assert received == stopped["cfg"]                                 # its seed and config, threads included
    assert [line for line in lines if "--resume" in line] == [line]


# ----------------------------------------------------------------------------
# --keep-metrics and the tables: nothing committed is replaced by less, bad data is named
# ----------------------------------------------------------------------------
def test_keep_metrics_never_replaces_a_run_of_another_config_or_more_iterations(tmp_path, capsys):
    keep = lambda *argv: cli(capsys, ["--keep-metrics", *argv], main=sweeps.main)     # noqa: E731
    panel_b(tmp_path / "src")                                        # a tiny sweep's two finished runs
    dest = tmp_path / "dest"
    for name in ("car-car-seed0", "car-rl-seed0"):                   # the committed runs of the default config
        shutil.copytree(REPO / "results" / "figure3_runs" / name, dest / name)
    committed = {p: p.read_bytes() for p in dest.glob("*/metrics.json")}
    code, err = keep(tmp_path / "src", dest)
    assert code == 2 and len(err) == 1 and "car-car-seed0/metrics.json holds a run made with iters=5" in err[0]
    assert "not replaced, nothing was kept (--force replaces it)" in err[0]
    assert {p: p.read_bytes() for p in dest.glob("*/metrics.json")} == committed

    base = rlil.preset("tiny", **TINY_SWEEP)                          # the same config with more iterations
    cfg = sweeps.figure3_runs(tmp_path, base, 1, 2, "b")[0]["cfg"]
    write_run(tmp_path / "more" / "car-car-seed0", cfg, iterations=3)
    with pytest.raises(run_folders.UsageError, match="holds 4 iterations, the new one only 2"):
        sweeps.keep_metrics(tmp_path / "src", tmp_path / "more")
    write_run(tmp_path / "longer" / "car-car-seed0", dataclasses.replace(cfg, iters=2))   # a continuation of dest's
    assert sweeps.keep_metrics(tmp_path / "longer", tmp_path / "src") == ["car-car-seed0"]

    assert keep(tmp_path / "src", dest, "--force")[0] == 0
    assert (dest / "car-rl-seed0" / "metrics.json").read_text() == (
        tmp_path / "src" / "car-rl-seed0" / "metrics.json").read_text()
    (tmp_path / "afile").write_text("mine\n")
    code, err = keep(tmp_path / "src", tmp_path / "afile")
    assert code == 2 and len(err) == 1 and "afile is a file" in err[0]
    assert (tmp_path / "afile").read_text() == "mine\n"


@pytest.fixture
def results_copy(tmp_path, monkeypatch):
    """results/ (without its images) under tmp_path, as tables.ROOT."""
    shutil.copytree(REPO / "results", tmp_path / "results", ignore=shutil.ignore_patterns("*.gif", "*.png"))
    monkeypatch.setattr(tables, "ROOT", tmp_path)
    return tmp_path / "results"


def test_tables_check_names_a_bad_run_metrics_json_in_one_line(results_copy, capsys):
    tiny = rlil.preset("tiny", **TINY_SWEEP)                          # a tiny run kept over a committed one
    write_run(results_copy / "figure3_runs" / "car-car-seed0", tiny)
    code, err = cli(capsys, ["--check"], main=tables.main)
    assert code == 2 and len(err) == 1 and "figure3_runs/car-car-seed0/metrics.json has 2 iterations" in err[0]


@pytest.mark.parametrize("cut", ["end", "middle"])
def test_tables_check_names_a_csv_cut_mid_row_in_one_line(results_copy, capsys, cut):
    path = results_copy / "figure3.csv"
    text = path.read_text()
    if cut == "end":
        path.write_text(text[:-25])                                   # the last row cut short
    else:
        lines = text.splitlines(keepends=True)
        path.write_text("".join(lines[:5]) + ",".join(lines[5].split(",")[:4]) + "\r\n" + "".join(lines[6:]))
    code, err = cli(capsys, ["--check"], main=tables.main)
    assert code == 2 and len(err) == 1 and "results/figure3.csv" in err[0]
    assert ("cut short" in err[0]) if cut == "end" else ("line 6: 4 of 11 cells" in err[0])


# ----------------------------------------------------------------------------
# Flags a sweep would not use, counts, paths
# ----------------------------------------------------------------------------
@pytest.mark.parametrize("argv, said", [
    (["--figure3", "--sample-efficiency"], "two sweeps"),
    (["--sample-efficiency", "--panels", "z"], "--panels goes with --figure3"),
    (["--figure3", "--train", "hexapod"], "--train does nothing with --figure3"),
    (["--figure3", "--seed", "3"], "--seed does nothing"),
    (["--figure3", "--method", "ppo"], "--method ppo does nothing with --figure3"),
    (["--sample-efficiency", "--method", "ppo"], "--method ppo does nothing with --sample-efficiency"),
    (["--figure3", "--env-steps", "1000"], "--env-steps is PPO's"),
    (["--figure3", "--threads", "2"], "--threads applies to a sweep only with --jobs 1"),
    (["--figure3", "--resume"], "--resume and --force do nothing"),
    (["--figure3", "--eval", "runs/x"], "--eval does not go with --figure3"),
    (["--figure3", "--seeds", "1001"], "--seeds takes 1 to 1000"),
    (["--figure3", "--jobs", "100000"], "--jobs 1 to 256"),
])
def test_a_flag_the_sweep_would_not_use_is_refused_in_one_line(tmp_path, capsys, argv, said):
    code, err = cli(capsys, [*argv, "--plan", "--out", tmp_path / "x"])
    assert code == 2 and len(err) == 1 and said in err[0], err
    assert not (tmp_path / "x").exists()


def test_a_huge_seed_count_is_refused_at_once_and_random_codes_are_bounded(capsys):
    done = subprocess.run([sys.executable, "train.py", "--figure3", "--seeds", "1000000000", "--plan"], cwd=REPO,
                          capture_output=True, text=True, timeout=15)
    assert done.returncode == 2 and done.stdout == "" and len(done.stderr.splitlines()) == 1
    assert "--seeds takes 1 to 1000" in done.stderr
    code, err = cli(capsys, ["--random-codes", "100000"], main=check_physics.main)
    assert code == 2 and len(err) == 1 and "--random-codes takes 0 to 724 (the 728 codes less the 4 given)" in err[0]


def test_an_output_folder_that_cannot_be_written_is_refused_before_any_work(tmp_path, capsys):
    panel_b(tmp_path / "runs")
    flags = ["--figure3", *TINY_FLAGS, "--panels", "b", "--seeds", "1"]
    code, err = cli(capsys, [*flags, "--collect", tmp_path / "runs", "--out", "/proc/col"])
    assert code == 2 and len(err) == 1 and "cannot write --out /proc/col" in err[0]
    (tmp_path / "afile").write_text("mine\n")
    code, err = cli(capsys, [*flags, "--collect", tmp_path / "runs", "--out", tmp_path / "afile"])
    assert code == 2 and len(err) == 1 and "afile is a file" in err[0]
    code, err = cli(capsys, [*flags, "--out", tmp_path / "afile" / "sweep"])     # a sweep that would run
    assert code == 2 and len(err) == 1 and "cannot write --out" in err[0]
    assert not list(tmp_path.glob("runs/figure3.*")) and (tmp_path / "afile").read_text() == "mine\n"


# ----------------------------------------------------------------------------
# Ray and SIGTERM: fail or stop in one line, nothing left behind, no orphan
# ----------------------------------------------------------------------------
def test_an_unreachable_ray_address_fails_in_one_line_within_15_s(tmp_path):
    pytest.importorskip("ray")
    done = subprocess.run([sys.executable, "train.py", "--figure3", *TINY_FLAGS, "--panels", "b", "--seeds", "1",
                           "--launcher", "ray", "--ray-address", "127.0.0.1:1", "--out", str(tmp_path / "x")],
                          cwd=REPO, capture_output=True, text=True, timeout=15)
    err = done.stderr.strip().splitlines()
    assert done.returncode == 2 and len(err) == 1 and "--ray-address 127.0.0.1:1: nothing answers there" in err[0], err
    assert not (tmp_path / "x").exists()
    with pytest.raises(run_folders.UsageError, match="takes HOST:PORT"):
        sweeps.check_ray("headnode")


def children_of(pid: int) -> list[int]:
    """The live processes whose parent is `pid` (Linux /proc)."""
    kids = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid and fields[0] != "Z":
            kids.append(int(stat.parent.name))
    return kids


def alive(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads the processes from /proc")
def test_sigterm_stops_the_sweeps_runs_and_says_how_to_continue(tmp_path):
    """SIGTERM (a scheduler's time limit) reaches each running train.py, which keeps its finished
    iterations; the sweep waits for them, prints one line with the command that continues it, and
    exits 143; no run is left running."""
    argv = ["train.py", "--figure3", "--preset", "tiny", "--panels", "b", "--seeds", "1", "--jobs", "2",
            "--out", str(tmp_path / "sweep")]
    sweep = subprocess.Popen([sys.executable, *argv], cwd=REPO, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                             text=True)
    logs = [tmp_path / "sweep" / name / "train.log" for name in ("car-car-seed0", "car-rl-seed0")]
    kids = []
    try:
        deadline = time.time() + 60                                  # both runs at work (their first log line)
        while time.time() < deadline and not (all(p.exists() and p.stat().st_size for p in logs)
                                              and len(children_of(sweep.pid)) == 2):
            assert sweep.poll() is None, sweep.stderr.read()
            time.sleep(0.1)
        kids = children_of(sweep.pid)
        assert len(kids) == 2
        sweep.send_signal(signal.SIGTERM)
        _, err = sweep.communicate(timeout=40)
        lines = err.strip().splitlines()
        assert sweep.returncode == 143 and "Traceback" not in err, err
        assert lines[-1].startswith("interrupted (SIGTERM): 0 of 2 runs finished and kept in ")
        assert lines[-1].endswith("continue with: python " + " ".join(argv))
        assert not [pid for pid in kids if alive(pid)]               # no orphan
        for log in logs:                                             # each run was stopped, not left to finish
            text = log.read_text()
            assert "interrupted (SIGTERM)" in text and "done:" not in text, text
    finally:
        for pid in [*kids, sweep.pid]:
            if alive(pid):
                os.kill(pid, signal.SIGKILL)
