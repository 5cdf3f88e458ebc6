"""Issue 20, item 5: synchronisation of the cameras of photogram mocap
(photogram.mocap.evaluation.sync), the per-camera median residual vector,
and the bad inputs of ``offsets``."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from photogram.mocap.evaluation.checks import check_bias
from photogram.mocap.evaluation.metrics import median_residual
from photogram.mocap.evaluation.sync import (apply_offsets, estimate_offsets, shift_observations,
                                             shift_series)
from photogram_cli.main import main

from benchmark_modules import load_benchmark

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[1]
DEMO = ROOT / "projects" / "pose2sim-demo" / "demo.prj"
DATA = ROOT.parent / "shared" / "data" / "pose2sim-demo"


def _bench():
    return load_benchmark("mocap_sync")


@pytest.fixture(scope="module")
def sim():
    from photogram.simulation.ski.simulate import simulate_session
    return simulate_session(seed=8)


def test_shift_series_integer_fractional_and_edges():
    a = np.arange(10.0)[:, None] * np.array([1.0, 2.0])
    b = shift_series(a, 2)
    assert np.array_equal(b[:8], a[2:]) and np.all(np.isnan(b[8:]))
    c = shift_series(a, -1.25)
    assert np.all(np.isnan(c[:2]))
    assert np.allclose(c[2:], (np.arange(2, 10.0)[:, None] - 1.25) * [1.0, 2.0])  # exact
    d = shift_series(a, 3.5, edge=True)
    assert np.allclose(d[-1], a[-1])                       # edge frame repeated


def test_shift_observations_needs_both_neighbours():
    obs = np.zeros((6, 2, 3))
    obs[..., 0] = np.arange(6)[:, None]
    obs[..., 1] = 1.0
    obs[..., 2] = 0.9
    obs[3, 0] = [np.nan, np.nan, 0.0]                      # missing
    out = shift_observations(obs, 0.5)
    assert np.isclose(out[0, 0, 0], 0.5) and np.isclose(out[0, 0, 2], 0.9)
    assert np.isnan(out[2, 0, 0]) and out[2, 0, 2] == 0   # between 2 and the missing 3
    assert np.isnan(out[5, 1, 0])                          # beyond the end


def test_lagged_correlation_finds_a_known_lag():
    """Pose2Sim's time-lagged Pearson correlation: ``other[f + k] = ref[f]``."""
    from photogram.mocap.evaluation.sync import lagged_correlation
    rng = np.random.default_rng(4)
    ref = np.convolve(rng.normal(size=300), np.ones(7) / 7, mode="same")
    other = np.roll(ref, 5) * 3.0 + 10.0                   # scale and offset do not matter
    lags, r = lagged_correlation(ref[20:-20], other[20:-20], 12)
    assert lags[np.nanargmax(r)] == 5 and np.nanmax(r) > 0.99


def test_a_camera_without_detections_gets_no_offset(sim):
    bench = _bench()
    obs, cams = bench.desynchronised(sim, {1: 2.0}, np.random.default_rng(5))
    obs[:, 5, :, :2] = np.nan
    obs[:, 5, :, 2] = 0.0
    est = estimate_offsets(obs, cams, sim.fps, reference=0)
    assert np.isnan(est.offsets[5]) and abs(est.offsets[1] - 2.0) < 0.05
    d = est.as_dict()["cameras"]
    assert d["C6"]["offset"] is None and d["C2"]["speed_lag"] is not None
    json.dumps(est.as_dict(), allow_nan=False)


def _check_recovered(est, truth, max_err, max_z):
    err = est.offsets - truth
    z = np.abs(err[1:]) / est.sigma[1:]
    assert np.all(np.abs(err) <= max_err), (err, est.sigma)
    assert np.all(z <= max_z), (err, est.sigma)
    return err, z


def test_known_integer_and_fractional_offsets_are_recovered(sim):
    """SIMULATED: C2 +2, C3 -1.4, C4 +0.5, C5 -3 frames (truth re-sampled
    in time, per-frame rotations and zoom shifted alike)."""
    bench = _bench()
    obs, cams = bench.desynchronised(sim, bench.TRUE_OFFSETS, np.random.default_rng(11))
    truth = np.array([bench.TRUE_OFFSETS.get(c, 0.0) for c in range(6)])
    est = estimate_offsets(obs, cams, sim.fps, reference=0, seed=1)
    assert np.all(np.abs(est.coarse - truth) <= 0.5 + 1e-9), est.coarse
    err, z = _check_recovered(est, truth, 0.06, 4.0)
    assert np.mean(z <= 2.0) >= 0.6                        # the sigma is not a fiction
    # applying the estimate re-synchronises: a second estimate is ~0
    obs2, cams2 = apply_offsets(obs, cams, {c: o for c, o in enumerate(est.offsets)})
    again = estimate_offsets(obs2, cams2, sim.fps, reference=0, seed=2)
    assert np.all(np.abs(again.offsets) < 0.1), again.offsets


def test_harsh_setting(sim):
    """Noise x 3, 15 % outliers, one camera with 30 % of the frames (not
    tuned on): every offset within 3 sigma and 0.1 frame."""
    bench = _bench()
    rng = np.random.default_rng(21)
    obs, cams = bench.desynchronised(sim, bench.TRUE_OFFSETS, rng, noise=3.0, outliers=0.15,
                                     few=2)
    truth = np.array([bench.TRUE_OFFSETS.get(c, 0.0) for c in range(6)])
    est = estimate_offsets(obs, cams, sim.fps, reference=0, seed=3)
    err = est.offsets - truth
    assert np.all(np.abs(err) <= 3 * est.sigma), (err, est.sigma)
    assert np.all(np.abs(err) < 0.1), (err, est.sigma)
    assert est.sigma[2] > est.sigma[[1, 3, 4, 5]].min()   # fewer detections, wider


@pytest.mark.skipif(not DATA.is_dir(), reason="Pose2Sim demo data absent")
def test_pose2sim_demo_cam03_is_synchronised():
    """REAL: cam_03's offset is compatible with 0 (its large errors are a
    static bias), and a shift of its detections by 2 frames is found."""
    from photogram.mocap.files import cameras_from_project
    from photogram.mocap.pipeline import _observations
    from photogram.project import read_project
    project = read_project(DEMO)
    cams = cameras_from_project(project)
    _, _, obs = _observations(project, cams)
    est = estimate_offsets(obs, cams, 60.0, reference=0)
    c = cams.index("cam_03")
    assert abs(est.offsets[c]) < 3 * est.sigma[c] and abs(est.offsets[c]) < 0.5
    moved = obs.copy()
    moved[:, c] = shift_observations(obs[:, c], -2.0)
    est2 = estimate_offsets(moved, cams, 60.0, reference=0)
    assert abs(est2.offsets[c] - est.offsets[c] - 2.0) < 3 * est.sigma[c]


def test_median_residual_vector_and_bias_warning():
    rng = np.random.default_rng(0)
    proj = rng.uniform(0, 1000, (50, 3, 10, 2))
    det = proj + rng.normal(0, 3, proj.shape)
    det[:, 1] += [24.0, -19.0]                             # injected static bias
    use = np.ones((50, 3, 10), bool)
    vec = median_residual(proj, det, use)
    assert np.allclose(vec[1], [24.0, -19.0], atol=0.6)
    assert np.all(np.abs(vec[[0, 2]]) < 0.6)
    err = np.linalg.norm(det - proj, axis=-1)
    rep = {f"c{c}": {"median_px": float(np.median(err[:, c])), "median_dx_px": vec[c, 0],
                     "median_dy_px": vec[c, 1]} for c in range(3)}
    notes = check_bias(rep)
    assert len(notes) == 1 and "c1 (+24" in notes[0] and "c0" not in notes[0]


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    from photogram.simulation.ski.simproject import write_simulated_project
    from photogram.simulation.ski.simulate import simulate_session
    folder = tmp_path_factory.mktemp("ski-sync")
    write_simulated_project(simulate_session(seed=5, frames_per_run=40), folder, name="ski")
    return folder


@pytest.fixture
def project(base, tmp_path):
    shutil.copytree(base, tmp_path / "p")
    return tmp_path / "p" / "ski.prj"


def _shift_csv_pixels(path, camera, dx, dy):
    lines = path.read_text().splitlines()
    header = None
    for i, line in enumerate(lines):
        if line.startswith("#"):
            continue
        f = line.split(",")
        if header is None:
            header = f
            continue
        if f[header.index("camera")] == camera and f[header.index("x")]:
            f[header.index("x")] = f"{float(f[header.index('x')]) + dx:.2f}"
            f[header.index("y")] = f"{float(f[header.index('y')]) + dy:.2f}"
            lines[i] = ",".join(f)
    path.write_text("\n".join(lines) + "\n")


def test_injected_bias_in_results_and_estimate_reported(project):
    """A camera whose detections are shifted by (+25, -15) px: its median
    residual vector in summary.json and reprojection.csv, the warning; and
    offsets = "report" gives offsets near 0 without applying them."""
    _shift_csv_pixels(project.parent / "detections.csv", "C3", 25.0, -15.0)
    text = project.read_text().replace("[mocap]\n", '[mocap]\noffsets = "report"\n', 1)
    project.write_text(text)
    assert main(["mocap", "--no-report", "-q", str(project)]) == 0
    s = json.loads((project.parent / "results" / "summary.json").read_text())
    r = s["reprojection"]["C3"]
    assert abs(r["median_dx_px"] - 25) < 3 and abs(r["median_dy_px"] + 15) < 3
    others = [np.hypot(v["median_dx_px"], v["median_dy_px"]) for k, v in
              s["reprojection"].items() if k != "C3"]
    # the default sigma^2 = 400 px^2 lets part of C3's 29 px bias into the
    # reconstruction: the others' vectors reach 2.1 px (0.4 px with the
    # paper's 100 px^2; C3's own (+22.9, -14.0) instead of (+24.6, -14.6))
    assert max(others) < 2.5
    assert any("static bias" in w and "C3" in w for w in s["warnings"])
    csv = (project.parent / "results" / "reprojection.csv").read_text()
    assert "median_dx_px" in csv.splitlines()[0]
    pypdf = pytest.importorskip("pypdf")
    assert main(["report", str(project.parent / "results")]) == 0
    text = "\n".join(p.extract_text() for p in
                     pypdf.PdfReader(str(project.parent / "results" / "report.pdf")).pages)
    # the cameras page (photogram/report/pages_mocap.py): "C3  100.0 %  median  (dx, dy) ..."
    row = next(line for line in text.splitlines() if line.split()[:1] == ["C3"]
               and "%" in line)
    dx = float(re.search(r"\(([-+][\d.]+), [-+][\d.]+\)", row).group(1))
    assert abs(dx - r["median_dx_px"]) < 0.01 * abs(r["median_dx_px"])
    sync = s["synchronisation"]
    assert sync["mode"] == "report" and sync["applied"] == {}
    for name, c in sync["estimate"]["cameras"].items():
        assert abs(c["offset"]) < max(3 * c["sigma"], 0.1), (name, c)


@pytest.mark.parametrize("value, words", [
    ("{ C9 = 1 }", ["C9", "does not have", "cameras: C1"]),
    ('{ C2 = "one" }', ["C2", "number of frames"]),
    ("{ C2 = 40 }", ["C2", "not shorter than the sequence", "-39 and 39"]),
    ('"guess"', ["offsets", "estimate"]),
])
def test_bad_offsets_are_one_line_and_exit_2(project, capsys, value, words):
    text = project.read_text().replace("[mocap]\n", f"[mocap]\noffsets = {value}\n", 1)
    project.write_text(text)
    capsys.readouterr()
    assert main(["mocap", "--no-report", str(project)]) == 2
    out, err = capsys.readouterr()
    assert out == "" and len(err.strip().splitlines()) == 1, err
    assert "ski.prj" in err
    for w in words:
        assert w in err, err


def _delay_camera(folder: Path, camera: str, frames: int, last: int):
    """Re-number ``camera``'s rows of detections.csv and camera_frames.csv
    as a camera started ``frames`` frames earlier (its frame f + frames
    shows frame f); its first camera_frames rows repeat frame 0."""
    for name in ("detections.csv", "camera_frames.csv"):
        path = folder / name
        lines = path.read_text().splitlines()
        out, header, first_rows = [], None, []
        for line in lines:
            if line.startswith("#"):
                out.append(line)
                continue
            f = line.split(",")
            if header is None:
                header = f
                out.append(line)
                continue
            if f[header.index("camera")] != camera:
                out.append(line)
                continue
            frame = int(f[0])
            if name == "camera_frames.csv" and frame == 0:
                first_rows += [",".join([str(k)] + f[1:]) for k in range(frames)]
            if frame + frames <= last:
                out.append(",".join([str(frame + frames)] + f[1:]))
        path.write_text("\n".join(out + first_rows) + "\n")


def test_offsets_applied_and_estimated_in_a_run(project):
    """SIMULATED end to end: camera C3 recorded 2 frames early (detections
    and per-frame rotations/zoom re-numbered). Unapplied, C3 does not fit;
    offsets = { C3 = 2 } restores it; "estimate" finds +2 and applies it.
    (The estimate runs on the detections before the athlete's multi-view
    choice, which would otherwise leave the unsynchronised camera out.)"""
    _delay_camera(project.parent, "C3", 2, 39)
    text = project.read_text()

    def run(extra):
        project.write_text(text.replace("[mocap]\n", f"[mocap]\n{extra}\n", 1))
        assert main(["mocap", "--no-report", "--no-figures", "-q", "--force", str(project)]) == 0
        return json.loads((project.parent / "results" / "summary.json").read_text())

    raw, given, est = run(""), run("offsets = { C3 = 2 }"), run('offsets = "estimate"')
    med = {k: s["reprojection"]["C3"]["median_px"] for k, s in
           (("raw", raw), ("given", given), ("est", est))}
    others = max(v["median_px"] for k, v in given["reprojection"].items() if k != "C3")
    # unapplied, C3 does not fit: far off, or (the multi-view choice of the
    # athlete, issue 20 item 4) left out of the observations as inconsistent
    assert (med["raw"] is None or med["raw"] > 5 * others) and med["given"] < 1.5 * others, med
    assert given["synchronisation"]["applied"] == {"C3": 2.0}
    cams = est["synchronisation"]["estimate"]["cameras"]
    assert abs(cams["C3"]["offset"] - 2.0) < max(3 * cams["C3"]["sigma"], 0.1), cams["C3"]
    assert all(abs(c["offset"]) < max(3 * c["sigma"], 0.1) for n, c in cams.items() if n != "C3")
    assert abs(est["synchronisation"]["applied"]["C3"] - 2.0) < 0.1
    assert est["reprojection"]["C3"]["median_px"] < 1.5 * others
    print({k: s["accuracy"]["mpjpe"] for k, s in (("raw", raw), ("given", given), ("est", est))})
    assert est["accuracy"]["mpjpe"] <= 1.1 * given["accuracy"]["mpjpe"]


def test_candidates_renumbered_by_whole_frames():
    """The multi-view choice sees a synchronised camera's candidates
    renumbered like its detections: frame f + k becomes frame f."""
    from photogram.mocap.body.skeleton import get_skeleton
    from photogram.mocap.stages import shift_candidates as _shift_candidates
    from photogram.mocap.tracking.detections import CameraDetections
    sk = get_skeleton("coco17")
    frames = np.array([0, 1, 1, 2, 4])
    joints = np.zeros((5, sk.n_joints, 3))
    joints[..., 0] = np.arange(5)[:, None]             # x tells the row
    det = CameraDetections.from_joints("C1", sk, frames, joints, n_frames=5)
    rows = np.array([0, 2, 3, -1, 4])                  # chosen row per frame
    d2, r2 = _shift_candidates(det, rows, 1)
    assert list(d2.frames) == [0, 0, 1, 3]             # frame 0 dropped, the rest one earlier
    # new frame f = old frame f + 1: rows 2 (x=2), 3 (x=3), none, 4 (x=4), none
    assert [d2.joints[r, 0, 0] if r >= 0 else None for r in r2] == [2, 3, None, 4, None]
    d3, r3 = _shift_candidates(det, rows, -2)
    assert list(d3.frames) == [2, 3, 3, 4]             # frame 4 falls off the end
    assert [d3.joints[r, 0, 0] if r >= 0 else None for r in r3] == [None, None, 0, 2, 3]
