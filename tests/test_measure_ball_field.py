"""Balls in `photogram measure` (``shape = "ball"``): the corner frame of
tests/test_measure_space.py with its dots replaced by bright balls resting
on the floor and walls (radius 30 mm, rendered by
:func:`photogram.measure.sphere.render_balls`), numbered by DLT from the
nine ArUco markers; the outline centres are corrected by the ball's
eccentricity (from the image's DLT) and compared with the true image of
each ball's centre."""

import json

import cv2
import numpy as np
import pytest

from photogram.measure.render import PlaneCamera, look_at
from photogram.measure.render3d import corner_frame, project3, render_plates
from photogram.measure.sphere import ball_eccentricity, render_balls
from photogram_cli.main import main

from test_measure_space import EYES

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow

RADIUS = 0.03


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    folder = tmp_path_factory.mktemp("balls")
    plates, _ = corner_frame(radius=RADIUS)
    markers = [p for p in plates if p.kind == "aruco"]
    balls = {p.id: p.X + RADIUS * p.normal for p in plates if p.kind == "dot"}
    K = np.array([[800.0, 0, 399.5], [0, 800, 299.5], [0, 0, 1]])
    (folder / "images").mkdir()
    truth, ecc = {}, {}
    for name, eye in EYES.items():
        R, t = look_at(eye, (0.4, 0.4, 0.35), up=(0, 0, 1))
        cam = PlaneCamera(K, R, t, (800, 600))          # no distortion (render_balls)
        flat = render_plates(markers, cam).astype(np.float64)
        ball = render_balls(np.array(list(balls.values())), RADIUS, K, R, t, (800, 600),
                            background=0.0)
        img = cv2.GaussianBlur(np.maximum(flat, ball.astype(np.float64)), (0, 0), 0.8)
        img += np.random.default_rng(len(truth)).normal(0, 2.0, img.shape)
        img = np.clip(np.rint(img), 0, 255).astype(np.uint8)
        cv2.imwrite(str(folder / "images" / f"{name}.png"), img)
        truth[name] = {k: project3(cam, X)[0] for k, X in balls.items()}
        ecc[name] = {k: ball_eccentricity(K, R @ X + t, RADIUS) for k, X in balls.items()}
    rng = np.random.default_rng(0)
    rows = ["id,kind,X,Y,Z"] + [f"{k},tie,{X[0] + rng.normal(0, 0.005):.4f},"
                                f"{X[1] + rng.normal(0, 0.005):.4f},"
                                f"{X[2] + rng.normal(0, 0.005):.4f}" for k, X in balls.items()]
    (folder / "balls.csv").write_text("\n".join(rows) + "\n")
    mk = [f'[[aruco.marker]]\nid = {p.marker}\npoint = "{p.id}"\n'
          f'xyz = [{p.X[0]}, {p.X[1]}, {p.X[2]}]' for p in markers]
    (folder / "frame.toml").write_text(
        '[field]\nname = "balls"\nimages = "images"\npolarity = "bright"\nshape = "ball"\n'
        f'diameter = {2 * RADIUS}\nmin_diameter = 4\nmax_diameter = 60\n\n'
        '[aruco]\ndictionary = "DICT_4X4_50"\n' + "\n".join(mk)
        + '\n\n[targets]\nfile = "balls.csv"\n')
    return folder, truth, ecc


def _table(folder):
    out = {}
    for line in (folder / "image_points.csv").read_text().splitlines()[2:]:
        st, pt, x, y, _ = line.split(",")
        if not pt.startswith("A"):
            out[st, pt] = np.array([float(x), float(y)]) - 0.5     # OpenCV pixel centres
    return out


def test_balls_measured_with_their_eccentricity(scene):
    folder, truth, ecc = scene
    rms, tab = {}, {}
    for flag, out in ((True, "with"), (False, "without")):
        args = ["measure", str(folder / "frame.toml"), "--output", str(folder / out),
                "--no-report", "-q"] + ([] if flag else ["--no-eccentricity"])
        assert main(args) == 0
        tab[flag] = _table(folder / out)
        e = np.array([xy - truth[st][pt] for (st, pt), xy in tab[flag].items()])
        n_true = sum(len(v) for v in truth.values())
        print(f"{out}: {len(e)} of {n_true} ball images numbered")
        assert len(e) >= 0.95 * n_true            # merged pairs are rejected
        assert np.hypot(*e.T).max() < 0.5                          # no wrong label
        rms[flag] = float(np.sqrt((e ** 2).sum(axis=1).mean()))
    keys = sorted(set(tab[True]) & set(tab[False]))
    true_ecc = np.array([ecc[st][pt] for st, pt in keys])
    applied = np.array([tab[False][k] - tab[True][k] for k in keys])
    dev = np.hypot(*(applied - true_ecc).T)
    size = np.hypot(*true_ecc.T)
    print(f"ball eccentricity: max {size.max():.3f} px, RMS {np.sqrt((size ** 2).mean()):.3f}; "
          f"applied minus true: max {dev.max():.4f} px; centres RMS {rms[True]:.4f} px "
          f"corrected, {rms[False]:.4f} px uncorrected")
    assert size.max() > 0.05                           # a scene where it matters
    assert dev.max() < 0.1 * size.max()                # the correction is the ball's
    assert rms[True] < 0.05 and rms[True] < rms[False]
    assert json.loads((folder / "with" / "summary.json").read_text())[
        "eccentricity_correction"] is True
    # balls have no normal: no [targets] snippet for the adjustment
    assert not (folder / "without" / "targets.toml").exists()


def test_unknown_shape_is_one_line(scene, tmp_path, capsys):
    folder = scene[0]
    bad = folder / "cube.toml"
    bad.write_text((folder / "frame.toml").read_text().replace('shape = "ball"',
                                                                'shape = "cube"'))
    assert main(["measure", str(bad), "--output", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "shape" in err[0] and "cube.toml" in err[0]
    assert not (tmp_path / "out").exists()
    plain = folder / "plain.toml"
    plain.write_text((folder / "frame.toml").read_text().replace('[targets]\nfile = "balls.csv"',
                                                                 ""))
    assert main(["measure", str(plain), "--output", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "table of targets" in err[0]
    assert not (tmp_path / "out").exists()
