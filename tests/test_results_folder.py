"""Results folders are complete or absent, and one run writes them at a time
(issue 16, items 13 and 14): interrupted runs (an exception mid-write, a full
disk, a killed process) leave the folder absent or the earlier results
intact, a rerun needs no --force, resumable state survives in the staging
folder, and a second run into a busy folder stops with one line."""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from photogram.errors import InputError
from photogram.project import atomic, read_results
from photogram.project.output_policy import claim_output
from photogram.project.results_folder import (
    INCOMPLETE, MANIFEST, final_folder, output_lock, staged_results, staging_path)
from photogram_cli.main import main

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[1]


def _lab(tmp_path) -> Path:
    from lab_stage import copy_measured_lab
    return copy_measured_lab(tmp_path / "lab") / "lab.prj"     # copied, measured once a session


def _digest(folder: Path) -> dict:
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def _fail_on_write(monkeypatch, n, exc):
    """Let atomic writes fail at the n-th file (a seam of atomic.py)."""
    real, calls = atomic._write_all, []

    def write(handle, data):
        calls.append(1)
        if len(calls) == n:
            raise exc
        real(handle, data)
    monkeypatch.setattr(atomic, "_write_all", write)


def _complete(folder: Path) -> None:
    """A results folder that reads back, with its report."""
    res = read_results(folder)
    assert res.summary["command"] == "calibrate" and res.summary["status"] == "converged"
    assert (folder / "report.pdf").is_file() and (folder / "covariance.npz").is_file()
    assert not (folder / INCOMPLETE).exists()
    assert not staging_path(folder).exists()


# ---------------------------------------------------------------- item 13


def test_ctrl_c_mid_write_leaves_no_results_and_the_rerun_needs_no_force(
        tmp_path, monkeypatch, capsys):
    prj = _lab(tmp_path)
    out = prj.parent / "results"
    _fail_on_write(monkeypatch, 3, KeyboardInterrupt())      # after summary.json + 1 file
    assert main(["calibrate", str(prj), "-q"]) == 130
    assert not out.exists()                                  # nothing that looks complete
    assert not staging_path(out).exists()                    # nothing half-written either
    monkeypatch.undo()
    capsys.readouterr()
    assert main(["calibrate", str(prj), "-q"]) == 0, capsys.readouterr().err
    _complete(out)


def test_full_disk_during_force_keeps_the_earlier_results_intact(
        tmp_path, monkeypatch, capsys):
    prj = _lab(tmp_path)
    out = prj.parent / "results"
    assert main(["calibrate", str(prj), "-q"]) == 0
    before = _digest(out)
    _fail_on_write(monkeypatch, 4, OSError(28, "No space left on device"))
    capsys.readouterr()
    assert main(["calibrate", str(prj), "-q", "--force"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "No space left on device" in err[0], err
    assert _digest(out) == before                            # old results, byte for byte
    assert not staging_path(out).exists()
    monkeypatch.undo()
    assert main(["calibrate", str(prj), "-q", "--force"]) == 0
    _complete(out)


HOLD = textwrap.dedent("""
    import pathlib, sys, time
    import photogram.report as report
    real = report.write_report

    def held(folder, **kw):      # stop in the middle of writing the results
        pathlib.Path(sys.argv[1]).write_text("ready")
        while not pathlib.Path(sys.argv[2]).exists():
            time.sleep(0.05)
        return real(folder, **kw)

    report.write_report = held
    from photogram_cli.main import main
    sys.exit(main(sys.argv[3:]))
""")


def _held_run(tmp_path, *args):
    """A `photogram` process stopped mid-write (its results files written, the
    report not yet); returns (process, go file)."""
    ready, go = tmp_path / "ready", tmp_path / "go"
    for f in (ready, go):
        f.unlink(missing_ok=True)
    proc = subprocess.Popen([sys.executable, "-c", HOLD, str(ready), str(go), *args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    t0 = time.time()
    while not ready.exists():
        if proc.poll() is not None:
            pytest.fail(f"the held run ended early: {proc.communicate()}")
        if time.time() - t0 > 300:
            proc.kill()
            pytest.fail("the held run did not reach the writing step")
        time.sleep(0.05)
    return proc, go


def test_killed_process_mid_write_leaves_no_results_and_the_rerun_needs_no_force(
        tmp_path, capsys):
    prj = _lab(tmp_path)
    out = prj.parent / "results"
    proc, _ = _held_run(tmp_path, "calibrate", str(prj), "-q")
    os.kill(proc.pid, signal.SIGKILL)                        # no cleanup at all
    proc.wait()
    assert not out.exists()                                  # no folder that looks complete
    assert main(["calibrate", str(prj), "-q"]) == 0, capsys.readouterr().err
    _complete(out)


def test_staging_folder_api(tmp_path):
    """Rename into an absent folder; merge into an existing one keeping a
    user's file and dropping the earlier run's entries the new run does not
    write; a resumable run's state survives an error and is continued."""
    out = tmp_path / "results"
    with staged_results(out) as stage:
        assert stage.path == tmp_path / ".results.incomplete" and not out.exists()
        assert final_folder(stage.path) == out
        for name in ("summary.json", "a.csv", "old.csv"):
            (stage.path / name).write_text(name)
    assert sorted(p.name for p in out.iterdir()) == [MANIFEST, "a.csv", "old.csv",
                                                     "summary.json"]
    (out / "notes.txt").write_text("mine")
    with staged_results(out) as stage:
        (stage.path / "summary.json").write_text("new")
        (stage.path / "a.csv").write_text("new a")
    assert sorted(p.name for p in out.iterdir()) == [MANIFEST, "a.csv", "notes.txt",
                                                     "summary.json"]
    assert (out / "a.csv").read_text() == "new a" and (out / "notes.txt").read_text() == "mine"
    # an error: the results stay; a resumable run keeps its state for the rerun
    mc = tmp_path / "mc"
    with pytest.raises(RuntimeError):
        with staged_results(mc, resumable=True) as stage:
            (stage.path / "samples").mkdir()
            (stage.path / "samples" / "chunk-00000.csv").write_text("run 0")
            raise RuntimeError("interrupted")
    assert not mc.exists()
    assert claim_output(mc, command="montecarlo", resumable=True) == "resume"
    with staged_results(mc, resumable=True) as stage:
        assert (stage.path / "samples" / "chunk-00000.csv").read_text() == "run 0"
        (stage.path / "summary.json").write_text("{}")
    assert (mc / "samples" / "chunk-00000.csv").read_text() == "run 0"
    # a later --force run starts from the earlier run's trials (hard links)
    with staged_results(mc, resumable=True) as stage:
        assert (stage.path / "samples" / "chunk-00000.csv").read_text() == "run 0"
        (stage.path / "samples" / "chunk-00000.csv").unlink()   # discarded, not the original
        assert (mc / "samples" / "chunk-00000.csv").read_text() == "run 0"
        (stage.path / "summary.json").write_text("{}")
    # a non-resumable error removes the staging folder, the results stay
    with pytest.raises(KeyboardInterrupt):
        with staged_results(out) as stage:
            (stage.path / "summary.json").write_text("half")
            raise KeyboardInterrupt
    assert (out / "summary.json").read_text() == "new" and not stage.path.exists()
    # an interrupted replacement is marked and replaced without --force
    (out / INCOMPLETE).write_text("")
    assert claim_output(out, command="calibrate") == "replace"


def test_results_folder_never_holds_an_input(tmp_path):
    prj = _lab(tmp_path)
    with pytest.raises(InputError, match="never writes over its inputs"):
        with staged_results(prj.parent, inputs=[prj]):
            pass


# ---------------------------------------------------------------- item 14


def test_second_run_into_a_busy_folder_stops_with_one_line(tmp_path, capsys):
    """Run A is stopped mid-write in another process; run B into the same
    folder (even with --force) exits 2 with one line and writes nothing;
    A then finishes with complete results of its own."""
    prj = _lab(tmp_path)
    out = prj.parent / "results"
    proc, go = _held_run(tmp_path, "calibrate", str(prj), "-q")
    try:
        capsys.readouterr()
        assert main(["calibrate", str(prj), "-q", "--force"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith(str(out)), err
        assert "another photogram run is writing into this folder" in err[0]
        assert "--output" in err[0]
        assert not (out / "summary.json").exists()           # B wrote nothing
    finally:
        go.write_text("go")
        stdout, stderr = proc.communicate(timeout=600)
    assert proc.returncode == 0, stderr
    _complete(out)
    log = (out / "log.txt").read_text()
    assert log.startswith(f"photogram calibrate {prj}")
    # the lock is free again: a --force run now goes through
    assert main(["calibrate", str(prj), "-q", "--force"]) == 0


def test_lock_is_reentrant_in_one_process_and_exclusive_across(tmp_path):
    out = tmp_path / "results"
    probe = ("import sys\nfrom photogram.project.results_folder import output_lock\n"
             "try:\n    with output_lock(sys.argv[1]):\n        print('free')\n"
             "except Exception as e:\n    print(e.one_line())\n")
    with output_lock(out, command="calibrate"):
        with output_lock(out):                               # the command inside the CLI
            pass
        other = subprocess.run([sys.executable, "-c", probe, str(out)], capture_output=True,
                               text=True, timeout=120)
        assert "another photogram run" in other.stdout, other
    other = subprocess.run([sys.executable, "-c", probe, str(out)], capture_output=True,
                           text=True, timeout=120)
    assert other.stdout.strip() == "free", other
