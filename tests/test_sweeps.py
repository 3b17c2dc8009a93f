"""Tests of the results tables (sweeps.py --tables): no committed table is typed by hand.

The committed results/*.md and every README.md / docs/*.md block between
`<!-- begin: results/NAME.md -->` and `<!-- end: results/NAME.md -->` must be
what the tables command makes from the committed CSVs, and a changed CSV must
change them (so the check can fail).  The sweeps themselves are tested in
test_rlil.py (Figure 3) and test_ppo.py (sample efficiency).
"""
import csv
import shutil

import pytest

import sweeps
import train


def test_committed_tables_and_readme_blocks_are_the_regenerated_ones():
    """What `python sweeps.py --tables --check` checks, in-process: nothing differs."""
    assert sweeps.tables(sweeps.ROOT, check=True) == []
    readme = (sweeps.ROOT / "README.md").read_text()
    assert sweeps.BEGIN.format("figure3") in readme                  # the check covers a README block


def copy_of_repo(tmp_path):
    """results/*.csv and *.md, README.md and docs/ (if any) under tmp_path."""
    (tmp_path / "results").mkdir()
    for p in [*sweeps.ROOT.glob("results/*.csv"), *sweeps.ROOT.glob("results/*.md")]:
        shutil.copy(p, tmp_path / "results" / p.name)
    shutil.copy(sweeps.ROOT / "README.md", tmp_path / "README.md")
    if (sweeps.ROOT / "docs").exists():
        shutil.copytree(sweeps.ROOT / "docs", tmp_path / "docs")
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
    stale = sweeps.tables(root, check=True)
    assert set(stale) >= set(before)                                 # and the other tables made from it
    assert all(p.read_text() == text for p, text in before.items())     # --check writes nothing
    monkeypatch.setattr(sweeps, "ROOT", root)
    assert sweeps.main(["--tables", "--check"]) == 1
    assert "differs: README.md" in capsys.readouterr().out

    assert sweeps.main(["--tables"]) == 0
    table = (root / "results" / "figure3.md").read_text()
    assert table != before[root / "results" / "figure3.md"] and "99.00" in table      # its final max
    assert "99.00]" in (root / "results" / "figure3_iterations.md").read_text()           # its max at iteration 5
    readme = (root / "README.md").read_text()
    begin, end = sweeps.BEGIN.format("figure3"), sweeps.END.format("figure3")
    assert readme.split(begin + "\n")[1].split(end)[0] == table      # the block is the new table
    assert sweeps.tables(root, check=True) == []
    assert sweeps.main(["--tables", "--check"]) == 0


def test_class_demo_csv_gets_its_per_iteration_table_and_a_missing_one_is_skipped(tmp_path):
    root = copy_of_repo(tmp_path)
    (root / "results" / "class_demo.csv").unlink(missing_ok=True)
    (root / "results" / "class_demo.md").unlink(missing_ok=True)
    (root / "README.md").write_text("no blocks\n")
    assert sweeps.tables(root) == []                                 # no class_demo.csv: nothing to make
    assert not (root / "results" / "class_demo.md").exists()
    rows = [{"panel": "a", "train": "car", "demos": "", "method": "RL", "seed": s, "iteration": i,
             "distance_m": 1.0 + i + s} for s in (0, 1) for i in (0, 1)]
    sweeps.write_rows_csv(root / "results" / "class_demo.csv", sweeps.FIGURE3_COLUMNS, rows)
    assert sweeps.tables(root) == [root / "results" / "class_demo.md"]
    assert (root / "results" / "class_demo.md").read_text().splitlines()[2:] == [
        "| (a) car | RL | 2 | 1.50 [1.00, 2.00] | 2.50 [2.00, 3.00] |"]


def test_a_block_naming_a_missing_table_is_a_one_line_error_exit_2(tmp_path, monkeypatch, capsys):
    root = copy_of_repo(tmp_path)
    readme = root / "README.md"
    readme.write_text(readme.read_text() + "\n" + sweeps.BEGIN.format("nothing") + "\nold\n"
                      + sweeps.END.format("nothing") + "\n")
    with pytest.raises(train.UsageError):
        sweeps.tables(root, check=True)
    monkeypatch.setattr(sweeps, "ROOT", root)
    with pytest.raises(SystemExit) as e:
        sweeps.main(["--tables"])
    err = capsys.readouterr().err
    assert e.value.code == 2 and len(err.strip().splitlines()) == 1 and "results/nothing.md" in err
    assert "old" in readme.read_text()                               # nothing was written
