"""Issue 23, item 3: units a coach reads (deg, m, km/h) and the height of O
above a landing-slope profile.

Conversions against exact values; the profile against a hand-computed
height; the whole intersect step of projects/jumps/jumps-coach.prj
(SIMULATED) against the simulation's truth; bad units -> one line, exit 2.
"""

from __future__ import annotations

import contextlib
import io
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from photogram.errors import InputError
from photogram.jump.coach import (coach_table, read_landing_profile, to_coach, unit_of)

ROOT = Path(__file__).resolve().parents[1]
JUMPS = ROOT / "projects" / "jumps"


def _cli():
    """The command line's entry point."""
    from photogram_cli.main import main
    return main


def _run(args):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = _cli()(args)
    return code, out.getvalue(), err.getvalue()


def _frame(angle_unit):
    right = {"gon": 100.0, "deg": 90.0, "rad": np.pi / 2}[angle_unit]
    return pd.DataFrame({"exposure": ["001"], "time": [0.0], "alpha": [right],
                         "sigma_alpha": [right / 100], "Z0": [-226.0], "sigma_Z0": [0.5],
                         "v": [250.0], "sigma_v": [2.0], "O_x": [425.0], "O_y": [0.0],
                         "O_z": [-226.0]})


@pytest.mark.parametrize("angle_unit", ["gon", "deg", "rad"])
def test_angles_become_degrees(angle_unit):
    c = to_coach(_frame(angle_unit), angle_unit, "dm")
    assert c["alpha"].iloc[0] == pytest.approx(90.0, rel=1e-15)
    assert c["sigma_alpha"].iloc[0] == pytest.approx(0.9, rel=1e-15)
    assert unit_of("alpha", angle_unit, "dm", "coach") == "deg"
    assert unit_of("alpha", angle_unit, "dm") == angle_unit


def test_speed_in_kmh_is_3_6_times_m_per_s_and_lengths_in_m():
    c = to_coach(_frame("gon"), "gon", "dm")
    assert c["v"].iloc[0] == pytest.approx(25.0 * 3.6, rel=1e-15)       # 250 dm/s = 25 m/s
    assert c["sigma_v"].iloc[0] == pytest.approx(0.2 * 3.6, rel=1e-15)
    assert c["Z0"].iloc[0] == pytest.approx(-22.6, rel=1e-15)
    assert c["O_x"].iloc[0] == pytest.approx(42.5, rel=1e-15)
    assert unit_of("v", "gon", "dm", "coach") == "km/h"
    assert unit_of("v", "gon", "dm") == "dm/s"
    table = coach_table(_frame("gon"), "gon", "dm")
    assert list(table.columns) == ["exposure", "time_s", "alpha_deg", "sigma_alpha_deg",
                                   "Z0_m", "sigma_Z0_m", "v_kmh", "sigma_v_kmh"]


def test_height_above_a_profile_by_hand(tmp_path):
    path = tmp_path / "profile.csv"
    path.write_text("# a kinked slope\ndistance,height\n0,0\n10,-5\n20,-20\n")
    ground = read_landing_profile(path)
    # O at x = 15: the surface is halfway between -5 and -20, z = -12.5
    h, dh = ground.height(np.array([[15.0, 3.0, -3.0], [5.0, 0.0, 1.0], [25.0, 0.0, 0.0]]))
    assert h[0] == pytest.approx(9.5, abs=1e-12)
    assert h[1] == pytest.approx(3.5, abs=1e-12)          # z(5) = -2.5
    assert np.isnan(h[2])                                  # beyond the profile
    assert dh[0] == pytest.approx([1.5, 0.0, 1.0])        # d h / d O: slope -1.5


@pytest.mark.parametrize("text, what", [
    ("distance,height\n0,0\n0,-1\n", "does not increase at row 2"),
    ("distance,z\n0,0\n1,-1\n", "column height is missing"),
    ("distance,height\n0,0\n", "at least 2 rows"),
    ("distance,height\n0,0\n1,abc\n", "row 2 is not two finite numbers"),
])
def test_bad_profile_is_one_input_error(tmp_path, text, what):
    path = tmp_path / "profile.csv"
    path.write_text(text)
    with pytest.raises(InputError, match=what):
        read_landing_profile(path)


def test_bad_units_in_the_project_exit_2_with_one_line(tmp_path):
    prj = tmp_path / "jumps.prj"
    shutil.copy(JUMPS / "jumper_points.csv", tmp_path)
    shutil.copy(JUMPS / "ski_lines.csv", tmp_path)
    prj.write_text((JUMPS / "jumps.prj").read_text() + '\n[report]\nunits = "imperial"\n')
    code, out, err = _run(["intersect", str(prj)])
    assert code == 2
    assert len(err.strip().splitlines()) == 1, err
    assert "units" in err and "imperial" in err and "coach" in err


def test_bad_units_option_exits_2_with_one_line(tmp_path):
    code, out, err = _run(["report", str(tmp_path), "--units", "furlongs"])
    assert code == 2
    assert len(err.strip().splitlines()) == 1, err


@pytest.mark.slow
def test_coach_project_against_the_simulation_truth(oriented_projects, tmp_path):
    """jumps-coach.prj (SIMULATED): coach.csv in deg, m, km/h; H above the
    landing profile against the true height; the report in coach units."""
    import pypdf
    root = tmp_path / "jumps"
    shutil.copytree(oriented_projects / "jumps", root)
    for name in ("jumps-coach.prj", "landing_profile.csv", "truth/heights.csv"):
        shutil.copy(JUMPS / name, root / name)
    prj = root / "jumps-coach.prj"
    text = prj.read_text().replace('"../', f'"{oriented_projects}/')
    prj.write_text(text)
    out = tmp_path / "results"
    code, _, err = _run(["intersect", str(prj), "-q", "--output", str(out)])
    assert code == 0, err
    e = pd.read_csv(out / "exposures.csv", dtype={"exposure": str})
    c = pd.read_csv(out / "coach.csv", dtype={"exposure": str})
    assert list(c["exposure"]) == list(e["exposure"])
    # dm/s -> m/s -> km/h; gon -> deg
    np.testing.assert_allclose(c["v_kmh"], 3.6 * 0.1 * e["v"], rtol=1e-9)
    np.testing.assert_allclose(c["alpha_deg"], 0.9 * e["alpha"], rtol=1e-9)
    np.testing.assert_allclose(c["Z0_m"], 0.1 * e["Z0"], rtol=1e-9)
    # against the truth of the simulation
    truth = pd.read_csv(root / "truth" / "heights.csv", comment="#", dtype={"exposure": str})
    z = (c["H_m"] - 0.1 * truth["H"]) / c["sigma_H_m"]
    assert np.all(np.abs(z) < 4), z.to_numpy()
    angles = pd.read_csv(root / "truth" / "angles.csv", comment="#", dtype={"exposure": str})
    z = (c["alpha_deg"] - 0.9 * angles["alpha"]) / c["sigma_alpha_deg"]
    assert np.all(np.abs(z) < 4), z.to_numpy()
    # H is the height above the slope, Z0 stays world Z (the slope is tens of m below 0)
    assert np.all(c["H_m"] > 2.5) and np.all(c["H_m"] < 5.0)
    assert np.all(c["Z0_m"] < -20)
    text = " ".join(p.extract_text() for p in pypdf.PdfReader(str(out / "report.pdf")).pages)
    assert "v [km/h]" in text and "km/h" in text and "H [m]" in text
    assert "dm/s" not in text
    # the same results rebuilt in the project's units, and back
    code, _, err = _run(["report", str(out), "-q", "--units", "project",
                         "--output", str(tmp_path / "again")])
    assert code == 0, err
    text = " ".join(p.extract_text() for p in
                    pypdf.PdfReader(str(tmp_path / "again" / "report.pdf")).pages)
    assert "dm/s" in text and "km/h" not in text


@pytest.mark.slow
def test_default_units_write_no_coach_outputs(example_steps):
    """Without [report] and --units: no coach.csv, no H, no report_units
    (projects/jumps/jumps.prj's `photogram intersect --no-report -q`, the
    session's example run: conftest.py ``example_steps``)."""
    import json
    out = example_steps.results("intersect jumps")
    assert "[report]" not in (out.parent / "jumps.prj").read_text()
    assert not (out / "coach.csv").exists()
    header = (out / "exposures.csv").read_text().splitlines()[0]
    assert header.endswith("O_x,O_y,O_z")
    summary = json.loads((out / "summary.json").read_text())
    assert "report_units" not in summary and "landing_profile" not in summary
