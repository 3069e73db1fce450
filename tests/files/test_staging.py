"""Temporary output folders: a killed writer's is removed by the next run, a live
writer's is not."""

from pathlib import Path

from photo3d.files.staging import stage_output


def test_a_killed_writers_folder_is_removed_by_the_next_run(tmp_path, monkeypatch):
    # issue 45: a SIGKILLed make left its hidden .OUT.*.tmp folder, and no later run
    # removed it; a live writer's folder is left alone
    import signal
    import subprocess
    import sys

    from photo3d.files import temps

    out = tmp_path / "out"
    code = ("import os, signal, sys; from photo3d.files.staging import stage_output; "
            "s = stage_output(sys.argv[1]); (s.path / 'part.bin').write_bytes(b'x'); "
            "print(s.path, flush=True); {end}")
    killed = subprocess.run([sys.executable, "-c", code.format(
        end="os.kill(os.getpid(), signal.SIGKILL)"), str(out)], capture_output=True, text=True)
    assert killed.returncode == -signal.SIGKILL
    left = Path(killed.stdout.strip())
    live = subprocess.Popen([sys.executable, "-c", code.format(end="sys.stdin.read()"),
                             str(out)], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            text=True)
    try:
        held = Path(live.stdout.readline().strip())
        assert left.is_dir() and held.is_dir()
        monkeypatch.setattr(temps, "ORPHAN_AGE_S", 0.0)
        with stage_output(out) as mine:
            assert not left.exists()  # its writer is gone
            assert held.is_dir()  # its writer is alive
            mine.commit()
    finally:
        live.communicate("")
    assert out.is_dir() and list(out.iterdir()) == []  # no writer mark left in it


def test_a_killed_writers_temporary_file_is_removed_by_the_next_write(tmp_path, monkeypatch):
    # issue 45: a SIGKILL during `export` left a hidden temporary file nothing removed
    import signal
    import subprocess
    import sys

    from photo3d.files import atomic, temps

    target = tmp_path / "splats.spz"
    code = ("import os, signal, sys; from photo3d.files.atomic import PendingFile; "
            "p = PendingFile(sys.argv[1]); p.path.write_bytes(b'half'); print(p.path, "
            "flush=True); os.kill(os.getpid(), signal.SIGKILL)")
    killed = subprocess.run([sys.executable, "-c", code, str(target)], capture_output=True,
                            text=True)
    left = Path(killed.stdout.strip())
    assert killed.returncode == -signal.SIGKILL and left.is_file()
    monkeypatch.setattr(temps, "ORPHAN_AGE_S", 0.0)
    atomic.write_bytes(target, b"whole")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["splats.spz"]
