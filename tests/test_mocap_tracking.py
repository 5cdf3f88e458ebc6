"""Athlete tracking (section 4.1), the observation sources and the plugin
detector on crops of synthetic images."""

import json

import numpy as np
import pytest

from photogram.errors import InputError
from photogram.mocap.body.skeleton import BODY25B, COCO17, SKI24
from photogram.mocap.sources.csv import CsvSource
from photogram.mocap.sources.openpose import read_openpose_folder
from photogram.mocap.sources.plugin import PluginDetector, load_function
from photogram.mocap.tracking.athlete import (TrackingSettings, clean_boxes, crop_image,
                                              crop_to_full, gaussian_smooth, select_person,
                                              track_detections)
from photogram.mocap.tracking.crop_tracking import track_images
from photogram.mocap.tracking.detections import CameraDetections

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow


def _person(cx, cy, h, conf, J=17):
    j = np.zeros((J, 3))
    j[:, 0] = cx + np.linspace(-h / 4, h / 4, J)
    j[:, 1] = cy + np.linspace(-h / 2, h / 2, J)
    j[:, 2] = conf
    return j


def test_main_person_is_chosen_consistently_next_to_a_bystander():
    frames, joints = [], []
    for f in range(30):
        if f != 12:                                   # the athlete is missed in frame 12
            frames.append(f)
            joints.append(_person(300 + 5 * f, 400, 500, 0.6))
        frames.append(f)
        joints.append(_person(60, 300, 200, 0.4))     # bystander at the side
    det = CameraDetections.from_joints("c", COCO17, frames, np.array(joints), 30)
    rows = select_person(det)
    assert rows[12] == -1
    chosen = det.joints[rows[rows >= 0]]
    assert np.all(chosen[:, 0, 2] == 0.6)
    tracked = track_detections(det)
    assert np.isnan(tracked.joints[12, 0, 0]) and np.isfinite(tracked.boxes[12]).all()
    side = tracked.boxes[:, 2] - tracked.boxes[:, 0]
    assert np.allclose(side, 1.5 * 500, rtol=0.02)


def test_a_detection_leaving_the_last_good_box_is_replaced():
    boxes = np.array([[0, 0, 10, 10], [1, 1, 11, 11], [50, 50, 60, 60], [2, 2, 12, 12]], float)
    assert clean_boxes(boxes).tolist() == [True, True, False, True]


def test_gaussian_smoothing_is_normalised_over_valid_frames():
    x = np.full(100, 3.0)
    valid = np.ones(100, bool)
    valid[40:45] = False
    x[~valid] = 1e6
    assert np.allclose(gaussian_smooth(x, valid, 10.0), 3.0)


def test_crop_round_trip():
    img = np.zeros((200, 300, 3), np.uint8)
    img[90:110, 140:160] = 255
    box = (100.0, 50.0, 250.0, 200.0)
    crop = crop_image(img, box, 100)
    ys, xs = np.nonzero(crop[..., 0] > 128)
    centre = crop_to_full(np.array([[xs.mean(), ys.mean(), 1.0]]), box, 100)
    assert np.allclose(centre[0, :2], (149.5, 99.5), atol=1.0)


NETWORK = '''
import numpy as np

def detect(image):
    """17 COCO joints on the bright square of an RGB crop."""
    ys, xs = np.nonzero(image[..., 0] > 128)
    if len(xs) == 0:
        return None
    x0, x1, y0, y1 = xs.min(), xs.max(), ys.min(), ys.max()
    j = np.zeros((17, 3))
    j[:, 0] = np.linspace(x0, x1, 17)
    j[:, 1] = np.linspace(y0, y1, 17)
    j[:, 2] = 0.9
    return j
'''


def test_plugin_network_on_crops_follows_the_athlete(tmp_path):
    (tmp_path / "mynet.py").write_text(NETWORK)
    detector = PluginDetector(load_function("mynet:detect", tmp_path, allow=True), COCO17,
                              "mynet:detect")
    images, truth = [], []
    for f in range(12):
        img = np.zeros((240, 320, 3), np.uint8)
        x = 60 + 10 * f
        img[100:160, x:x + 30] = 255
        images.append(img)
        truth.append((x, 100))
    t = track_images(images, detector, "cam", TrackingSettings(crop_size=120, sigma_centre=2,
                                                               sigma_side=5, sigma_refine=2))
    assert t.joints.shape == (12, 17, 3)
    assert np.allclose(t.joints[:, 0, :2], truth, atol=2.5)
    with pytest.raises(InputError, match="cannot import module"):
        load_function("nomodule_xyz:detect", tmp_path, allow=True)
    with pytest.raises(InputError, match="shape"):
        PluginDetector(lambda img: np.zeros((3, 3)), COCO17)(images[0])


def test_openpose_folder_with_two_people(tmp_path):
    folder = tmp_path / "cam1_json"
    folder.mkdir()
    for f in range(3):
        people = []
        for k in range(2):
            kp = np.zeros((25, 3))
            kp[:, 0], kp[:, 1], kp[:, 2] = 100 * (k + 1) + f, 200, 0.5 + 0.1 * k
            kp[3] = 0
            people.append({"person_id": [-1], "pose_keypoints_2d": kp.ravel().tolist()})
        (folder / f"cam01.{f:04d}.json").write_text(json.dumps({"version": 1.3,
                                                                  "people": people}))
    det = read_openpose_folder(folder, BODY25B, "cam_01")
    assert det.n_frames == 3 and len(det.frames) == 6
    assert np.isnan(det.joints[0, 3, 0]) and det.joints[0, 3, 2] == 0
    with pytest.raises(InputError, match="keypoints"):
        read_openpose_folder(folder, COCO17)


def test_csv_source_errors_name_the_line(tmp_path):
    p = tmp_path / "det.csv"
    p.write_text("frame,camera,joint,x,y,confidence\n3,C1,head,1,2,0.9\n4,C9,head,1,2,0.9\n")
    with pytest.raises(InputError) as exc:
        CsvSource(p, SKI24, ["C1", "C2"])
    assert exc.value.line == 3 and "C9" in exc.value.what
    p.write_text("frame,camera,joint,x,y,confidence\n3,C1,head,1,2,0.9\n5,C1,nose,1,2,0.9\n")
    with pytest.raises(InputError, match="unknown joint 'nose'"):
        CsvSource(p, SKI24, ["C1"])
    p.write_text("frame,camera,joint,x,y,confidence\n3,C1,head,1,2,0.9\n5,C1,neck,4,5,0.8\n")
    src = CsvSource(p, SKI24, ["C1", "C2"])
    det = src.detections("C1")
    assert src.first_frame == 3 and det.n_frames == 3 and det.frames.tolist() == [0, 2]
    assert np.allclose(det.joints[1, 1], (4, 5, 0.8))


def test_plugin_source_end_to_end_through_the_command(tmp_path, capsys):
    """kind = "plugin": images per camera, the network on crops, reconstruction."""
    import cv2

    from photogram_cli.main import main
    (tmp_path / "mynet.py").write_text(NETWORK)
    for cam in ("A", "B"):
        (tmp_path / cam).mkdir()
        for f in range(8):
            img = np.zeros((120, 160, 3), np.uint8)
            x = 40 + 4 * f + (10 if cam == "B" else 0)
            img[30:90, x:x + 20] = 255
            cv2.imwrite(str(tmp_path / cam / f"{f:03d}.png"), img)
    (tmp_path / "stations.csv").write_text(
        "station,camera,X0,Y0,Z0,omega,phi,kappa\nA,A,0,-10,1,90,0,0\nB,B,3,-10,1,90,10,0\n")
    cams = "".join(f'[cameras.{c}]\nmodel = "opencv"\nimage_size = [160, 120]\nfx = 200.0\n'
                   f'fy = 200.0\ncx = 80.0\ncy = 60.0\n\n' for c in "AB")
    (tmp_path / "p.prj").write_text(
        '[project]\nname = "p"\n\n' + cams + '[stations]\nfile = "stations.csv"\n\n'
        '[mocap]\nfps = 25\n\n[mocap.source]\nkind = "plugin"\nnetwork = "mynet:detect"\n'
        'skeleton = "coco17"\ncameras = { A = "A", B = "B" }\n\n'
        '[mocap.tracking]\ncrop_size = 64\nsigma_centre = 2\nsigma_side = 4\n')
    assert main(["mocap", "--no-report", "--no-figures", "-q", "--allow-plugin",
                 str(tmp_path / "p.prj")]) == 0
    det = (tmp_path / "results" / "detections.csv").read_text().splitlines()
    assert len(det) == 2 + 2 * 8 * 17
    (tmp_path / "p.prj").write_text((tmp_path / "p.prj").read_text().replace(
        "mynet:detect", "mynet:nothing"))
    assert main(["mocap", "--no-report", str(tmp_path / "p.prj"), "--force", "--allow-plugin"]) == 2
    assert "has no function 'nothing'" in capsys.readouterr().err
