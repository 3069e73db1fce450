"""``photo3d eval`` without ``-o``: every run gets its own results folder (``out/eval``,
``out/eval-2``, ...), says which, and replaces nothing (issue 36, item 13; the second
run failed with "results folder out/eval exists" before)."""

from __future__ import annotations

from pathlib import Path

from photo3d.cli import main

QUICK = ["eval", "--synthetic", "1", "--methods", "forward-warp", "--no-lpips"]


def test_each_run_gets_its_own_folder_and_says_which(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(QUICK) == 0
    first = Path("out/eval/results.json")
    before = first.stat().st_mtime_ns, first.read_bytes()
    assert "results folder: out/eval\n" in capsys.readouterr().err
    assert main(QUICK) == 0, capsys.readouterr().err
    printed = capsys.readouterr()
    assert "results folder: out/eval-2\n" in printed.err
    assert "written: out/eval-2/results.json" in printed.out
    assert (first.stat().st_mtime_ns, first.read_bytes()) == before
    assert sorted(p.name for p in Path("out/eval-2").iterdir()) == [
        "grid_synthetic0.png", "results.json", "results.md"]


def test_a_failed_run_removes_only_the_folders_it_created(tmp_path, capsys, monkeypatch):
    def fails(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr("photo3d.eval.report.run", fails)
    assert main(QUICK) == 130
    assert list(tmp_path.iterdir()) == []  # out/ and out/eval were this run's: both gone
    (tmp_path / "out" / "eval").mkdir(parents=True)
    (tmp_path / "out" / "eval" / "notes.txt").write_text("mine")
    assert main([*QUICK, "-q"]) == 130
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["eval"]
    assert (tmp_path / "out" / "eval" / "notes.txt").read_text() == "mine"
    capsys.readouterr()
