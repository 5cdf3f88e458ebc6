"""The photogram command line: version, check, dispatch, exit codes."""

from __future__ import annotations

import re
import types
from pathlib import Path

import numpy as np
import pytest

import photogram
from photogram.project import read_project
from photogram_cli import main as cli
from photogram_cli.main import COMMANDS, Command, main

from project_cases import DATA, make_project

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow

def test_version(capsys):
    assert main(["--version"]) == 0
    assert capsys.readouterr().out.strip() == f"photogram {photogram.__version__}"


def test_no_command_prints_help(capsys):
    assert main([]) == 2
    assert "COMMAND" in capsys.readouterr().err


def test_every_subcommand_has_verbose_quiet_output():
    parser = cli.build_parser()
    for name, cmd in COMMANDS.items():
        argv = [name, "-v", "-q", "--output", "out"] + (["x.prj"] if cmd.needs_project else [])
        args = parser.parse_args(argv)
        assert args.verbose == 1 and args.quiet and str(args.output) == "out"


def test_check_prints_a_summary(capsys):
    assert main(["check", str(DATA / "lab" / "lab.prj")]) == 0
    out = capsys.readouterr().out
    assert "cameras       2: K1 (brown, 5 free), K2 (brown, 4 free, 1 weighted)" in out
    assert "points        13: 8 control, 2 check, 3 tie" in out
    assert "observations  49 image points, 0 image-line points" in out
    assert "rays/point    min 3, max 4" in out
    assert "warnings: none" in out
    assert len(out.splitlines()) <= 24


def test_check_field_project_with_cameras_from_file(capsys):
    assert main(["check", str(DATA / "field")]) == 0
    out = capsys.readouterr().out
    assert "from lab_cameras.toml" in out and "camera_to_world" in out
    assert "2 distance, 1 vertical" in out


def test_check_quiet_prints_nothing(capsys):
    assert main(["check", "-q", str(DATA / "lab" / "lab.prj")]) == 0
    assert capsys.readouterr() == ("", "")


def test_check_warnings_are_printed(tmp_path, capsys):
    prj = make_project(tmp_path)
    with open(prj.parent / "points.csv", "a") as f:
        f.write("99,tie,,,,,,\n")
    assert main(["check", str(prj)]) == 0
    assert "warning: 1 point(s) are not measured in any image and are not used: 99" in \
        capsys.readouterr().out


def test_check_output_writes_a_normalised_copy(tmp_path, capsys):
    out = tmp_path / "copy"
    assert main(["check", "-q", str(DATA / "field" / "field.prj"), "--output", str(out)]) == 0
    copy = read_project(out / "field.prj")
    assert copy.units.angle == "gon" and copy.rotation_direction == "camera_to_world"
    assert main(["check", "-q", str(DATA / "field" / "field.prj"), "--output", str(out)]) == 2
    assert "file exists" in capsys.readouterr().err
    assert main(["check", "-q", str(DATA / "field" / "field.prj"), "--output", str(out),
                 "--force"]) == 0


def test_mocap_needs_a_mocap_section(capsys):
    assert main(["mocap", "--no-report", str(DATA / "lab" / "lab.prj")]) == 2
    err = capsys.readouterr().err
    assert err.startswith(str(DATA / "lab" / "lab.prj")) and "no [mocap] section" in err


def test_montecarlo_needs_a_montecarlo_section(capsys):
    assert main(["montecarlo", "--no-report", str(DATA / "lab" / "lab.prj")]) == 2
    err = capsys.readouterr().err
    assert err.startswith(str(DATA / "lab" / "lab.prj")) and "no [montecarlo] section" in err


def test_demo_runs_the_lab_and_field_chain(tmp_path, monkeypatch, capsys):
    import functools
    import shutil

    import photogram.demo as demo
    root = Path(demo.__file__).resolve().parents[1]
    shutil.copytree(root / "projects" / "lab", tmp_path / "projects" / "lab",
                    ignore=shutil.ignore_patterns("results", "results-*"))
    shutil.copytree(root / "projects" / "field", tmp_path / "projects" / "field",
                    ignore=shutil.ignore_patterns("results"))
    monkeypatch.setattr(demo, "ROOT", tmp_path)
    monkeypatch.setattr(demo, "PROJECTS", tmp_path / "projects")
    all_steps = demo.steps
    assert [s[0] for s in all_steps()[:3]] == ["measure", "calibrate", "orient"]
    # the first three steps, measure, calibrate and orient without report.pdf
    # (not under test here: tests/test_report*.py and, for measure,
    # test_measure_errors.py::test_report_drawings_and_pdf; the report costs
    # more CPU than the adjustment)
    monkeypatch.setattr(demo, "steps", lambda: [
        (c, functools.partial(f, report=False), p, n) for c, f, p, n in all_steps()[:3]])
    assert main(["demo"]) == 0
    out = capsys.readouterr().out
    # the photographs are measured first, checked against the typed table, then calibrated
    assert re.search(r"measure projects/lab/frame\.toml: \d+ observations in 9 images", out)
    check = re.search(r"check against the typed lab_image_points\.csv: (\d+) of 446 found.*"
                      r" (\d+) more than 3 px off \(wrong labels\)", out)
    assert check and int(check.group(1)) >= 0.84 * 446 and check.group(2) == "0", out
    measured = tmp_path / "projects" / "lab" / "results-measure"
    assert (measured / "image_points.csv").is_file() and not (measured / "report.pdf").exists()
    assert "calibrate projects/lab/lab.prj: converged" in out
    assert "orient projects/field/field.prj: converged" in out
    assert (tmp_path / "projects" / "field" / "results" / "summary.json").is_file()



@pytest.fixture
def fake_command(monkeypatch):
    """Register a command 'calibrate' whose function is ``behaviour``."""
    def install(behaviour):
        module = types.ModuleType("fake_engine")
        module.run = behaviour
        monkeypatch.setitem(__import__("sys").modules, "fake_engine", module)
        monkeypatch.setitem(COMMANDS, "calibrate",
                            Command("fake_engine:run", "the adjustment engine", "test"))
    return install


def test_registered_function_gets_project_and_output(fake_command, tmp_path, capsys):
    seen = {}

    def run(project, args):
        seen["project"], seen["folder"] = project, project.output_folder()
        return 0
    fake_command(run)
    assert main(["calibrate", "--no-report", str(DATA / "lab" / "lab.prj"), "--output", str(tmp_path)]) == 0
    assert seen["project"].name == "lab" and seen["folder"] == tmp_path


def test_internal_error_is_one_line_exit_1(fake_command, capsys):
    def run(project, args):
        raise ValueError("boom\nsecond line")
    fake_command(run)
    assert main(["calibrate", "--no-report", str(DATA / "lab" / "lab.prj")]) == 1
    err = capsys.readouterr().err
    assert err == ("internal error: ValueError: boom second line (please report; "
                   "rerun with -v for the traceback)\n")


def test_internal_error_verbose_has_traceback(fake_command, capsys):
    def run(project, args):
        raise ValueError("boom")
    fake_command(run)
    assert main(["calibrate", "--no-report", "-v", str(DATA / "lab" / "lab.prj")]) == 1
    err = capsys.readouterr().err
    assert "Traceback" in err and err.splitlines()[-1].startswith("internal error")


def test_keyboard_interrupt_exit_130(fake_command, capsys):
    def run(project, args):
        raise KeyboardInterrupt
    fake_command(run)
    assert main(["calibrate", "--no-report", str(DATA / "lab" / "lab.prj")]) == 130
    assert capsys.readouterr().err == "photogram calibrate: interrupted\n"


def test_missing_third_party_package_is_reported(monkeypatch, capsys):
    monkeypatch.setitem(COMMANDS, "calibrate",
                        Command("no_such_package_xyz.engine:run", "the adjustment engine", "t"))
    assert main(["calibrate", "--no-report", str(DATA / "lab" / "lab.prj")]) == 2
    err = capsys.readouterr().err
    assert "needs the Python package 'no_such_package_xyz'" in err


def test_module_without_function_is_not_built(monkeypatch, capsys):
    monkeypatch.setitem(COMMANDS, "calibrate",
                        Command("photogram.errors:calibrate", "the adjustment engine", "t"))
    assert main(["calibrate", "--no-report", str(DATA / "lab" / "lab.prj")]) == 2
    assert "not built yet" in capsys.readouterr().err


def test_calibrate_writes_results_where_asked(tmp_path, capsys):
    out = tmp_path / "res"
    assert main(["calibrate", "--no-report", str(DATA / "lab" / "lab.prj"), "--output", str(out)]) == 0
    import json
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "converged"
    assert summary["redundancy"] > 0
    for name in ("cameras.toml", "stations.csv", "points.csv", "residuals.csv", "log.txt"):
        assert (out / name).is_file()
    assert not (DATA / "lab" / "results").exists()


def test_intersect_writes_the_jump_results(tmp_path, capsys):
    """photogram intersect on the generated jumps project, with the true
    (nominal) cameras and stations so that it runs before calibrate/orient."""
    import shutil

    import pandas as pd
    root = Path(photogram.__file__).resolve().parents[1] / "projects"
    for name in ("jumps", "field"):
        shutil.copytree(root / name, tmp_path / name, ignore=shutil.ignore_patterns("results*"))
    prj = tmp_path / "jumps" / "jumps.prj"
    text = prj.read_text()
    text = text.replace("../lab/results/cameras.toml", "../field/cameras-nominal.toml")
    text = text.replace("../field/results/stations.csv", "../field/truth/stations.csv")
    text = "\n".join(line for line in text.splitlines() if not line.startswith("orientation ="))
    prj.write_text(text)
    out = tmp_path / "out"
    assert main(["intersect", "--no-report", str(prj), "--output", str(out)]) == 0
    assert "intersect: 24 exposures" in capsys.readouterr().out
    frame = pd.read_csv(out / "exposures.csv")
    assert len(frame) == 24 and {"alpha", "sigma_alpha", "v", "sigma_v"} <= set(frame.columns)
    truth = pd.read_csv(tmp_path / "jumps" / "truth" / "angles.csv", comment="#")
    z = (frame["alpha"] - truth["alpha"]) / frame["sigma_alpha"]
    assert np.all(np.abs(z) < 4.5)
    for name in ("points3d.csv", "lines3d.csv", "jump.trc", "stick.png", "timeseries.png",
                 "summary.json"):
        assert (out / name).stat().st_size > 0
