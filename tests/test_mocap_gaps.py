"""Issue 22, item 2: a joint-frame fewer than two cameras observe is a gap,
never a coordinate; a non-finite energy is an error.

Simulated skiing (:func:`photogram.simulation.ski.simulate.simulate_session`)
with 2 and 3 cameras, detections blanked so that chosen joint-frames are
seen by one camera or none: exactly the joint-frames with fewer than two
detections that count (read back from the results' detections.csv) are
empty in joints3d.csv, NaN in joints3d.trc, invalid in joints3d.c3d,
named in metrics.csv's ``gap_joints`` and counted in summary.json ``gaps``.
"""

import csv
import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from photogram.io.trc import read_trc
from photogram.mocap.body.skeleton import SKI24
from photogram.mocap.evaluation.metrics import COM_JOINTS, biomechanics
from photogram.mocap.files import read_joints
from photogram.mocap.reconstruction.filtering import FilterSettings, filter_joints
from photogram.mocap.reconstruction.observability import (BEHIND, DISAGREE, NO_CAMERA,
                                                          NOT_SOLVED, ONE_CAMERA,
                                                          bridge_short_runs, find_gaps,
                                                          observing_cameras)
from photogram.simulation.ski.simproject import write_simulated_project
from photogram.simulation.ski.simulate import simulate_session
from photogram_cli.main import main

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow

J = SKI24.index


def _blanked(n_cameras):
    """A short simulated run with detections removed: (sim, one-camera
    joint-frames, no-camera joint-frames) as sets of (frame, joint)."""
    sim = simulate_session(seed=5, n_runs=1, frames_per_run=60, n_cameras=n_cameras)
    obs = sim.observations.copy()
    C = n_cameras
    obs[20:30, 1:, J("r_knee")] = np.nan            # one camera left (camera 0)
    obs[35:41, :, J("l_hand")] = np.nan             # no camera
    obs[45:48, :C - 1, J("head")] = np.nan          # one camera left (the last)
    if C > 2:
        obs[10:20, 0, J("l_ankle")] = np.nan        # two of three left: still determined
    region = {(f, J("r_knee")) for f in range(20, 30)} | {(f, J("head")) for f in range(45, 48)}
    none = {(f, J("l_hand")) for f in range(35, 41)}
    seen = np.sum(np.isfinite(obs[..., 0]) & (np.nan_to_num(obs[..., 2]) > 0), axis=1)
    one = {(f, j) for f, j in region if seen[f, j] == 1}    # the simulator misses a few
    none |= {(f, j) for f, j in region if seen[f, j] == 0}
    assert len(one) >= len(region) - 2
    return replace(sim, observations=obs), one, none


def _views_written(res: Path, n_frames: int) -> np.ndarray:
    """Cameras per (frame, joint) with a detection of confidence > 0 in the
    results' detections.csv."""
    cams = [set() for _ in range(n_frames * SKI24.n_joints)]
    with open(res / "detections.csv") as handle:
        rows = [r for r in csv.reader(handle) if r and not r[0].startswith("#")]
    head = rows[0]
    for r in rows[1:]:
        d = dict(zip(head, r))
        if float(d["confidence"]) > 0:
            cams[int(d["frame"]) * SKI24.n_joints + J(d["joint"])].add(d["camera"])
    return np.array([len(c) for c in cams]).reshape(n_frames, SKI24.n_joints)


def _run(tmp_path, n_cameras):
    sim, one, none = _blanked(n_cameras)
    write_simulated_project(sim, tmp_path, name="ski")
    assert main(["mocap", "--no-report", "--no-figures", str(tmp_path / "ski.prj"), "-q"]) == 0
    return sim, one, none, tmp_path / "results"


@pytest.fixture(scope="module", params=[2, 3], ids=["2 cameras", "3 cameras"])
def run(request, tmp_path_factory):
    return (request.param, *_run(tmp_path_factory.mktemp(f"gaps{request.param}"),
                                 request.param))


def _written_gaps(res: Path) -> np.ndarray:
    _, X = read_joints(res / "joints3d.csv", SKI24)
    return np.isnan(X).any(-1)


@pytest.mark.filterwarnings("ignore:No analog data")
def test_joint_frames_under_two_cameras_are_gaps_in_every_output(run):
    """Every joint-frame fewer than two cameras detect is empty in joints3d.csv,
    NaN in the TRC, invalid in the C3D and counted by reason in summary.json."""
    n_cameras, sim, one, none, res = run
    F = sim.joints.shape[0]
    views = _views_written(res, F)
    # the blanked joint-frames have the views intended
    assert all(views[f, j] == 1 for f, j in one) and all(views[f, j] == 0 for f, j in none)
    frames, X = read_joints(res / "joints3d.csv", SKI24)
    assert frames.tolist() == list(range(F))
    gap = np.isnan(X).any(-1)
    assert np.array_equal(np.isnan(X).all(-1), gap)
    # every joint-frame fewer than two cameras see is a gap; the others that are
    # gaps are those the reconstruction fits in one camera only (summary.json)
    assert np.all(gap[views < 2])
    if n_cameras > 2:
        assert not gap[10:20, J("l_ankle")].any()
    trc = read_trc(res / "joints3d.trc", rotate_to_z_up=True)
    T = np.stack([trc.markers[n] for n in SKI24.joints], axis=1)
    assert np.array_equal(np.isnan(T).all(-1), gap) and np.array_equal(np.isnan(T).any(-1), gap)
    assert np.allclose(T[~gap], X[~gap], atol=1e-5)
    assert "NaN" in (res / "joints3d.trc").read_text()
    import c3d
    with open(res / "joints3d.c3d", "rb") as handle:
        points = np.array([p for _, p, _ in c3d.Reader(handle).read_frames()])
    assert np.array_equal(points[:, :, 3] == -1, gap)
    assert np.allclose(points[~gap][:, :3] / 1000, X[~gap], atol=1e-4)
    # what is reported is near the truth (2 cameras cannot tell a left/right
    # swap of the simulated detector in one camera: up to 0.8 m in frames 3-5)
    err = np.linalg.norm(X - sim.joints, axis=-1)
    if n_cameras > 2:
        assert np.nanmax(err) < 0.1 and np.nanmean(err) < 0.02
    else:
        assert np.nanmax(err) < 1.0 and np.nanmedian(err) < 0.04
    s = json.loads((res / "summary.json").read_text())
    g = s["gaps"]
    assert g["total"] == int(gap.sum()) and g["joint_frames"] == gap.size
    assert g["by_reason"]["one camera"] == int(np.sum(views == 1))
    assert g["by_reason"]["no camera"] == int(np.sum(views == 0))
    assert g["by_reason"]["cameras disagree"] == int(np.sum(gap & (views >= 2)))
    # ... each of which has a simulated outlier (moved 50-150 px) or swap in a camera
    corrupted = sim.outlier.any(1) | sim.swapped.any(1)[:, None]
    assert np.all(corrupted[gap & (views >= 2)])
    assert g["by_reason"]["not solved"] == g["by_reason"]["behind the cameras"] == 0
    assert g["bridged"] == 0 and g["max_error_px"] == 60.0
    assert g["per_joint"] == {n: int(c) for n, c in zip(SKI24.joints, gap.sum(0)) if c}
    assert any("are gaps" in w and f"{int(gap.sum())} of" in w for w in s["warnings"])
    assert "are gaps" in (res / "log.txt").read_text()


def test_metrics_are_empty_where_a_joint_they_need_is_a_gap_and_flagged(run):
    _, sim, one, none, res = run
    gap = _written_gaps(res)
    with open(res / "metrics.csv") as handle:
        rows = [r for r in csv.reader(handle) if r and not r[0].startswith("#")]
    head, body = rows[0], rows[1:]
    col = {k: [r[i] for r in body] for i, k in enumerate(head)}
    names = np.array(SKI24.joints)
    assert col["gap_joints"] == [" ".join(names[g]) for g in gap]
    com_gap = gap[:, [J(n) for n in COM_JOINTS]].any(1)
    assert [v == "" for v in col["com_x"]] == com_gap.tolist()
    assert [v == "" for v in col["speed"]] == com_gap.tolist()
    knee = gap[:, [J("r_hip"), J("r_knee"), J("r_ankle")]].any(1)
    assert [v == "" for v in col["knee_flexion_r"]] == knee.tolist()
    assert knee[20:30].all() and com_gap[35:41].all() and com_gap[45:48].all()
    # the results folder still loads for the exports (photogram export)
    from photogram.io.trajectories import load_trajectories
    traj = load_trajectories(res)
    M = np.stack([traj.markers[n] for n in SKI24.joints], axis=1)
    assert np.array_equal(np.isnan(M).any(-1), gap)
    assert np.array_equal(np.isnan(traj.mot["knee_flexion_r"]), knee)


def _nan_energy(monkeypatch):
    import photogram.mocap.reconstruction.reconstruct as rc
    solve = rc.solve_gauss_newton

    def diverging(*args, **kwargs):
        a, E, it = solve(*args, **kwargs)
        return a, E * np.nan if kwargs.get("second_order") else E, it   # the last stage
    monkeypatch.setattr(rc, "solve_gauss_newton", diverging)


def test_a_non_finite_energy_is_an_error_and_writes_no_results(tmp_path, monkeypatch, capsys):
    sim = simulate_session(seed=5, n_runs=1, frames_per_run=30, n_cameras=2)
    write_simulated_project(sim, tmp_path, name="ski")
    _nan_energy(monkeypatch)
    assert main(["mocap", "--no-report", str(tmp_path / "ski.prj")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "not finite" in err and "ski.prj" in err
    assert "stage 5 of 5" in err and "nan" in err
    assert not (tmp_path / "results").exists()


# --------------------------------------------------------------------------
def test_observing_cameras_needs_confidence_and_a_point_in_front():
    sim = simulate_session(seed=5, n_runs=1, frames_per_run=20, n_cameras=3)
    obs = sim.observations.copy()
    obs[:, 0, 0, 2] = 0.2
    seen = observing_cameras(obs, 0.3)
    assert not seen[:, 0, 0].any()
    assert np.array_equal(observing_cameras(obs, 0.0, sim.cameras, sim.joints),
                          observing_cameras(obs, 0.0))      # all in front
    X = sim.joints.copy()
    c = sim.cameras
    d = X[:, 0] - c.X0[1]
    X[:, 0] = c.X0[1] - d                                   # head mirrored behind camera 1
    behind = observing_cameras(obs, 0.0, c, X)
    assert not behind[:, 1, 0].any() and np.array_equal(behind[:, :, 1:],
                                                        observing_cameras(obs)[:, :, 1:])


def test_short_runs_are_bridged_only_between_determined_frames_of_a_segment():
    d = np.array([1, 0, 0, 1, 0, 1, 1, 0, 0, 0, 1, 0], bool)[:, None]
    b = bridge_short_runs(d, 2, breaks=())[:, 0].astype(int).tolist()
    assert b == [1, 1, 1, 1, 1, 1, 1, 0, 0, 0, 1, 0]
    assert bridge_short_runs(d, 0)[:, 0].tolist() == d[:, 0].tolist()
    assert bridge_short_runs(d, 3)[7:10, 0].all() and not bridge_short_runs(d, 3)[11, 0]
    assert not bridge_short_runs(d, 2, breaks=[2])[1:3, 0].any()     # never across a break


def test_find_gaps_reasons_and_support_frames():
    sim, one, none = _blanked(2)
    obs = sim.observations
    g = find_gaps(obs)
    views = np.sum(np.isfinite(obs[..., 0]) & (np.nan_to_num(obs[..., 2]) > 0), axis=1)
    assert np.array_equal(g.mask, views < 2)
    assert all(g.reason[f, j] == ONE_CAMERA for f, j in one)
    assert all(g.reason[f, j] == NO_CAMERA for f, j in none)
    wide = find_gaps(obs, support_frames=3)            # the head's 3 frames bridged
    assert not wide.mask[45:48, J("head")].any() and wide.bridged[45:48, J("head")].all()
    assert wide.mask[20:30, J("r_knee")].all()         # 10 frames: not bridged
    s = wide.summary(SKI24.joints)
    assert s["bridged"] == int(wide.bridged.sum()) and s["support_frames"] == 3
    X = np.where(g.mask[..., None], np.nan, sim.joints)
    X[5, J("neck")] = np.nan                             # seen twice but no position
    assert find_gaps(obs, X=X, cameras=sim.cameras).reason[5, J("neck")] == NOT_SOLVED
    c = sim.cameras
    X[7, J("neck")] = 2 * c.X0[0] - sim.joints[7, J("neck")]    # behind camera 0 (of 2)
    g = find_gaps(obs, X=X, cameras=c)
    assert g.reason[7, J("neck")] == BEHIND and g.views[7, J("neck")] == 1
    assert g.summary(SKI24.joints)["by_reason"]["behind the cameras"] == 1
    # a detection 80 px off the true joint: the other camera alone fits it
    T = sim.joints
    moved = obs.copy()
    moved[12, 0, J("r_elbow"), :2] = c.project(T)[12, 0, J("r_elbow")] + [80.0, 0.0]
    moved[12, 1, J("r_elbow"), :2] = c.project(T)[12, 1, J("r_elbow")]
    moved[12, :, J("r_elbow"), 2] = 0.9
    assert find_gaps(moved, X=T, cameras=c).reason[12, J("r_elbow")] == 0
    g = find_gaps(moved, X=T, cameras=c, max_error_px=60.0)
    assert g.reason[12, J("r_elbow")] == DISAGREE and g.views[12, J("r_elbow")] == 1
    assert find_gaps(moved, X=T, cameras=c, max_error_px=90.0).reason[12, J("r_elbow")] == 0


def test_the_post_filter_filters_the_runs_between_gaps_on_their_own():
    fps = 50.0
    t = np.arange(200) / fps
    x = np.sin(2 * np.pi * 1.0 * t) + 0.05 * np.random.default_rng(1).normal(size=t.size)
    X = np.repeat(x[:, None, None], 3, axis=2)          # (F, 1, 3)
    X[60:70] = np.nan                                   # a gap
    X[150:155, 0, 1] = np.nan                           # a gap in one coordinate
    Y, report = filter_joints(X, fps, FilterSettings())
    assert np.array_equal(np.isnan(Y), np.isnan(X))     # gaps stay gaps
    alone, _ = filter_joints(X[:60], fps, FilterSettings())
    assert np.allclose(Y[:60], alone)                   # the runs filtered on their own
    after, _ = filter_joints(X[70:], fps, FilterSettings())
    assert np.allclose(Y[70:150, 0, 0], after[:80, 0, 0])
    assert not np.allclose(Y[:60], X[:60])               # filtered, not copied
    assert report["runs_filtered"] == 2 + 3 + 2          # x, y (split twice), z


def test_biomechanics_with_gaps():
    sim = simulate_session(seed=5, n_runs=1, frames_per_run=40, n_cameras=2)
    gaps = np.zeros((40, SKI24.n_joints), bool)
    gaps[5, J("r_knee")] = True
    gaps[10, J("l_toes")] = True
    gaps[15, J("r_pole")] = True                        # not a CoM joint
    X = np.where(gaps[..., None], np.nan, sim.joints)
    b = biomechanics(X, SKI24, sim.fps, gaps=gaps)
    assert np.isnan(b["knee_flexion_r"][5]) and np.isfinite(b["knee_flexion_l"][5])
    assert np.isnan(b["com_x"][5]) and np.isnan(b["com_x"][10]) and np.isnan(b["speed"][10])
    assert np.isnan(b["fore_aft_angle"][10]) and b["outside"][10] in ("r", "l")
    assert b["outside"][5] == "" and np.isnan(b["fore_aft_distance"][5])
    full = biomechanics(sim.joints, SKI24, sim.fps)
    assert b["com_x"][15] == full["com_x"][15] and np.isfinite(b["lean"][15])
    ok = ~gaps[:, [J(n) for n in COM_JOINTS]].any(1)
    assert np.allclose(b["com_x"][ok], full["com_x"][ok])
    # without the mask a missing segment is left out (the skeleton lacks it)
    assert np.isfinite(biomechanics(X, SKI24, sim.fps)["com_x"][10])


def test_mark_gaps_finds_the_gaps_of_a_solve_that_did_not_mark_them():
    """The estimated-rotation solve leaves its gaps to the pipeline."""
    from photogram.mocap.reconstruction.reconstruct import (Reconstruction,
                                                            ReconstructionSettings)
    from photogram.mocap.stages import mark_gaps
    sim, one, none = _blanked(2)
    rec = Reconstruction(joints=sim.joints.copy(), n_views=None, limb_lengths=None,
                         energy=1.0, iterations=1, seconds=0.0, solver="test", n_windows=1)
    warnings = []
    out = mark_gaps(rec, sim.observations, sim.cameras, SKI24, ReconstructionSettings(), [],
                    warnings)
    views = np.sum(np.isfinite(sim.observations[..., 0])
                   & (np.nan_to_num(sim.observations[..., 2]) > 0), axis=1)
    gap = np.isnan(out.joints).any(-1)
    assert np.array_equal(out.gaps.mask, gap) and np.all(gap[views < 2])
    # with the true joints only the simulated outliers and swaps disagree
    corrupted = sim.outlier.any(1) | sim.swapped.any(1)[:, None]
    assert np.all(corrupted[gap & (views >= 2)])
    assert len(warnings) == 1 and f"{out.gaps.total} of 1440" in warnings[0]
    assert not np.isnan(rec.joints).any()                  # the input is not changed
