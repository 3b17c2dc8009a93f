"""Sweeps: many train.py runs of one experiment, then one plot, one CSV and one summary table.

A sweep is a set of runs that differ only in design, demonstrations, method
and seed: the paper's Figure 3 (4 panels x {RL+IL, RL} x seeds) and the
sample-efficiency comparison (hexapod and leg_none_wheel x {RL+IL, RL, PPO,
PPO+IL} x seeds).  Each run is a normal train.py run directory under the
sweep's folder (runs/figure3/<run name>/ with metrics.json, checkpoint.pt,
...), made by its own `train.py` process, --jobs at a time, its output in its
train.log.  A finished run (its metrics.json at its last iteration) is reused,
an interrupted one continues with --resume, so a sweep that stops resumes where
it was, and its runs can be spread over machines and merged into one folder
before plotting.  A run folder is reused or resumed only when its
metrics.json can be read and records the config the sweep asks for that run
(`check_reuse`); SIGTERM or Ctrl-C stops the runs in progress, each keeping its
finished iterations (`stop_runs`).  The sweep then writes <name>.png,
<name>.csv and <name>.md there.  The committed tables are made from the committed CSVs by
experiments/tables.py.

    python train.py --figure3 [--seeds 3] [--jobs 2] [--panels abcd] [--out runs/figure3]
    python train.py --sample-efficiency [--seeds 3] [--jobs 2] [--env-steps N] [--out runs/sample_efficiency]
    python experiments/sweeps.py --keep-metrics SWEEP_DIR DEST [--force]   # what is committed of a sweep
"""
from __future__ import annotations

import csv
import dataclasses
import json
import math
import shlex
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

if __package__ in (None, ""):              # run as a script: the stage files are one folder up
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import modular_rlil_minimal as rlil                                                          # noqa: E402
import ppo_minimal as ppo_lib                                                                 # noqa: E402
import sim2d                                                                                  # noqa: E402
from experiments.run_folders import (COLOURS, Interrupted, UsageError, config_args,  # noqa: E402
                                     config_from_dict, is_ppo, run_name)
from experiments.stats import (area_under_curve, bootstrap_ci, interval, iterations_to_converge)  # noqa: E402
from sim2d import atomic_write                                                                # noqa: E402

ROOT = Path(__file__).resolve().parents[1]          # the repository: train.py, results/
LAUNCHERS = ("local", "ray")                        # how a sweep runs its runs (launch_runs)
MAX_SEEDS, MAX_JOBS = 1000, 256                     # the most --seeds and --jobs a sweep takes
STOP_GRACE_S = 20.0         # how long a stopped sweep waits for its runs to keep their work before killing them
RAY_CONNECT_S = 6.0         # how long --ray-address gets to answer (a TCP connect, then a trial ray.init)


# ----------------------------------------------------------------------------
# Figure 3 of the paper: four conditions, RL vs RL+IL, over seeds
# ----------------------------------------------------------------------------
PANELS = {   # panel: (trained design, demo designs), the paper's Fig. 3 (a)-(d)
    "a": ("hexapod", ("hexapod",)),
    "b": ("car", ("car",)),
    "c": ("leg_leg_wheel", ("hexapod", "car")),
    "d": ("leg_none_wheel", ("hexapod", "car")),
}


def figure3_runs(out: Path, base: rlil.Config, seeds: int, jobs: int, panels: str = "abcd") -> list[dict]:
    """One entry per run of the sweep: its panel, method, seed, directory and train.py arguments.

    Every run has `base`'s budget; design, demos and seed are the panel's, and a
    run gets one torch thread when several run at once.
    """
    runs = []
    for panel, (design, demos) in PANELS.items():
        if panel not in panels:
            continue
        for method, demo_list in (("RL+IL", demos), ("RL", ())):
            for seed in range(seeds):
                cfg = dataclasses.replace(base, train=(sim2d.parse_design(design),), seed=seed,
                                          demos=tuple(sim2d.parse_design(d) for d in demo_list),
                                          threads=1 if jobs > 1 else base.threads)
                runs.append({"panel": panel, "train": design, "demos": "+".join(demos), "method": method,
                             "seed": seed, "dir": out / run_name(cfg), "args": config_args(cfg), "cfg": cfg})
    return runs


# ----------------------------------------------------------------------------
# Reusing a run folder: its metrics.json must be readable and record the asked config
# ----------------------------------------------------------------------------
def read_metrics(run_dir: Path) -> tuple[dict | None, str | None]:
    """(run_dir/metrics.json, its config rebuilt under "cfg"), None); (None, what is wrong with it, in
    words) when it cannot be used; (None, None) when there is none."""
    try:
        saved = json.loads((Path(run_dir) / "metrics.json").read_text())
    except (FileNotFoundError, NotADirectoryError):
        return None, None
    except OSError as e:
        return None, f"cannot be read ({e.strerror or type(e).__name__})"
    except ValueError:                                    # not JSON, or not text
        return None, "is not JSON (cut short, or not written by train.py)"
    its = saved.get("iterations") if isinstance(saved, dict) else None
    if not (isinstance(its, list) and its and all(isinstance(m, dict) and type(m.get("iteration")) is int for m in its)):
        return None, "is not a train.py metrics.json (no list of iterations)"
    try:
        cfg = config_from_dict(saved["config"])
    except UsageError as e:
        return None, f"records a config this version cannot rebuild ({e})"
    except (KeyError, TypeError, ValueError, AttributeError):
        return None, "records no config that train.py wrote"
    return {**saved, "cfg": cfg}, None


def null_figure(saved: dict, keys=("distance_m",), optional=()) -> str | None:
    """The first figure among `keys` (and `optional` ones, where a row has them) that is not a finite
    number in a metrics.json's rows, in words (train.py writes a non-finite one as null); else None."""
    for m in saved["iterations"]:
        for k in keys + tuple(k for k in optional if k in m):
            v = m.get(k)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                return f"holds {k}={json.dumps(v)} at iteration {m['iteration']} (no finite figure)"
    return None


def shown(setting: str, value) -> str:
    """A config value as the sweep's messages show it: designs by name, no demos as none."""
    if setting in ("train", "demos"):
        return "+".join(sim2d.design_name(d) for d in value) or "none"
    return str(value)


INACTIVE = {"clone_data": lambda cfg: not rlil.uses_clone_data(cfg)}   # setting: when it does nothing


def config_difference(recorded, asked) -> list[tuple[str, str, str]]:
    """(setting, recorded value, asked value) for every setting in which a run's recorded config
    differs from the asked one ("versions" is not a setting).  The budget (Algorithm 1's iters,
    PPO's env_steps) counts only where the recorded one is larger: a smaller one is what --resume
    continues.  A setting of INACTIVE counts only where it acts in both (--clone-data only with
    demos): the committed RL runs of Figure 3 were made with it off."""
    method = lambda c: "ppo" if is_ppo(c) else "rlil"                # noqa: E731
    if method(recorded) != method(asked):
        return [("method", method(recorded), method(asked))]

    def flat(cfg) -> dict:
        d = dataclasses.asdict(cfg)
        return {**{k: v for k, v in d.items() if k != "gnn"}, **{f"gnn.{k}": v for k, v in d["gnn"].items()}}
    old, new = flat(recorded), flat(asked)
    budget = "env_steps" if is_ppo(asked) else "iters"
    idle = {k for k, inactive in INACTIVE.items() if k in new and (inactive(recorded) or inactive(asked))}
    return [(k, shown(k, old[k]), shown(k, new[k])) for k in new
            if old[k] != new[k] and k not in idle and not (k == budget and old[k] < new[k])]


def settings(diff: list[tuple], side: int, limit: int = 4) -> str:
    """`setting=value, ...` of one side (1: recorded, 2: asked) of a config_difference, `limit` at most."""
    text = ", ".join(f"{d[0]}={d[side]}" for d in diff[:limit])
    return text + (f" and {len(diff) - limit} more" if len(diff) > limit else "")


def more(items: list) -> str:
    return f" (and {len(items) - 1} more run{'s' * (len(items) > 2)})" if len(items) > 1 else ""


def check_reuse(runs: list[dict], accept: bool = False, collect: bool = False, log=print) -> None:
    """Before anything runs or is written: a UsageError of one line for the first run folder whose
    metrics.json cannot be read (with `collect` such a run is named among the missing ones instead)
    or whose recorded config is not the one the sweep asks for that run (config_difference), unless
    `accept`: then those runs are used as they are (r["as_is"]: neither resumed nor run again) and
    one warning line names them."""
    unreadable, other = [], []
    for r in runs:
        saved, why = read_metrics(r["dir"])
        if why and not collect:
            unreadable.append(f"{r['dir'] / 'metrics.json'} {why}")
        elif saved and config_difference(saved["cfg"], r["cfg"]):
            other.append((r, config_difference(saved["cfg"], r["cfg"])))
    if unreadable:
        raise UsageError(f"{unreadable[0]}{more(unreadable)}: move that run folder away (or repair the file) "
                         "and run the sweep again")
    if other and not accept:
        r, diff = other[0]
        raise UsageError(f"{r['dir']} was made with {settings(diff, 1)}; this sweep asks {settings(diff, 2)}"
                         f"{more(other)}: a sweep reuses a run only with the settings it asks for (run it with "
                         "those, name another folder, or pass --accept-other-configs to use such runs as they are)")
    for r, _ in other:
        r["as_is"] = True
    if other:
        log(f"warning: {len(other)} run{'s' * (len(other) > 1)} made with other settings used as they are "
            "(--accept-other-configs): " + "; ".join(f"{r['dir']} ({settings(diff, 1)})" for r, diff in other))


def check_writable(out: Path) -> None:
    """A UsageError of one line unless `out` is, or can be made, a folder files can be written in;
    whatever this made to find out is removed again."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise UsageError(f"--out {out} is a file: name a folder for the sweep's outputs")
    top = out
    while not top.parent.exists() and top.parent != top:
        top = top.parent                                  # the first folder this would make
    made = not top.exists()
    try:
        out.mkdir(parents=True, exist_ok=True)
        tempfile.TemporaryFile(dir=out).close()
    except OSError as e:
        raise UsageError(f"cannot write --out {out} ({e.strerror or type(e).__name__}): name a folder you can write")
    finally:
        if made and top.is_dir():
            shutil.rmtree(top, ignore_errors=True)


def run_problem(r: dict, last: int, keys=("distance_m",), optional=()) -> str | None:
    """Why run `r` is missing or failed, in words ending with its folder; None when it finished: its
    exit status, an unreadable metrics.json, a null figure, or fewer than its iterations."""
    saved, why = read_metrics(r["dir"])
    code = r.get("returncode", 0)
    status = f"exit status {code}, " if code else ""
    bad = why or (null_figure(saved, keys, optional) if saved else None)
    if bad:
        return f"{status}metrics.json {bad} ({r['dir']})"
    done = saved["iterations"][-1]["iteration"] if saved else 0
    last = r.get("last", last)
    return f"{status}{max(done, 0)} of {last} iterations ({r['dir']})" if done < last or code else None


def last_iteration(run_dir: Path) -> int:
    """The iteration of the last row of a run's metrics.json; -1 when it has none (or it cannot be read)."""
    saved, _ = read_metrics(run_dir)
    return saved["iterations"][-1]["iteration"] if saved else -1


# ----------------------------------------------------------------------------
# Launchers: local processes, Ray tasks, or a plan for any scheduler
# ----------------------------------------------------------------------------
def run_command(run: dict) -> list[str]:
    """The train.py command of one run: its arguments and directory, --resume once it has a checkpoint."""
    cmd = [sys.executable, str(ROOT / "train.py"), *run["args"], "--out", str(run["dir"])]
    return cmd + (["--resume"] if (run["dir"] / "checkpoint.pt").exists() else [])


RUNNING: dict = {}               # pid -> Popen of every train.py this process runs now (run_one)
RUNNING_LOCK = threading.Lock()
STOPPING = threading.Event()     # set by stop_runs: no run starts any more
SIGNALLED: list = []             # the signals raise_interrupted saw (Ray's ray.wait turns them into KeyboardInterrupt)
STOP_FILE = ".stop"              # a run folder's request to stop its run, made by a stopped Ray sweep (ray_results)


def run_one(cmd: list[str], run_dir: str) -> int:
    """Run one train.py command, its output appended to run_dir/train.log; returns its exit status.
    It runs in a session of its own, so a signal reaches it only as the sweep passes it on
    (stop_runs), or, on a Ray worker, as run_dir/STOP_FILE appears; interrupted while waiting for
    it, this stops it in turn."""
    stop = Path(run_dir) / STOP_FILE
    with RUNNING_LOCK:
        if STOPPING.is_set() or stop.exists():
            return -signal.SIGTERM
        Path(run_dir).mkdir(parents=True, exist_ok=True)
        with open(Path(run_dir) / "train.log", "a") as f:
            proc = subprocess.Popen(cmd, stdout=f, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                    start_new_session=True)
        RUNNING[proc.pid] = proc
    try:
        while True:
            try:
                return proc.wait(timeout=0.5)
            except subprocess.TimeoutExpired:
                if stop.exists():
                    stop_processes([proc], signal.SIGTERM)
    except BaseException:
        stop_processes([proc], signal.SIGTERM)
        raise
    finally:
        with RUNNING_LOCK:
            RUNNING.pop(proc.pid, None)


def stop_processes(procs: list, signum: int, grace: float = STOP_GRACE_S, hurry=None) -> None:
    """Send `signum` to each process still running, wait up to `grace` seconds (or until `hurry` is
    set) for them to end, then kill those left."""
    for p in procs:
        if p.poll() is None:
            try:
                p.send_signal(signum)
            except ProcessLookupError:
                pass
    deadline = time.monotonic() + grace
    while (any(p.poll() is None for p in procs) and time.monotonic() < deadline
           and not (hurry and hurry.is_set())):
        time.sleep(0.05)
    for p in procs:
        if p.poll() is None:
            p.kill()
            p.wait()


def stop_runs(signum: int, grace: float = STOP_GRACE_S) -> None:
    """Pass `signum` (SIGTERM, SIGINT) on to every train.py this process runs, so that each keeps its
    finished iterations and prints its resume line, and wait for them: `grace` seconds at most, or
    until a second signal; those left are killed (their last checkpoint stays).  No run starts after."""
    hurry = threading.Event()
    main = threading.current_thread() is threading.main_thread()
    before = {s: signal.signal(s, lambda *_: hurry.set()) for s in (signal.SIGINT, signal.SIGTERM)} if main else {}
    try:
        with RUNNING_LOCK:
            STOPPING.set()
            procs = list(RUNNING.values())
        stop_processes(procs, signum, grace, hurry)
    finally:
        for s, handler in before.items():
            signal.signal(s, handler)


def raise_interrupted(signum, frame) -> None:
    """SIGTERM handler of a sweep: stop like Ctrl-C does."""
    SIGNALLED.append(signum)
    raise Interrupted(signum)


def interrupted_line(e: Interrupted, out: Path, command: str) -> str:
    """The one line a stopped sweep prints: what was kept and the command that continues it."""
    counts = f"{e.finished} of {e.total} runs finished and" if e.total is not None else "finished runs are"
    return (f"interrupted ({e}): {counts} kept in {out}, interrupted ones keep their finished iterations "
            f"(each run's train.log says where it stopped); continue with: {command}")


def unfinished(runs: list[dict], last: int) -> list[dict]:
    """The runs whose metrics.json has not reached iteration `last` (a run's own "last" if it has one),
    less those used as they are (check_reuse's r["as_is"])."""
    return [r for r in runs if not r.get("as_is") and last_iteration(r["dir"]) < r.get("last", last)]


def plan_lines(runs: list[dict], last: int) -> list[str]:
    """One shell line per unfinished run, for a SLURM job array, GNU parallel or any scheduler:
    `mkdir -p DIR && python .../train.py ARGS --out DIR >> DIR/train.log 2>&1`."""
    q = shlex.quote
    return [f"mkdir -p {q(str(r['dir']))} && {' '.join(map(q, ['python', *run_command(r)[1:]]))} "
            f">> {q(str(r['dir'] / 'train.log'))} 2>&1" for r in unfinished(runs, last)]


def check_ray(address: str | None) -> None:
    """Before anything is written: Ray is installed and, with an address, a Ray cluster answers there
    within RAY_CONNECT_S seconds: HOST:PORT takes a TCP connect, then any address a trial ray.init in
    a child process, killed at the limit (ray.init itself retries an address for minutes).  Else a
    UsageError of one line."""
    try:
        import ray                                            # noqa: F401
    except ImportError:
        raise UsageError("--launcher ray needs Ray: pip install -r requirements-ray.txt")
    if address is None:
        return
    hint = "start the cluster (ray start --head) or name its head's HOST:PORT (port 6379 by default)"
    if address != "auto":
        host, _, port = address.split("://", 1)[-1].rpartition(":")
        if not host or not port.isdigit() or not 0 < int(port) < 65536:
            raise UsageError(f"--ray-address takes HOST:PORT, ray://HOST:PORT or auto, got {address!r}")
        try:
            socket.create_connection((host.strip("[]"), int(port)), timeout=RAY_CONNECT_S / 2).close()
        except OSError as e:
            raise UsageError(f"--ray-address {address}: nothing answers there ({e.strerror or e or type(e).__name__}): {hint}")
    trial = (f"import ray; ray.init(address={address!r}, include_dashboard=False, log_to_driver=False); "
             "ray.shutdown()")
    try:
        done = subprocess.run([sys.executable, "-c", trial], capture_output=True, text=True,
                              stdin=subprocess.DEVNULL, timeout=RAY_CONNECT_S)
    except subprocess.TimeoutExpired:
        raise UsageError(f"--ray-address {address}: no Ray cluster answered within {RAY_CONNECT_S:g} s: {hint}")
    if done.returncode != 0:
        why = ([line for line in done.stderr.splitlines() if line.strip()] or ["no message"])[-1].strip()
        raise UsageError(f"--ray-address {address}: Ray could not connect ({why[:200]}): {hint}")


def ray_results(todo: list[dict], jobs: int, address: str | None):
    """Yield (run, exit status) as Ray tasks finish, one task of one CPU per run's train.py command:
    on the cluster at `address`, else on a local Ray instance of `jobs` CPUs.  The workers must see
    this repository and the sweep folder at the same paths (a shared filesystem); `check_ray` has
    seen the address answer.  Closed early (SIGTERM, Ctrl-C), it cancels the tasks not started,
    asks the running ones to stop their train.py (a STOP_FILE in the run folder, which run_one
    watches: Ray's cancel does not interrupt a waiting task) and waits for them."""
    try:
        import ray
    except ImportError:
        raise UsageError("--launcher ray needs Ray: pip install -r requirements-ray.txt")

    def task(cmd, run_dir):                       # defined here so Ray ships it by value to any worker
        return run_one(cmd, run_dir)

    started = not ray.is_initialized()
    if started:
        main = threading.current_thread() is threading.main_thread()
        handlers = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)} if main else {}
        try:
            ray.init(address=address, num_cpus=None if address else jobs, include_dashboard=False,
                     log_to_driver=False)
        except Exception as e:
            raise UsageError(f"Ray did not start ({type(e).__name__}: {(str(e).strip().splitlines() or [''])[0]})")
        finally:
            for s, handler in handlers.items():        # Ray's own SIGTERM handler would end this process at once
                signal.signal(s, handler)
    remote = ray.remote(num_cpus=1)(task)
    pending = {remote.remote(run_command(r), str(r["dir"])): r for r in todo}
    try:
        while pending:
            [ref], _ = ray.wait(list(pending), num_returns=1)
            yield pending.pop(ref), ray.get(ref)
    except BaseException:              # stopped: cancel what has not started, stop what runs, wait for it
        stops = [r["dir"] / STOP_FILE for r in pending.values()]
        for ref, stop in zip(pending, stops):
            ray.cancel(ref)
            if stop.parent.is_dir():
                stop.touch()
        try:
            ray.wait(list(pending), num_returns=len(pending), timeout=STOP_GRACE_S + 5)
        finally:
            for stop in stops:
                stop.unlink(missing_ok=True)
        raise
    finally:
        if started:
            ray.shutdown()


def local_results(todo: list[dict], jobs: int):
    """Yield (run, exit status) as the runs' train.py processes end, `jobs` at a time; closed early,
    it starts no more (the running ones are stop_runs')."""
    from concurrent.futures import ThreadPoolExecutor, as_completed
    pool = ThreadPoolExecutor(max_workers=jobs)
    try:
        futures = {pool.submit(run_one, run_command(r), str(r["dir"])): r for r in todo}
        for future in as_completed(futures):
            yield futures[future], future.result()
    finally:
        pool.shutdown(wait=False, cancel_futures=True)


def launch_runs(runs: list[dict], last: int, jobs: int, log, what: str, launcher: str = "local",
                ray_address: str | None = None) -> None:
    """Run every unfinished run of a sweep as its own train.py process, continuing interrupted ones
    with --resume: `jobs` at a time as local processes, or as Ray tasks (`ray_results`).  Each
    run's output goes to its train.log, its exit status to r["returncode"].  SIGTERM (as Ctrl-C)
    passes the signal on to the runs, waits for them (`stop_runs`) and raises Interrupted."""
    t0, todo = time.perf_counter(), unfinished(runs, last)
    where = f"on Ray ({ray_address or 'a local instance'})" if launcher == "ray" else f"{jobs} at a time"
    log(f"{what}: {len(runs)} runs, {len(runs) - len(todo)} already finished, {where}")
    STOPPING.clear()
    SIGNALLED.clear()
    main = threading.current_thread() is threading.main_thread()
    before = signal.signal(signal.SIGTERM, raise_interrupted) if main else None
    results = ray_results(todo, jobs, ray_address) if launcher == "ray" else local_results(todo, jobs)
    try:
        for done, (r, code) in enumerate(results, 1):
            r["returncode"] = code
            status = "ok" if code == 0 else f"FAILED (see {r['dir'] / 'train.log'})"
            log(f"run {done}/{len(todo)} {r['dir'].name}: {status}; about "
                f"{(time.perf_counter() - t0) / done * (len(todo) - done):.0f} s left")
    except KeyboardInterrupt as e:                    # Interrupted, train.py's SIGINT/SIGTERM, or Ctrl-C
        signum = getattr(e, "signum", None) or (SIGNALLED[-1] if SIGNALLED else signal.SIGINT)
        stop_runs(signum)                             # the local runs; Ray's stop as their tasks are cancelled
        results.close()
        left = unfinished(runs, last)
        raise Interrupted(signum, len(runs) - len(left), len(runs)) from None
    finally:
        results.close()
        if main:
            signal.signal(signal.SIGTERM, before)


def checked_launch(runs: list[dict], last: int, out: Path, jobs: int, log, what: str, launcher: str,
                   ray_address: str | None, collect: Path | None, accept_other_configs: bool) -> None:
    """Everything a sweep checks before it writes (the run folders' configs, `out`, the Ray address),
    then, unless `collect`, `launch_runs`; a refusal leaves no `out` it made behind."""
    check_reuse(runs, accept_other_configs, collect is not None, log)
    check_writable(out)
    if collect is None and launcher == "ray":
        check_ray(ray_address)
    made = not out.exists()
    out.mkdir(parents=True, exist_ok=True)
    if collect is None:
        try:
            launch_runs(runs, last, jobs, log, what, launcher, ray_address)
        except UsageError:
            if made and not any(out.iterdir()):
                out.rmdir()                                # nothing left behind
            raise


def figure3(out: Path, base: rlil.Config, seeds: int, jobs: int, log=None, panels: str = "abcd",
            launcher: str = "local", ray_address: str | None = None, collect: Path | None = None,
            accept_other_configs: bool = False) -> list[str]:
    """Run (or reuse) every run of the sweep as its own train.py process, then plot and tabulate.

    Each run is a normal run directory under `out`, so a sweep resumes (finished
    runs are reused, interrupted ones continue) and its runs can be spread over
    machines by any scheduler (`plan_lines`) and merged into one folder.  With
    `collect`, nothing runs: the figure, CSV and summary are made from the run
    directories under `collect` that exist, and written to `out`.  A run folder
    whose metrics.json cannot be read, or records another config, is refused
    first (`check_reuse`; `accept_other_configs` uses the latter as they are).
    Returns the runs that failed, are missing, cannot be read, hold a null
    distance or did not finish all `base.iters` iterations, one line each; they
    are named in the summary and on the plot too.
    """
    log = log or rlil.ProgressLog()
    runs = figure3_runs(collect or out, base, seeds, jobs, panels)
    checked_launch(runs, base.iters, out, jobs, log, "figure 3", launcher, ray_address, collect, accept_other_configs)
    problems = [f"({r['panel']}) {r['method']} seed {r['seed']}: {why}" for r in runs
                if (why := run_problem(r, base.iters))]
    rows = figure3_rows(runs)
    write_figure3(out, rows, base.iters, problems, panels)
    summary = summarize_figure3(rows, base.iters, seeds, problems, panels)
    atomic_write(out / "figure3.md", lambda p: Path(p).write_text(summary))
    print(summary)
    log(f"wrote {out / 'figure3.png'}, {out / 'figure3.csv'} and {out / 'figure3.md'}"
        + (f"; {len(problems)} runs missing or failed" if problems else ""))
    return problems


FIGURE3_COLUMNS = ["panel", "train", "demos", "method", "seed", "iteration", "distance_m",
                   "model_progress_m", "sim_progress_m", "seconds", "cpu_capability"]


def figure3_rows(runs: list[dict]) -> list[dict]:
    """The CSV rows (FIGURE3_COLUMNS) of every finished iteration of the runs whose metrics.json can
    be read and holds no null distance; the model's and the simulator's progress over the first T
    steps are empty at iteration 0 (no model yet)."""
    rows = []
    for r in runs:
        saved, _ = read_metrics(r["dir"])
        if saved is None or null_figure(saved):
            continue
        cpu = (saved["config"].get("versions") or {}).get("cpu_capability")    # None before it was recorded
        rows += [{"panel": r["panel"], "train": r["train"], "demos": r["demos"], "method": r["method"],
                  "seed": r["seed"], "iteration": m["iteration"], "distance_m": m["distance_m"],
                  "model_progress_m": m.get("model_progress_m"), "sim_progress_m": m.get("sim_progress_m"),
                  "seconds": m.get("seconds"), "cpu_capability": cpu}
                 for m in saved["iterations"]]
    return rows


def panel_curves(rows: list[dict], panel: str, iters: int):
    """One panel's curves: runs (method -> seed -> iteration -> distance), gaps (method ->
    iteration -> [|model - simulator progress| per seed]), the mean curve per method, and the
    convergence threshold: 90 % of the best mean at iteration `iters` of either method."""
    runs, gaps = {}, {}
    for r in rows:
        if r["panel"] == panel:
            runs.setdefault(r["method"], {}).setdefault(r["seed"], {})[r["iteration"]] = r["distance_m"]
            if r.get("model_progress_m") is not None and r.get("sim_progress_m") is not None:
                gaps.setdefault(r["method"], {}).setdefault(r["iteration"], []).append(
                    abs(r["model_progress_m"] - r["sim_progress_m"]))
    mean = {m: {i: np.mean([c[i] for c in curves.values() if i in c])
                for i in range(iters + 1) if any(i in c for c in curves.values())}
            for m, curves in runs.items()}
    finals = [curve[iters] for curve in mean.values() if iters in curve]
    return runs, gaps, mean, 0.9 * max(finals) if finals else float("inf")


def per_run(curves: tuple, iters: int) -> dict:
    """method -> {"converge": [iterations to converge per finished run], "auc": [...], "final": [...]},
    from one panel's `panel_curves` (its runs and its convergence threshold)."""
    runs, _, _, threshold = curves
    out = {}
    for method, curves in runs.items():
        done = [c for c in curves.values() if area_under_curve(c, iters) is not None]
        out[method] = {"converge": [iterations_to_converge(c, threshold, iters) for c in done],
                       "auc": [area_under_curve(c, iters) for c in done], "final": [c[iters] for c in done]}
    return out



def provenance(rows: list[dict]) -> str:
    """One line: how many runs, on which CPU capabilities, and their summed time."""
    cpus, seconds = {}, 0.0
    for r in rows:
        if r["iteration"] == 0:
            cpus[r.get("cpu_capability") or "not recorded"] = cpus.get(r.get("cpu_capability") or "not recorded", 0) + 1
        seconds += r.get("seconds") or 0.0
    where = ", ".join(f"{n} with CPU capability {cpu}" for cpu, n in sorted(cpus.items()))
    return (f"{sum(cpus.values())} runs ({where}, as torch reports it; one torch thread each); "
            f"their iterations took {seconds / 3600:.1f} h of one core in all.")


def summarize_figure3(rows: list[dict], iters: int, seeds: int, problems: list[str] = (), panels: str = "abcd") -> str:
    """Markdown: the runs' provenance, then per panel and method: iterations to converge (per seed
    and their median with its 95 % bootstrap CI), the area under the curve and the final distance
    (mean with CI), the final min-max, the largest drop of a seed, and model exploitation.

    Converged = the first iteration whose distance reaches 90 % of the best mean
    at iteration `iters` of either method in that panel; a seed that never does
    is counted at iters + 1 ("never") in the median.  Area under the curve = a
    run's mean distance over iterations 1..iters.  Largest drop = the largest
    fall of one seed from one iteration to the next after iteration 1 (negative
    when every seed only rises).  Exploitation = the largest, over iterations
    >= 1, of the mean over seeds of |model_progress_m - sim_progress_m| (the
    first T steps).  Statistics are over the seeds that finished.
    """
    lines = [provenance(rows), "",
             "| panel | method | seeds | iterations to converge, per seed | median [95 % CI] "
             "| area under the curve (m) [95 % CI] | final (m) [95 % CI] | final min-max (m) "
             "| largest drop after it. 1 (m) | exploitation (m) |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    fmt = lambda i: "never" if i == iters + 1 else str(i)             # noqa: E731
    for panel, (design, demos) in PANELS.items():
        if panel not in panels:
            continue
        curves = panel_curves(rows, panel, iters)
        runs, gaps, _, _ = curves
        stats = per_run(curves, iters)
        for method in ("RL+IL", "RL"):
            head = f"| ({panel}) {design} ({' + '.join(demos)} demos) | {method} |"
            st = stats.get(method)
            if not st or not st["final"]:
                lines.append(f"{head} 0 of {seeds} | no run finished | | | | | | |")
                continue
            drops = [c[i] - c[i + 1] for c in runs[method].values() for i in range(1, iters) if i + 1 in c]
            gap = max((np.mean(v) for v in gaps.get(method, {}).values()), default=float("nan"))
            lines.append(f"{head} {len(st['final'])} of {seeds} | {', '.join(map(fmt, st['converge']))} "
                         f"| {np.median(st['converge']):g} {interval(bootstrap_ci(st['converge'], np.median))} "
                         f"| {np.mean(st['auc']):.2f} {interval(bootstrap_ci(st['auc']))} "
                         f"| {np.mean(st['final']):.2f} {interval(bootstrap_ci(st['final']))} "
                         f"| {min(st['final']):.2f} - {max(st['final']):.2f} "
                         f"| {max(drops, default=0.0):.2f} | {gap:.2f} |")
    if problems:
        lines += ["", "Missing or failed runs (left out of the statistics above):"] + [f"- {p}" for p in problems]
    return "\n".join(lines) + "\n"


def write_rows_csv(path: Path, columns: list[str], rows: list[dict]) -> None:
    """A CSV with a header row of `columns` and one line per dict, written atomically."""
    def write(p):
        with open(p, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=columns)
            w.writeheader()
            w.writerows(rows)
    atomic_write(path, write)


def save_sweep_plot(fig, path: Path, problems: list[str]) -> None:
    """Save a sweep's figure atomically (missing or failed runs named along its foot) and close it."""
    import matplotlib.pyplot as plt
    if problems:
        fig.text(0.01, 0.01, "missing or failed: " + "; ".join(p.split(" (")[0] for p in problems),
                 fontsize=8, color="tab:red", wrap=True)
    fig.tight_layout(rect=(0, 0.04 * bool(problems), 1, 1))
    atomic_write(path, lambda p: fig.savefig(p, format="png"))
    plt.close(fig)


def write_figure3(out: Path, rows: list[dict], iters: int, problems: list[str] = (), panels: str = "abcd") -> None:
    """figure3.csv and figure3.png: the mean over seeds as a line, its 95 % bootstrap CI as a band,
    min and max over seeds as dotted lines."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    write_rows_csv(out / "figure3.csv", FIGURE3_COLUMNS, rows)
    shown = [(p, v) for p, v in PANELS.items() if p in panels]
    narrow = len(shown) < 3                                   # the title then takes two lines
    fig, axes = plt.subplots(1, len(shown), figsize=(max(4 * len(shown), 8), 3.8 + 0.18 * (len(problems) + narrow)),
                             dpi=100, sharey=True, squeeze=False)
    axes = axes[0]
    for ax, (panel, (design, demos)) in zip(axes, shown):
        for method, colour in (("RL+IL", "tab:blue"), ("RL", "tab:red")):
            table = {}
            for row in rows:
                if row["panel"] == panel and row["method"] == method:
                    table.setdefault(row["iteration"], []).append(row["distance_m"])
            if not table:
                continue
            it = sorted(table)
            counts = sorted({len(table[i]) for i in it})
            seeds = f"{counts[0]}" if len(counts) == 1 else f"{counts[0]}-{counts[-1]}"
            ax.plot(it, [np.mean(table[i]) for i in it], "o-", color=colour, label=f"{method} ({seeds} seeds)")
            band = [bootstrap_ci(table[i]) for i in it]                              # 95 % CI of the mean
            ax.fill_between(it, [lo for lo, _ in band], [hi for _, hi in band], color=colour, alpha=0.25)
            for edge in (min, max):                                                   # min-max over seeds
                ax.plot(it, [edge(table[i]) for i in it], ":", color=colour, lw=1)
        ax.set_title(f"({panel}) {design}, demos: {' + '.join(demos)}", fontsize=10)
        ax.set_xlabel("iteration")
        ax.set_xticks(range(iters + 1))
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="lower right")
    axes[0].set_ylabel("distance in 200 steps (m)")
    fig.suptitle(f"mean over seeds, its 95 % bootstrap interval (band) and min-max (dotted)"
                 f"{chr(10) if narrow else '; '}{provenance(rows)}", fontsize=8, wrap=True)
    save_sweep_plot(fig, out / "figure3.png", problems)


# ----------------------------------------------------------------------------
# Sample efficiency (not in the paper): Algorithm 1 against PPO per simulator step and per second
# ----------------------------------------------------------------------------
SAMPLE_EFFICIENCY = {"hexapod": PANELS["a"][1], "leg_none_wheel": PANELS["d"][1]}   # design: Figure 3's demos
SAMPLE_METHODS = ("RL+IL", "RL", "PPO", "PPO+IL")     # PPO+IL: PPO with the same demos (issue #24)
SB3_METHOD = "SB3 PPO"   # Stable-Baselines3's PPO (interfaces/sb3_ppo.py): not launched here, its CSVs collected
THRESHOLDS_M = (5.0, 10.0, 15.0)
SAMPLE_COLUMNS = ["train", "method", "seed", "iteration", "sim_steps", "seconds", "distance_m"]


def sample_efficiency_runs(out: Path, base: rlil.Config, base_ppo: ppo_lib.PPOConfig, seeds: int,
                           jobs: int) -> list[dict]:
    """One entry per run: hexapod and leg_none_wheel x SAMPLE_METHODS x seeds, with `base`'s and
    `base_ppo`'s budgets (the demos: Figure 3's for the design, for RL+IL and PPO+IL); one torch
    thread per run when several run at once."""
    runs = []
    for design, demos in SAMPLE_EFFICIENCY.items():
        code = (sim2d.parse_design(design),)
        for method in SAMPLE_METHODS:
            with_demos = tuple(sim2d.parse_design(d) for d in demos) if method.endswith("+IL") else ()
            ppo = method.startswith("PPO")
            for seed in range(seeds):
                cfg = dataclasses.replace(base_ppo if ppo else base, train=code, seed=seed, demos=with_demos,
                                          threads=1 if jobs > 1 else (base_ppo if ppo else base).threads)
                last = ppo_lib.iterations(cfg) if ppo else cfg.iters
                runs.append({"train": design, "method": method, "seed": seed, "dir": out / run_name(cfg),
                             "args": config_args(cfg), "cfg": cfg, "last": last})
    return runs


SAMPLE_FIGURES = (("distance_m", "seconds"), ("sim_steps",))   # needed in every row; needed where a row has it


def sample_efficiency_rows(runs: list[dict]) -> list[dict]:
    """The CSV rows (SAMPLE_COLUMNS) of every recorded evaluation of the runs whose metrics.json can
    be read and holds no null figure; seconds are cumulative."""
    rows = []
    for r in runs:
        saved, _ = read_metrics(r["dir"])
        if saved is None or null_figure(saved, *SAMPLE_FIGURES):
            continue
        cfg, seconds = saved["cfg"], 0.0
        for m in saved["iterations"]:
            seconds += m["seconds"]
            steps = m["sim_steps"] if "sim_steps" in m else rlil.sim_steps(cfg, m["iteration"])   # runs before sim_steps
            rows.append({"train": r["train"], "method": r["method"], "seed": r["seed"], "iteration": m["iteration"],
                         "sim_steps": steps, "seconds": seconds, "distance_m": m["distance_m"]})
    return rows


def sb3_rows(folder: Path) -> list[dict]:
    """The CSV rows (SAMPLE_COLUMNS, method SB3_METHOD) of every `interfaces/sb3_ppo.py --out
    folder/<design>-seed<S>.csv` there (none when the folder does not exist): one row per
    evaluation, its steps the simulator steps; its seconds exclude the evaluations."""
    rows = []
    for path in sorted(Path(folder).glob("*-seed*.csv")):
        design, seed = path.stem.rsplit("-seed", 1)
        with open(path, newline="") as f:
            for i, r in enumerate(csv.DictReader(f)):
                rows.append({"train": design, "method": SB3_METHOD, "seed": int(seed), "iteration": i,
                             "sim_steps": int(r["steps"]), "seconds": float(r["seconds"]),
                             "distance_m": float(r["distance_m"])})
    return rows


def mean_curve(rows: list[dict], design: str, method: str) -> list[tuple]:
    """[(sim_steps, mean seconds, [distance per seed]) per iteration] of one design and method;
    every seed evaluates at the same iterations and simulator steps.  Only iterations that every
    seed reached count: runs stopped after a time (experiments/side_by_side.py) end at different
    iterations, and a mean over fewer seeds is not the curve's."""
    table = {}
    for row in rows:
        if row["train"] == design and row["method"] == method:
            table.setdefault(row["iteration"], []).append(row)
    seeds = max(map(len, table.values()), default=0)
    return [(np.mean([r["sim_steps"] for r in table[i]]), np.mean([r["seconds"] for r in table[i]]),
             [r["distance_m"] for r in table[i]]) for i in sorted(table) if len(table[i]) == seeds]


def summarize_sample_efficiency(rows: list[dict], seeds: int, problems: list[str] = (),
                                designs=tuple(SAMPLE_EFFICIENCY), methods=None) -> str:
    """Markdown: per design and method, the simulator steps and seconds at which the mean over seeds
    first reaches each of THRESHOLDS_M in 200 steps, and where each ends.  methods: by default
    SAMPLE_METHODS, and SB3_METHOD where the rows hold it."""
    if methods is None:
        methods = SAMPLE_METHODS + ((SB3_METHOD,) if any(r["method"] == SB3_METHOD for r in rows) else ())
    head = " | ".join(f"{t:g} m: steps | {t:g} m: seconds" for t in THRESHOLDS_M)
    lines = [f"| design | method | seeds | {head} | final steps | final seconds | final mean (m) | final min-max (m) |",
             "|---|---|---|" + "---|" * (2 * len(THRESHOLDS_M) + 4)]
    for design in designs:
        for method in methods:
            curve = mean_curve(rows, design, method)
            if not curve:
                lines.append(f"| {design} | {method} | 0 of {seeds} |" + " |" * (2 * len(THRESHOLDS_M) + 4))
                continue
            cells = []
            for t in THRESHOLDS_M:
                hit = next(((s, sec) for s, sec, d in curve if np.mean(d) >= t), None)
                cells += [f"{hit[0]:,.0f}", f"{hit[1]:.0f}"] if hit else ["not reached", ""]
            steps, seconds, final = curve[-1]
            lines.append(f"| {design} | {method} | {len(final)} of {seeds} | {' | '.join(cells)} | {steps:,.0f} | "
                         f"{seconds:.0f} | {np.mean(final):.2f} | {min(final):.2f} - {max(final):.2f} |")
    if problems:
        lines += ["", "Missing or failed runs (left out of the means above):"] + [f"- {p}" for p in problems]
    return "\n".join(lines) + "\n"


def write_sample_efficiency(out: Path, rows: list[dict], problems: list[str] = ()) -> None:
    """sample_efficiency.csv and .png: per design, distance against simulator steps and against
    seconds (both log axes; the untrained PPO policy at 0 steps is left off), mean over seeds as a
    line, min-max as a band, the summary's thresholds as dotted lines."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib import ticker

    write_rows_csv(out / "sample_efficiency.csv", SAMPLE_COLUMNS, rows)
    fig, axes = plt.subplots(len(SAMPLE_EFFICIENCY), 2, figsize=(13, 3.8 * len(SAMPLE_EFFICIENCY)), dpi=100,
                             sharey="row", squeeze=False)
    for row_axes, (design, demos) in zip(axes, SAMPLE_EFFICIENCY.items()):
        for method, colour in COLOURS.items():
            curve = [c for c in mean_curve(rows, design, method) if c[0] > 0]
            if not curve:
                continue
            n = len(curve[-1][2])
            label = (f"{method}" + (f" ({' + '.join(demos)} demos)" if method.endswith("+IL") else "")
                     + f", {n} seed{'s' * (n > 1)}")
            for ax, k in zip(row_axes, (0, 1)):
                x = [c[k] for c in curve]
                ax.plot(x, [np.mean(c[2]) for c in curve], "o-", ms=3, color=colour, label=label)
                ax.fill_between(x, [min(c[2]) for c in curve], [max(c[2]) for c in curve], color=colour, alpha=0.2)
        for ax, xlabel, unit in zip(row_axes, ("simulator steps (evaluation excluded)",
                                               "wall-clock seconds (one thread, evaluation included)"), ("", " s")):
            ax.set_xscale("log")
            ax.xaxis.set_major_formatter(ticker.FuncFormatter(                 # 1,000 and 100 s, not 10^3
                lambda v, _, u=unit: f"{v:,.0f}{u}" if v >= 1 else f"{v:g}{u}"))
            ax.xaxis.set_minor_formatter(ticker.NullFormatter())
            for t in THRESHOLDS_M:                # the summary table's thresholds
                ax.axhline(t, color="grey", lw=0.8, ls=":")
            ax.set_xlabel(xlabel)
            ax.set_title(design, fontsize=10)
            ax.grid(alpha=0.3, which="both")
        row_axes[0].set_ylabel("distance in 200 steps (m)")
        row_axes[1].legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.02, 1))    # beside the row
    save_sweep_plot(fig, out / "sample_efficiency.png", problems)


def sample_efficiency(out: Path, base: rlil.Config, base_ppo: ppo_lib.PPOConfig, seeds: int, jobs: int,
                      log=None, launcher: str = "local", ray_address: str | None = None,
                      collect: Path | None = None, accept_other_configs: bool = False) -> list[str]:
    """Run (or reuse) every run as its own train.py process (or, with `collect`, only read the run
    directories under `collect`), then plot, tabulate and summarise (sample_efficiency.png, .csv,
    .md in `out`), with the SB3 PPO runs whose CSVs are in its sb3_ppo_runs/ (sb3_rows).  Run
    folders are checked first as in `figure3`.  Returns the runs that failed, are missing, cannot be
    read, hold a null figure or did not finish."""
    log = log or rlil.ProgressLog()
    runs = sample_efficiency_runs(collect or out, base, base_ppo, seeds, jobs)
    checked_launch(runs, 0, out, jobs, log, "sample efficiency", launcher, ray_address, collect, accept_other_configs)
    problems = [f"{r['train']} {r['method']} seed {r['seed']}: {why}" for r in runs
                if (why := run_problem(r, r["last"], *SAMPLE_FIGURES))]
    rows = sample_efficiency_rows(runs) + sb3_rows((collect or out) / "sb3_ppo_runs")
    write_sample_efficiency(out, rows, problems)
    summary = summarize_sample_efficiency(rows, seeds, problems)
    atomic_write(out / "sample_efficiency.md", lambda p: Path(p).write_text(summary))
    print(summary)
    log(f"wrote {out / 'sample_efficiency.png'}, .csv and .md" + (f"; {len(problems)} runs missing or failed"
                                                                   if problems else ""))
    return problems


# ----------------------------------------------------------------------------
# What is committed of a sweep: each finished run's metrics.json
# ----------------------------------------------------------------------------
def replacing(target: Path, new: dict) -> str | None:
    """Why the metrics.json at `target` must not be replaced by `new` (read_metrics' dict) without
    --force, in words: it cannot be read, it records another config (config_difference: a larger
    budget in `new` is a continuation), or it has more iterations; None when it may."""
    old, why = read_metrics(target.parent)
    if why:
        return f"exists and {why}"
    diff = config_difference(old["cfg"], new["cfg"])
    if diff:
        return f"holds a run made with {settings(diff, 1)}, the new one has {settings(diff, 2)}"
    if len(new["iterations"]) < len(old["iterations"]):
        return f"holds {len(old['iterations'])} iterations, the new one only {len(new['iterations'])}"
    return None


def keep_metrics(src: Path, dest: Path, force: bool = False) -> list[str]:
    """Copy the metrics.json of every finished run directory under `src` (its last row at the
    iteration its config asks for: Algorithm 1's iters, PPO's `ppo_minimal.iterations`) to
    dest/<run name>/metrics.json, the small per-run results a sweep is committed as; `--collect
    dest` rebuilds the figure from them, and copied into a sweep folder they count as finished
    runs.  Everything is checked before anything is copied: a metrics.json of `src` that cannot be
    read, or one in `dest` it would replace that holds another config or more iterations (unless
    `force`, `replacing`), is a UsageError of one line and nothing is copied.  Returns the run
    names copied."""
    src, dest = Path(src), Path(dest)
    if dest.exists() and not dest.is_dir():
        raise UsageError(f"--keep-metrics: {dest} is a file: name a folder (new or existing) for the runs' metrics.json")
    todo = []
    for path in sorted(src.glob("*/metrics.json")):
        saved, why = read_metrics(path.parent)
        if why:
            raise UsageError(f"{path} {why}: nothing was kept (move that run away, or repair the file)")
        cfg = saved["cfg"]
        if saved["iterations"][-1]["iteration"] < (ppo_lib.iterations(cfg) if is_ppo(cfg) else cfg.iters):
            continue                                            # unfinished
        target = dest / path.parent.name / "metrics.json"
        if target.parent.exists() and not target.parent.is_dir():
            raise UsageError(f"{target.parent} is a file, not a run folder: nothing was kept")
        why = None if force or not target.exists() else replacing(target, saved)
        if why:
            raise UsageError(f"{target} {why}: not replaced, nothing was kept (--force replaces it)")
        todo.append((path, target))
    try:
        for path, target in todo:
            target.parent.mkdir(parents=True, exist_ok=True)
            atomic_write(target, lambda p, t=path.read_text(): Path(p).write_text(t))
    except OSError as e:
        raise UsageError(f"cannot write {dest} ({e.strerror or type(e).__name__}): name a folder you can write")
    return [path.parent.name for path, _ in todo]


def main(argv=None) -> int:
    parser = sim2d.CliParser(description="Keep what is committed of a sweep (the sweeps themselves run with "
                             "train.py --figure3 or --sample-efficiency).")
    parser.add_argument("--keep-metrics", nargs=2, metavar=("SWEEP_DIR", "DEST"), required=True,
                        help="copy the metrics.json of every finished run (Algorithm 1 or PPO) in SWEEP_DIR to "
                             "DEST/<run name>/; a DEST run's metrics.json of another config or with more "
                             "iterations is not replaced")
    parser.add_argument("--force", action="store_true", help="replace DEST runs' metrics.json whatever they hold")
    args = parser.parse_args(argv)
    src, dest = map(Path, args.keep_metrics)
    if not src.is_dir():
        parser.error(f"--keep-metrics: {src} is not a folder of run directories")
    try:
        kept = keep_metrics(src, dest, args.force)
    except UsageError as e:
        parser.error(str(e))
    print(f"kept {len(kept)} finished runs' metrics.json in {dest}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
