"""photogram simulate: design files -> synthetic projects with truth that
read back and adjust; the designs in projects/designs; bad input."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from photogram.errors import InputError
from photogram.project import read_project

DESIGNS = Path(__file__).resolve().parents[1] / "projects" / "designs"


@pytest.fixture(scope="module")
def situation_b(tmp_path_factory):
    from photogram.commands.simulate import simulate
    folder = tmp_path_factory.mktemp("sb")
    prj, project, truth = simulate(DESIGNS / "situation-b.toml", folder)
    return folder, prj, project, truth


def test_situation_b_reads_back_and_adjusts(situation_b):
    from photogram.bundle import adjust
    folder, prj, project, truth = situation_b
    back = read_project(prj)
    assert len(back.stations) == 3 and len(back.distances) == 4 and len(back.verticals) == 4
    assert not np.any(back.points.kind == "control")            # no reference points
    assert sum(i.startswith("P1@") for i in back.points.ids) == 24
    assert all(c.free_mask().sum() == 2 for c in back.cameras.values())    # c and K1
    assert all(c.parameters["x0"].value == 320.0 for c in back.cameras.values())
    assert np.all(np.isfinite(back.stations.position_sigma))    # datum: station priors
    result = adjust(back)                       # photogram calibrate without the files
    assert result.summary["status"] == "converged"
    assert 0.8 < result.summary["sigma0"] < 1.2
    # the estimated c near the truth (a few of its sigmas)
    for name, cam in result.project.cameras.items():
        c_true = truth["cameras"][name]["c"]
        assert abs(cam.parameters["c"].value - c_true) < 4 * result.camera_sigma[name]["c"]
    for name in ("cameras.csv", "stations.csv", "points.csv", "image_points.csv",
                 "distances.csv"):
        assert (folder / "truth" / name).is_file()
    assert (folder / "montecarlo.prj").is_file()


def test_simulated_montecarlo_chain_uses_the_truth(situation_b):
    from photogram.montecarlo import run_montecarlo
    folder, *_ = situation_b
    chain = read_project(folder / "montecarlo.prj")
    assert chain.montecarlo.truth == "simulation" and chain.montecarlo.align == "plan"
    _, summary = run_montecarlo(chain, runs=12, chunk=6, output=folder / "mc", progress=False)
    assert summary["failed"] == 0
    assert set(summary["headline"]) == {"station", "interior", "point"}


@pytest.mark.parametrize("design, counts", [("lab.toml", (9, 50)), ("arena.toml", (3, 21))])
def test_builtin_designs_are_the_example_networks(tmp_path, design, counts):
    from photogram.commands.simulate import simulate
    prj, project, _ = simulate(DESIGNS / design, tmp_path)
    back = read_project(prj)
    assert (len(back.stations), len(back.points)) == counts
    truth = (tmp_path / "truth" / "points.csv").read_text()
    assert truth.startswith("# SIMULATED data")


@pytest.mark.parametrize("text, message", [
    ('[design]\nname = "x"\nsede = 1\n', "unknown key 'sede'"),
    ('[design]\nbuiltin = "moon"\n', "unknown builtin 'moon'"),
    ('[design]\nname = "x"\n[cameras.K1]\nc = 1000.0\nimage_size = [640, 480]\n'
     '[[stations]]\nname = "S1"\ncamera = "K9"\nposition = [0, 0, 0]\nlook_at = [0, 1, 0]\n',
     "unknown camera 'K9'"),
])
def test_bad_design_is_one_line_with_file_and_line(tmp_path, text, message, capsys):
    from photogram.simulation.design_file import read_design
    from photogram_cli.main import main
    path = tmp_path / "bad.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(InputError) as err:
        read_design(path)
    assert message in str(err.value) and err.value.line is not None
    assert main(["simulate", str(path)]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"{path}:")


def test_missing_design_exits_2(tmp_path, capsys):
    from photogram_cli.main import main
    assert main(["simulate", str(tmp_path / "none.toml")]) == 2
    assert "design file not found" in capsys.readouterr().err


def test_command_line_writes_the_project(tmp_path, capsys):
    from photogram_cli.main import main
    assert main(["simulate", str(DESIGNS / "arena.toml"), "--output", str(tmp_path)]) == 0
    assert "written" in capsys.readouterr().out
    assert (tmp_path / "arena.prj").is_file() and (tmp_path / "montecarlo.prj").is_file()
    # a second run refuses to overwrite without --force
    assert main(["simulate", str(DESIGNS / "arena.toml"), "--output", str(tmp_path)]) == 2
    assert main(["simulate", str(DESIGNS / "arena.toml"), "--output", str(tmp_path),
                 "--force"]) == 0
