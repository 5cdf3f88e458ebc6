"""Issue 16, item 19: every file name made from a user-given name (camera,
station, point, project) stays inside its folder: ``..``, ``/``, NUL and very
long names are tried wherever photogram turns a name into a file name."""

from __future__ import annotations

import types

import numpy as np
import pytest

from photogram.project.safe_names import MAX_LENGTH, inside, safe_name, safe_names

HOSTILE = ["..", ".", "../../../../x", "/", "/etc/passwd", "a/b", "a\\b", "x\x00y", "\x00",
           "", " ", "x" * 5000, "é" * 300, "CON", "nul.txt", "-rf", "C1\n[project]"]


def _files_under(root):
    return sorted(p for p in root.rglob("*") if p.is_file())


@pytest.mark.parametrize("name", HOSTILE, ids=repr)
def test_safe_name_stays_in_its_folder(tmp_path, name):
    s = safe_name(name)
    assert s and len(s) <= MAX_LENGTH
    assert s not in (".", "..") and not s.startswith((".", "-"))
    assert set(s) <= set("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_.-")
    assert s.split(".")[0].upper() not in ("CON", "NUL", "PRN", "AUX")
    folder = tmp_path / "out"
    folder.mkdir()
    path = folder / (s + ".npz")
    assert path.resolve().parent == folder.resolve()
    path.write_bytes(b"x")                  # a real file name on this file system
    assert inside(folder, name, ".npz") == path


def test_safe_names_keeps_ordinary_names_and_keeps_names_apart():
    assert safe_names(["C1", "cam-2", "P17", "situation-b", "GoPro.3"]) == \
        ["C1", "cam-2", "P17", "situation-b", "GoPro.3"]
    names = ["a/b", "a_b", "a b", "C1", "c1", "x" * 300, "x" * 299 + "y", "..", "/"]
    out = safe_names(names)
    assert len({s.lower() for s in out}) == len(names)          # distinct, also ignoring case
    assert out[1] == "a_b" and out[3] == "C1"                   # unchanged names keep their form
    assert all(len(s) <= MAX_LENGTH for s in out)
    with pytest.raises(ValueError):
        safe_names(["a", "a"])


def test_inside_refuses_a_symbolic_link_out_of_the_folder(tmp_path):
    from photogram.errors import InputError
    (tmp_path / "out").mkdir()
    (tmp_path / "elsewhere").mkdir()
    (tmp_path / "out" / "C1.npz").symlink_to(tmp_path / "elsewhere" / "C1.npz")
    with pytest.raises(InputError, match="outside the folder"):
        inside(tmp_path / "out", "C1", ".npz", what="camera")


def test_mocap_partial_files_stay_in_the_partial_folder(tmp_path, monkeypatch):
    """The resumable rotation differences of ``photogram mocap`` are one file
    per camera in .partial/rotation_differences: hostile camera names must
    not put them anywhere else (today's main wrote
    ``.partial/rotation_differences/../../../../x.npz``)."""
    from photogram.mocap.motion import homography, video
    from photogram.mocap.motion.homography import HomographySettings, RotationDifferences
    from photogram.mocap.motion.unknown_rotations import _from_images
    from photogram.mocap.reconstruction.cameras import MocapCameras

    base = tmp_path / "a" / "b" / "c" / "d" / "e" / "f"        # ../../../../x stays in tmp_path
    cache = base / "results" / ".partial" / "rotation_differences"
    names = ["../../../../x", str(tmp_path / "abs" / "evil"), "C1/../../y", "z" * 300, "C1",
             "c1"]
    C = len(names)
    (base / "video").mkdir(parents=True)
    images = {}
    for i, name in enumerate(names):
        images[name] = base / "video" / f"{i}.avi"
        images[name].write_bytes(b"not read")
    F = 4
    monkeypatch.setattr(video, "read_frames",
                        lambda path, frames=None: (np.zeros((8, 8, 3), np.uint8) for _ in frames))
    monkeypatch.setattr(homography, "rotation_differences", lambda *a, **k: RotationDifferences(
        dR=np.repeat(np.eye(3)[None], F - 1, 0), inliers=np.full(F - 1, 50),
        matches=np.full(F - 1, 60), ok=np.ones(F - 1, bool), seconds=0.1, frames=F))
    cams = MocapCameras(names, ["opencv"] * C, [np.array([1000., 1000, 4, 4, 0, 0, 0, 0, 0])] * C,
                        np.zeros((C, 3)), np.repeat(np.eye(3)[None], C, 0), np.full((C, 2), 8.0))
    ms = types.SimpleNamespace(images=images)
    out = _from_images(ms, cams, [None] * C, (0, F), HomographySettings(), cache=cache)
    assert sorted(out) == sorted(names)
    written = _files_under(tmp_path)
    partial = [p for p in written if p.suffix == ".npz"]
    assert len(partial) == C                                   # one file per camera, none shared
    assert all(p.parent == cache for p in partial), partial
    # and a rerun finds them again (resumable): nothing measured twice
    monkeypatch.setattr(homography, "rotation_differences",
                        lambda *a, **k: pytest.fail("measured again"))
    again = _from_images(ms, cams, [None] * C, (0, F), HomographySettings(), cache=cache)
    assert sorted(again) == sorted(names)


@pytest.mark.parametrize("name", ["../../../escape", "/tmp-abs/escape", "a\x00b", "x" * 400])
def test_simulate_design_name_stays_in_the_output_folder(tmp_path, name):
    """``name`` of a design file becomes ``<name>.prj`` (and, without
    --output, the folder results/<name>): it must stay inside."""
    import json

    from photogram.commands.simulate import simulate
    from photogram.project import read_project
    designs = tmp_path / "d1" / "d2" / "d3" / "designs"
    designs.mkdir(parents=True)
    design = designs / "lab.toml"
    if name.startswith("/"):
        name = str(tmp_path / name.lstrip("/"))
    design.write_text(f'[design]\nbuiltin = "lab"\nseed = 1\nname = {json.dumps(name)}\n')
    prj, project, _ = simulate(design)                          # default folder results/<name>
    assert prj.parent.parent == designs / "results"
    assert all(p.is_relative_to(designs / "results") for p in _files_under(tmp_path)
               if p != design)
    assert read_project(prj).name == name
    out = tmp_path / "out"
    prj2, _, _ = simulate(design, out)
    assert prj2.parent == out and prj2.suffix == ".prj"


@pytest.mark.parametrize("name", ["..", "../../x", "a\x00b", "s" * 400])
def test_opencv_export_station_names_stay_in_the_folder(tmp_path, name):
    """One FileStorage file per station: hostile station names stay in the
    folder and two stations never share a file."""
    from photogram.geometry import rodrigues_to_matrix
    from photogram.io.exchange import View
    from photogram.io.opencv_fs import read_opencv, write_opencv
    K = np.array([[1500.0, 0, 960], [0, 1500, 540], [0, 0, 1]])

    def view(n, t):
        return View(name=n, camera=n, K=K, dist=np.zeros(5), R_cv=rodrigues_to_matrix(
            np.array([0.1, 0.2, 0.3])), t_cv=np.array([t, 0, 4.0]), image_size=(1920, 1080))
    folder = tmp_path / "x" / "y" / "out"
    files = write_opencv(folder, [view(name, 0.0), view(safe_name(name), 1.0)])
    assert len(set(files)) == 2 and all(f.parent == folder for f in files)
    assert _files_under(tmp_path) == sorted(files)
    assert read_opencv(files[1])[0].t_cv[0] == pytest.approx(1.0)


def test_simulated_mocap_project_name_stays_in_its_folder(tmp_path):
    """The simulator's project name (generate.py --name, a library argument)
    becomes <name>.prj and <name>-estimate.prj inside the folder."""
    from photogram.simulation.ski.simproject import write_estimate_project, write_simulated_project
    from photogram.simulation.ski.simulate import simulate_session
    sim = simulate_session(seed=5, n_runs=1, frames_per_run=10)
    folder = tmp_path / "a" / "b" / "project"
    written = write_simulated_project(sim, folder, name="../../ski")
    est = write_estimate_project(sim, folder, name="../../ski")
    assert all(p.resolve().is_relative_to(folder) for p in _files_under(tmp_path))
    assert est.parent == folder and (folder / "ski.prj") in written
