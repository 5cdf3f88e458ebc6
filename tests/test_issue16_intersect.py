"""Issue 16, items 4, 10 (intersect plausibility), 11, 12 and 15: honest
intersect results and exports (docs/reliability.md, the issue 16 section).

The chain lab -> field -> jumps and the mocap results of ski-ptz are
those of the session's example runs (conftest.py's ``example_steps``,
shared with tests/test_examples_unchanged.py): the chain copied once per
module.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import photogram
from photogram_cli.main import main

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow

PROJECTS = Path(photogram.__file__).resolve().parents[1] / "projects"


@pytest.fixture(scope="module")
def chain(tmp_path_factory, example_steps):
    """calibrate lab, orient field, intersect jumps: a copy of the session's
    example runs (conftest.py ``example_steps``; `photogram intersect
    --no-report -q jumps.prj` on the session's calibrated lab and oriented
    field; the paths in its results those of the copy)."""
    example_steps.results("intersect jumps")
    return example_steps.copy(("lab", "field", "jumps"), tmp_path_factory.mktemp("i16") / "chain")


@pytest.fixture(scope="module")
def mocap_results(example_steps):
    """ski-ptz's `photogram mocap --no-report -q` results, the session's
    example run (read only)."""
    return example_steps.results("mocap ski-ptz")


def _variant(chain, name, old, new):
    """A copy of jumps.prj beside it with one line replaced."""
    prj = chain / "jumps" / "jumps.prj"
    text = prj.read_text()
    assert old in text
    out = chain / "jumps" / name
    out.write_text(text.replace(old, new))
    return out


def _table(path):
    return pd.read_csv(path, comment="#", dtype={"exposure": str, "point": str, "line": str})


# ---------------------------------------------------------------- item 4

def test_orientation_of_the_lab_alone_is_refused(chain, capsys, tmp_path):
    """orientation = ["../lab/results"] alone propagated the interior
    covariance with the stations held exact (sigmas ~15x too large, exit 0);
    now one line naming the stations and the field results to add."""
    prj = _variant(chain, "jumps-lab.prj", 'orientation = ["../field/results"]',
                   'orientation = ["../lab/results"]')
    line = 1 + prj.read_text().splitlines().index(
        next(ln for ln in prj.read_text().splitlines() if ln.startswith("orientation =")))
    out = tmp_path / "out"
    assert main(["intersect", "--no-report", str(prj), "--output", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert err[0].startswith(f"{prj}:{line}: [intersect] orientation")
    assert "stations S1, S2, S3" in err[0] and 'orientation = ["../field/results"]' in err[0]
    assert not out.exists()
    # lab and field together (the field's joint covariance covers the stations) run
    both = _variant(chain, "jumps-both.prj", 'orientation = ["../field/results"]',
                    'orientation = ["../lab/results", "../field/results"]')
    assert main(["intersect", "--no-report", "-q", str(both), "--output", str(tmp_path / "both")]) == 0


# ---------------------------------------------------------------- item 11

def test_one_exposure_numbering_in_every_output(chain):
    """exposures.csv numbered 0..23 while points3d.csv, lines3d.csv and the
    ski checks use the measured ids 001..024: a join shifted every row."""
    res = chain / "jumps" / "results"
    e, p, lines = _table(res / "exposures.csv"), _table(res / "points3d.csv"), \
        _table(res / "lines3d.csv")
    measured = list(dict.fromkeys(_table(chain / "jumps" / "jumper_points.csv")["exposure"]))
    assert list(e["exposure"]) == measured == list(dict.fromkeys(p["exposure"]))
    assert set(lines["exposure"]) == set(measured)
    checks = json.loads((res / "summary.json").read_text())["ski_checks"]
    assert checks and set(checks) <= set(measured)
    # joined on the exposure id, O of the stick model is the midpoint of the bindings
    bind = p[p["point"].isin(["P3", "P4"])].groupby("exposure")[["X", "Y", "Z"]].mean()
    joined = e.set_index("exposure").join(bind, how="inner")
    assert len(joined) == len(e) == 24
    for c in "XYZ":
        assert np.allclose(joined[f"O_{c.lower()}"], joined[c], rtol=0, atol=1e-6)


# ---------------------------------------------------------------- item 10

def test_a_jumper_in_the_wrong_unit_is_flagged(chain, capsys, tmp_path):
    """length_unit = "m" on dm data gave v = 208-253 m/s with exit 0 and no
    word; now a warning (summary.json, log.txt, one line on stderr) with the
    measured speed, naming dm as the unit that fits."""
    res = chain / "jumps" / "results"
    v_dm = _table(res / "exposures.csv")["v"].to_numpy(float)      # dm/s, the right unit
    good = json.loads((res / "summary.json").read_text())["warnings"]
    assert not [w for w in good if w.startswith("implausible")]
    prj = _variant(chain, "jumps-m.prj", 'length_unit = "dm"', 'length_unit = "m"')
    out = tmp_path / "m"
    done = subprocess.run([sys.executable, "-m", "photogram_cli", "intersect", "--no-report", str(prj),
                           "--output", str(out)], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    err = done.stderr.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("intersect: warning: implausible")
    warnings = json.loads((out / "summary.json").read_text())["warnings"]
    speed = [w for w in warnings if w.startswith("implausible speed")]
    assert len(speed) == 1
    assert f"v reaches {v_dm.max():.3g} m/s at 24 of 24 exposures" in speed[0]
    assert 'length_unit = "dm"' in speed[0]
    assert any(w.startswith("implausible jumper size") for w in warnings)
    assert any(w.startswith("implausible height change") for w in warnings)
    assert "implausible speed" in (out / "log.txt").read_text()


def test_vertical_acceleration_of_a_parabola():
    from photogram.jump.plausibility import _vertical_acceleration
    t = np.arange(24) / 30.0
    a, sa = _vertical_acceleration(t, 100.0 + 3.0 * t - 0.5 * 9.81 * t ** 2)
    assert a == pytest.approx(-9.81, abs=1e-9) and sa < 1e-9
    a10, _ = _vertical_acceleration(t, 10.0 * (3.0 * t - 0.5 * 9.81 * t ** 2))
    assert a10 == pytest.approx(-98.1, abs=1e-8)
    assert np.isnan(_vertical_acceleration(t[:5], t[:5])[0])


# ---------------------------------------------------------------- item 12

def _colmap_points(path):
    rows = [ln.split() for ln in path.read_text().splitlines() if ln and ln[0] != "#"]
    header = next(ln for ln in path.read_text().splitlines() if "Number of points" in ln)
    return rows, int(header.split(":")[1].split(",")[0])


def test_colmap_export_of_the_jump_has_every_point(chain, tmp_path):
    """The jumps results wrote 'Number of points: 96' and no point (their
    residuals.csv listed no observation, so no point had a track)."""
    res = chain / "jumps" / "results"
    assert main(["export", "-q", "colmap", str(res), "--to", str(tmp_path / "model")]) == 0
    rows, count = _colmap_points(tmp_path / "model" / "points3D.txt")
    pts = _table(res / "points.csv")
    assert count == len(rows) == len(pts) == 96
    xyz = {r[0]: [float(x) for x in r[1:4]] for r in rows}
    order = sorted(xyz, key=int)                          # renumbered 1..96 in table order
    assert np.allclose([xyz[k] for k in order], pts[["X", "Y", "Z"]].to_numpy(), atol=1e-9)
    assert all(len(r[8:]) == 2 * 3 for r in rows)         # every point seen by S1, S2, S3
    resid = _table(res / "residuals.csv")
    assert len(resid) == 288 and {"x", "y", "vx", "vy"} <= set(resid.columns)


def test_colmap_header_counts_the_points_written():
    from photogram.io.colmap import format_colmap
    from photogram.io.exchange import View
    view = View(name="S1", camera="K1", K=np.array([[1000.0, 0, 320], [0, 1000, 240], [0, 0, 1]]),
                dist=np.zeros(5), R_cv=np.eye(3), t_cv=np.zeros(3), image_size=(640, 480))
    text = format_colmap([view], ["1", "2"], np.array([[0.0, 0, 5], [1, 1, 5]]),
                         [(0, 0, 320.0, 240.0)])["points3D.txt"]
    rows = [ln for ln in text.splitlines() if not ln.startswith("#")]
    assert len(rows) == 1 and "# Number of points: 1," in text


def test_colmap_export_reads_back_with_pycolmap(chain, tmp_path):
    pycolmap = pytest.importorskip("pycolmap")
    res = chain / "jumps" / "results"
    assert main(["export", "-q", "colmap", str(res), "--to", str(tmp_path / "m")]) == 0
    rec = pycolmap.Reconstruction(str(tmp_path / "m"))
    assert len(rec.points3D) == 96 and len(rec.images) == 3


def test_pose2sim_export_of_a_dm_project_is_in_metres(chain, tmp_path):
    """Pose2Sim assumes metres; the field project is in dm."""
    from photogram.io.pose2sim import read_pose2sim
    res = chain / "field" / "results"
    assert main(["export", "-q", "pose2sim", str(res), "--to", str(tmp_path / "c.toml")]) == 0
    views = read_pose2sim(tmp_path / "c.toml")
    st = _table(res / "stations.csv").set_index("station")
    for v in views:
        X0 = -v.R_cv.T @ np.asarray(v.t_cv, float)
        assert np.allclose(X0, st.loc[v.name, ["X0", "Y0", "Z0"]].to_numpy(float) * 0.1,
                           rtol=1e-12, atol=1e-9)


@pytest.mark.parametrize("fmt", ["pose2sim", "opencv", "colmap"])
def test_pan_tilt_zoom_cameras_are_not_exported_as_frame_0(fmt, capsys, tmp_path):
    to = tmp_path / ("c.toml" if fmt == "pose2sim" else "c.yml" if fmt == "opencv" else "m")
    assert main(["export", fmt, str(PROJECTS / "ski-ptz" / "ski-ptz.prj"), "--to", str(to)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "pan, tilt or zoom" in err[0] and "ski-ptz.prj" in err[0]
    assert not to.exists()


def test_mocap_results_export_to_trc_c3d_csv_mot(mocap_results, tmp_path):
    """photogram export trc|c3d|csv|mot on a mocap results folder failed
    ('no points3d.csv'); the exports now hold joints3d.csv's joints (metres)
    and metrics.csv's angles."""
    from photogram.io.trajectories import read_c3d, read_mot
    from photogram.io.trc import read_trc
    joints = pd.read_csv(mocap_results / "joints3d.csv", comment="#")
    metrics = pd.read_csv(mocap_results / "metrics.csv", comment="#")
    names = [c[:-2] for c in joints.columns if c.endswith("_X")]
    xyz = np.stack([joints[[f"{j}_X", f"{j}_Y", f"{j}_Z"]].to_numpy(float) for j in names], 1)
    for fmt in ("trc", "c3d", "csv", "mot"):
        assert main(["export", "-q", fmt, str(mocap_results), "--to",
                     str(tmp_path / f"j.{fmt}")]) == 0
    trc = read_trc(tmp_path / "j.trc", rotate_to_z_up=True)
    assert list(trc.markers) == names and trc.units == "m"
    assert np.allclose(np.stack([trc.markers[j] for j in names], 1), xyz, equal_nan=True)
    assert np.allclose(trc.times, joints["time"])
    c3d = read_c3d(tmp_path / "j.c3d")
    assert c3d["labels"] == names and c3d["units"] == "mm" and c3d["rate"] == 50
    assert np.allclose(c3d["xyz"], xyz * 1000.0, atol=0.01, equal_nan=True)
    csv = pd.read_csv(tmp_path / "j.csv")
    assert list(csv.columns[:5]) == ["exposure", "time", "head_X", "head_Y", "head_Z"]
    assert np.allclose(csv["head_Z"], joints["head_Z"], equal_nan=True)
    assert list(csv["exposure"]) == list(joints["frame"])
    mot = read_mot(tmp_path / "j.mot")
    assert np.allclose(mot["knee_flexion_r"], metrics["knee_flexion_r"], equal_nan=True)
    assert np.allclose(mot["speed"], metrics["speed"], equal_nan=True)       # m project


def test_csv_export_is_a_plain_table(chain, tmp_path):
    """The first line was a '#' comment: pandas.read_csv read it as the header."""
    res = chain / "jumps" / "results"
    to = tmp_path / "jump.csv"
    assert main(["export", "-q", "csv", str(res), "--to", str(to)]) == 0
    table = pd.read_csv(to, dtype={"exposure": str})
    p = _table(res / "points3d.csv")
    first = p[(p["exposure"] == "001") & (p["point"] == "P1")]
    assert len(table) == 24 and table.columns[0] == "exposure"
    assert table.loc[0, "exposure"] == "001"
    assert table.loc[0, "P1_X"] == pytest.approx(float(first["X"].iloc[0]) * 0.1, rel=1e-12)
    meta = json.loads((tmp_path / "jump.csv.json").read_text())
    assert meta["length_unit"] == "m" and meta["source_length_unit"] == "dm"


def test_export_source_can_be_imported_first():
    done = subprocess.run([sys.executable, "-c", "import photogram.io.export_source"],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr


# ---------------------------------------------------------------- item 15

def test_export_never_writes_over_its_input(chain, capsys, tmp_path):
    """--to RESULTS/points3d.csv --force replaced the export's own input."""
    res = tmp_path / "results"
    shutil.copytree(chain / "jumps" / "results", res)
    targets = {"csv": res / "points3d.csv", "trc": res / "summary.json",
               "mot": res / "exposures.csv", "ply": res / "points.csv",
               "c3d": chain / "jumps" / "jumper_points.csv"}      # read for the camera masks
    for fmt, target in targets.items():
        before = target.read_bytes()
        assert main(["export", fmt, str(res), "--to", str(target), "--force"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "never writes over the files it reads" in err[0]
        assert target.read_bytes() == before
    # a new file in the results folder is fine
    assert main(["export", "-q", "csv", str(res), "--to", str(res / "jump.csv")]) == 0
