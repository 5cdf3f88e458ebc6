"""Bad input through the command line: exit code 2, exactly one line on
stderr naming file and line, no traceback, for every command."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from photogram_cli.main import COMMANDS, main

from project_cases import CASES, expected_line, make_project

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow


@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_check_reports_bad_input_in_one_line(tmp_path, capsys, case):
    prj = make_project(tmp_path, case.project)
    case.edit(prj.parent)
    assert main(["check", str(prj)]) == 2
    out, err = capsys.readouterr()
    assert out == ""
    lines = err.splitlines()
    assert len(lines) == 1, err
    line = expected_line(prj.parent, case)
    where = str(prj.parent / case.file) + (f":{line}:" if line is not None else ":")
    assert lines[0].startswith(where), lines[0]
    assert "Traceback" not in err


@pytest.mark.parametrize("command", [c for c, cmd in COMMANDS.items() if cmd.needs_project])
def test_every_command_validates_the_project_first(tmp_path, capsys, command):
    prj = make_project(tmp_path)
    (prj.parent / "points.csv").write_text("id,kind,X\n1,control,nan\n")
    assert main([command, str(prj)]) == 2
    err = capsys.readouterr().err
    assert err.splitlines() == [err.strip()]
    assert err.startswith(f"{prj.parent / 'points.csv'}:2: 'nan' in column 'X'")


def test_missing_project_file(tmp_path, capsys):
    assert main(["check", str(tmp_path / "none.prj")]) == 2
    err = capsys.readouterr().err
    assert err.strip() == (f"{tmp_path / 'none.prj'}: project file not found "
                           "(check the path; it is relative to the current folder)")


def test_verbose_error_prints_the_traceback_too(tmp_path, capsys):
    assert main(["check", "-v", str(tmp_path / "none.prj")]) == 2
    err = capsys.readouterr().err
    assert "Traceback" in err
    assert err.strip().splitlines()[-1].endswith("(check the path; it is relative to the current folder)")


def _run(*args, cwd):
    env = dict(os.environ, PYTHONWARNINGS="ignore")
    return subprocess.run([sys.executable, "-m", "photogram_cli", *args], cwd=cwd,
                          capture_output=True, text=True, env=env, timeout=60)


def test_console_process_bad_input(tmp_path):
    prj = make_project(tmp_path)
    (prj.parent / "lab.prj").write_text("[project]\nname = \n")
    proc = _run("calibrate", "lab/lab.prj", cwd=tmp_path)
    assert proc.returncode == 2
    assert proc.stdout == ""
    assert proc.stderr.splitlines() == [
        "lab/lab.prj:2: TOML syntax error: Invalid value "
        "(text needs double quotes, e.g. datum = \"control\")"]


def test_console_process_mocap_without_mocap_section(tmp_path):
    make_project(tmp_path)
    proc = _run("mocap", "lab/lab.prj", cwd=tmp_path)
    assert proc.returncode == 2
    assert proc.stderr.startswith("lab/lab.prj: this project has no [mocap] section")
    assert proc.stderr.count("\n") == 1


def test_the_parser_is_built_once_per_command_table(monkeypatch):
    from photogram_cli import main as cli
    first = cli._parser()
    assert cli._parser() is first
    monkeypatch.setitem(cli.COMMANDS, "extra", cli.Command("photogram.nowhere:run", "x", "x"))
    other = cli._parser()
    assert other is not first
    assert other.parse_args(["extra", "p.prj"]).command == "extra"
