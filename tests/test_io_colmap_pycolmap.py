"""COLMAP itself (pycolmap) reads photogram's COLMAP exports and writes
rigs that photogram reads; skipped where pycolmap is not installed (it is
not a dependency of photogram). Measured with pycolmap 4.2.1: parameters
equal bit for bit, COLMAP's projection of the exported cameras reproduces
the exported 2D points to 4.6e-13 px, rig poses equal bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from photogram.io.colmap import read_colmap
from photogram.io.formats import export_results, import_project
from test_io_colmap_models import PARAMS, rig_scene, scene, write_bin

pycolmap = pytest.importorskip("pycolmap")


@pytest.mark.parametrize("out", ["colmap", "colmap-bin"])
@pytest.mark.parametrize("model", list(PARAMS))
def test_colmap_reads_the_export_and_projects_its_points(tmp_path, model, out):
    write_bin(tmp_path / "m", *scene(model))
    prj = import_project("colmap", tmp_path / "m", tmp_path / "imp")
    export_results(out, prj, tmp_path / "back")
    rec = pycolmap.Reconstruction(str(tmp_path / "back"))
    cam = rec.cameras[3]
    assert cam.model.name == model
    assert np.allclose(np.array(cam.params), PARAMS[model], rtol=1e-12, atol=0)
    worst = 0.0
    for im in rec.images.values():
        for p2 in im.points2D:
            if p2.has_point3D():
                X = rec.points3D[p2.point3D_id].xyz
                xy = np.asarray(cam.img_from_cam(im.cam_from_world() * X))
                worst = max(worst, np.abs(xy - p2.xy).max())
    assert worst < 1e-9


@pytest.mark.parametrize("kind", ["binary", "text"])
def test_rigs_written_by_colmap_read_by_photogram(tmp_path, kind):
    """COLMAP reads the test's rig model (so the test's writer follows its
    layout), writes it with rigs and frames, and photogram reads COLMAP's
    files to the same poses as COLMAP's cam_from_world."""
    write_bin(tmp_path / "m", *rig_scene())
    rec = pycolmap.Reconstruction(str(tmp_path / "m"))
    assert (rec.num_rigs(), rec.num_frames(), rec.num_images()) == (1, 3, 6)
    (tmp_path / "w").mkdir()
    (rec.write_binary if kind == "binary" else rec.write_text)(str(tmp_path / "w"))
    ext = ".bin" if kind == "binary" else ".txt"
    assert (tmp_path / "w" / ("rigs" + ext)).is_file()
    views = {v.name: v for v in read_colmap(tmp_path / "w").views}
    for im in rec.images.values():
        pose = im.cam_from_world()
        assert np.allclose(views[im.name].R_cv, pose.rotation.matrix(), rtol=0, atol=1e-15)
        assert np.allclose(views[im.name].t_cv, pose.translation, rtol=0, atol=1e-15)
