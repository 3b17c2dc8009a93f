"""The house in layers: every module imports only from the layers below it, and nothing closes a circle.

    world        sim2d
    stages       demos, gnn
    algorithms   modular_rlil_minimal, ppo_minimal
    interfaces   interfaces/gymnasium_env, interfaces/sb3_ppo (gymnasium and SB3 over the world)
    shared       experiments/stats, experiments/run_folders
    experiments  experiments/sweeps, experiments/transfer, experiments/tables, tools/*
    command      train
    lesson       lesson/grade, lesson/lesson, lesson/exercises/* (the class: they import the stages; nothing imports them)

Imports are read from the source (ast), function-level ones included, so a
stage file that forwards to a tool inside a function is caught too.  Modules of
one layer may import each other as long as no circle forms.
"""
import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
LAYERS = [
    ["sim2d"],
    ["demos", "gnn"],
    ["modular_rlil_minimal", "ppo_minimal"],
    ["interfaces.gymnasium_env", "interfaces.sb3_ppo"],
    ["experiments.stats", "experiments.run_folders"],
    ["experiments.sweeps", "experiments.transfer", "experiments.tables", "experiments.diagnosis",
     "experiments.gradient_check", "experiments.side_by_side", "experiments.model_replay", "experiments.flattery_curve",
     "experiments.clone_flips", "experiments.phase_probe",
     "tools.bench", "tools.check_physics", "tools.mutations"],
    ["train"],
    ["lesson.grade", "lesson.lesson", "lesson.exercises.ex1_reward", "lesson.exercises.ex2_message_passing",
     "lesson.exercises.ex3_rl_loss", "lesson.exercises.ex4_il_loss", "lesson.exercises.ex5_adaptive_lr",
     "lesson.exercises.ex6_experiment"],
]
LAYER = {module: k for k, modules in enumerate(LAYERS) for module in modules}
PACKAGES = {"experiments", "interfaces", "tools", "lesson", "lesson/exercises"}   # folders of modules, each a package


def module_name(path: Path, root: Path) -> str:
    return ".".join(path.relative_to(root).with_suffix("").parts)


def project_modules(root: Path) -> list[Path]:
    """Every Python file of the project but the tests and the packages' faces (__init__.py)."""
    return sorted(p for p in [*root.glob("*.py"), *[q for d in PACKAGES for q in (root / d).glob("*.py")]]
                  if p.name not in ("__init__.py", "conftest.py"))


def imports(path: Path, known: set[str]) -> set[str]:
    """The project modules that `path` imports, wherever in the file the import stands."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found |= {node.module} | {f"{node.module}.{a.name}" for a in node.names}
    return found & known


def import_graph(root: Path) -> dict[str, set[str]]:
    paths = {module_name(p, root): p for p in project_modules(root)}
    return {m: imports(p, set(paths)) - {m} for m, p in paths.items()}


def upward_imports(graph: dict[str, set[str]]) -> list[str]:
    """'a -> b' for each import from a lower layer to a higher one (an unlayered module is an error too)."""
    bad = [f"{m} is in no layer (add it to LAYERS)" for m in graph if m not in LAYER]
    bad += [f"{m} -> {n}" for m, deps in graph.items() for n in sorted(deps)
            if m in LAYER and n in LAYER and LAYER[n] > LAYER[m]]
    return bad


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Every circle of imports found by a depth-first walk, as the list of modules around it."""
    found, state = [], {}                               # state: 1 on the walk's path, 2 done

    def walk(m, path):
        state[m] = 1
        for n in sorted(graph.get(m, ())):
            if state.get(n) == 1:
                found.append(path[path.index(n):] + [n])
            elif n not in state:
                walk(n, path + [n])
        state[m] = 2
    for m in sorted(graph):
        if m not in state:
            walk(m, [m])
    return found


def test_no_import_points_up_and_none_closes_a_circle():
    graph = import_graph(ROOT)
    assert {"sim2d", "train", "experiments.sweeps", "tools.bench", "interfaces.sb3_ppo"} <= set(graph)
    assert upward_imports(graph) == []
    assert circles(graph) == []


def test_the_top_level_holds_the_stage_files_and_train_py_only():
    assert sorted(p.name for p in ROOT.glob("*.py")) == [
        "conftest.py", "demos.py", "gnn.py", "modular_rlil_minimal.py", "ppo_minimal.py", "sim2d.py", "train.py"]


@pytest.mark.parametrize("stage, line", [("gnn.py", "import train"),
                                         ("sim2d.py", "    from tools import bench"),
                                         ("experiments/run_folders.py", "from experiments import sweeps")])
def test_the_check_fails_on_a_stage_file_that_imports_a_tool(tmp_path, stage, line):
    """The same check on a copy with one import added that points up (the last also closes a circle)."""
    for p in project_modules(ROOT):
        dest = tmp_path / p.relative_to(ROOT)
        dest.parent.mkdir(parents=True, exist_ok=True)
        dest.write_text(p.read_text() + ("\n\ndef _up():\n" if line.startswith(" ") else "\n") + line + "\n")
        if dest.relative_to(tmp_path).as_posix() != stage:
            dest.write_text(p.read_text())
    graph = import_graph(tmp_path)
    assert upward_imports(graph), stage
    if stage.startswith("experiments"):
        assert circles(graph)


def test_every_mutation_of_the_table_still_finds_its_one_line():
    """tools/mutations.py breaks a line by text: an edit elsewhere that repeats the text, or one that
    changes it, leaves the mutation 'NOT APPLIED' and its test unchecked until the next full run.
    This reads the files only, so it fails at once (a comment quoting `LEVEL = 0.95` once did it)."""
    from tools.mutations import MUTATIONS
    for what, file, old, _new, test in MUTATIONS:
        count = (ROOT / file).read_text().count(old)
        assert count == 1, f"{what!r}: its line occurs {count} times in {file}"
        assert (ROOT / test.split("::")[0]).is_file(), test
