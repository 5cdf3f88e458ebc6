"""The harsh setting of the ski simulator (issue 22, item 6): the shipped
project is what its generator writes, and every degradation has the
statistics its settings say (SIMULATED data, truth known)."""

import runpy
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from photogram.geometry.rotations import matrix_to_rodrigues
from photogram.mocap.body.skeleton import SKI24
from photogram.mocap.evaluation.metrics import pck
from photogram.simulation.ski.harsh import (HarshSettings, simulate_harsh,
                                            simulated_rotation_differences, two_cameras)
from photogram.simulation.ski.harsh_detector import image_height
from photogram.simulation.ski.harsh_eval import undetermined_joint_frames, used_people

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = ROOT / "projects" / "ski-ptz-harsh"


@pytest.fixture(scope="module", params=[22, 23], ids=["seed22", "seed23"])
def sim(request):
    return simulate_harsh(seed=request.param)


def _athlete_errors(sim):
    o, xy = sim.observations, sim.image_truth
    seen = o[..., 2] > 0
    return np.linalg.norm(o[..., :2] - xy, axis=-1)[seen], seen


@pytest.mark.slow
def test_shipped_project_is_reproducible(tmp_path):
    """projects/ski-ptz-harsh is exactly what generate.py writes (every file)."""
    written = runpy.run_path(str(SHIPPED / "generate.py"), run_name="gen")
    written["main"](["--out", str(tmp_path)])
    files = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*") if p.is_file())
    assert len(files) == 14
    for f in files:
        assert (tmp_path / f).read_bytes() == (SHIPPED / f).read_bytes(), f
        if f.suffix in (".csv", ".prj"):
            assert (SHIPPED / f).read_text().startswith("# SIMULATED data"), f
    size = sum((SHIPPED / f).stat().st_size for f in files)
    assert size < 6e6


def test_projects_read_with_three_modes():
    from photogram.project import read_project
    known = read_project(SHIPPED / "ski-ptz-harsh.prj")
    est = read_project(SHIPPED / "ski-ptz-harsh-estimate.prj")
    two = read_project(SHIPPED / "two-cameras" / "ski-ptz-harsh-2cam.prj")
    assert known.mocap.rotation != "estimate" and est.mocap.rotation == "estimate"
    assert sorted(two.cameras) == ["C3", "C5"] and len(known.cameras) == 6


def test_detector_error_pck_and_outliers_match_the_settings(sim):
    st = sim.settings
    err, seen = _athlete_errors(sim)
    assert 16.0 < err.mean() < 24.0                          # "about 20 px"
    assert np.median(err) < 0.6 * err.mean()                 # heavy tails
    det = np.where(seen[..., None], sim.observations[..., :2], np.nan)
    assert 0.72 < pck(det, sim.image_truth, SKI24) < 0.80    # "about 0.76"
    frac = sim.outlier.sum() / seen.sum()
    assert abs(frac - st.outlier_fraction) < 0.01
    conf = sim.observations[..., 2][seen]
    good = ~sim.outlier[seen]
    low, high = err[good] > np.quantile(err[good], 0.8), err[good] < np.quantile(err[good], 0.2)
    assert conf[good][low].mean() < conf[good][high].mean() - 0.1   # falls with the error


def test_noise_grows_as_the_athlete_gets_small(sim):
    o, xy = sim.observations, sim.image_truth
    h = image_height(xy)
    err = np.linalg.norm(o[..., :2] - xy, axis=-1) / h[..., None]
    ok = (o[..., 2] > 0) & ~sim.outlier & ~sim.swapped[..., None]
    small = ok & (h < np.nanquantile(h, 0.25))[..., None]
    big = ok & (h > np.nanquantile(h, 0.75))[..., None]
    assert np.median(err[small]) > 1.2 * np.median(err[big])


def test_swaps_come_in_bursts(sim):
    s = sim.swapped
    assert 0.03 < s.mean() < 0.07
    starts = np.sum(s[1:] & ~s[:-1]) + np.sum(s[0])
    assert s.sum() / starts >= 3.0                            # bursts of 3-12 frames


def test_bystander_nearer_the_named_camera_than_the_athlete(sim):
    st = sim.settings
    c = sim.cameras.index(st.near_camera)
    coach = sim.kinds.index(f"coach (near {st.near_camera})")
    X0 = sim.cameras.X0[c]
    d_coach = np.linalg.norm(sim.people_3d[coach - 1].mean(1) - X0, axis=-1)
    d_athlete = np.linalg.norm(sim.joints.mean(1) - X0, axis=-1)
    both = (sim.person_id[:, c, coach] >= 0) & (sim.person_id[:, c, 0] >= 0)
    nearer = both & (d_coach < d_athlete)
    assert nearer.sum() >= 100                  # in the image with the athlete, nearer
    h_coach = image_height(sim.people[coach][:, c, :, :2])
    h_ath = image_height(sim.people[0][:, c, :, :2])
    assert np.mean(h_coach[nearer] > h_ath[nearer]) > 0.9       # and bigger


def test_person_ids_are_shuffled_per_frame(sim):
    pid = sim.person_id
    n = np.sum(pid >= 0, axis=-1)
    for f, c in zip(*np.nonzero(n > 0)):
        ids = pid[f, c][pid[f, c] >= 0]
        assert sorted(ids) == list(range(len(ids)))
    crowded = (n >= 2) & (pid[..., 0] >= 0)
    assert crowded.sum() > 200
    assert 0.2 < np.mean(pid[..., 0][crowded] == 0) < 0.8


def test_long_tracking_loss_and_jump(sim):
    st = sim.settings
    c = sim.cameras.index(st.loss_camera)
    lost = slice(st.loss_start, st.loss_start + st.loss_frames)
    assert not np.any(sim.observations[lost, c, :, 2] > 0)
    assert st.loss_frames >= 95
    # the camera points away: the athlete's true projection leaves the image
    xy = sim.image_truth[lost, c]
    out = ~((xy[..., 0] >= 0) & (xy[..., 0] < 1920) & (xy[..., 1] >= 0) & (xy[..., 1] < 1080))
    assert np.all(out, axis=-1).sum() > 30
    g = sim.cameras.index(st.ghost_camera)
    frames = slice(st.ghost_start, st.ghost_start + st.ghost_frames)
    assert np.all(sim.person_id[frames, g, -1] >= 0) and np.all(sim.person_id[frames, g, 0] < 0)


def test_cameras_lag_jitter_and_are_mis_levelled(sim):
    R = sim.cameras.R                                        # (F, C, 3, 3)
    x_axis = R[..., 0, :]                                    # camera x in world
    roll = np.degrees(np.arcsin(np.abs(x_axis[..., 2])))     # against the horizontal
    assert np.all(np.median(roll, axis=0) > 0.5)
    assert np.all(np.max(roll, axis=0) < 10.0)
    centre = np.nanmean(sim.image_truth, axis=2) - np.array([960.0, 540.0])
    off = np.nanmedian(np.linalg.norm(centre, axis=-1), axis=0)
    assert np.all(off > 50.0)                                # the athlete off centre
    slow = sim.cameras.index(sim.settings.slow_camera)
    xy = sim.image_truth[:, slow]
    outside = ~((xy[..., 0] >= 0) & (xy[..., 0] < 1920) & (xy[..., 1] >= 0) & (xy[..., 1] < 1080))
    assert outside.any(-1).sum() > 10                        # it leaves the image at times


def test_terrain_is_not_planar_and_has_a_kicker(sim):
    n0 = sim.slope_normal
    feet = SKI24.indices(["r_ski_tip", "r_ski_tail", "l_ski_tip", "l_ski_tail"])
    h = sim.joints[:, feet].mean(1) @ n0                     # height above the plane
    assert np.ptp(h) > 1.0
    a, b = sim.info["airborne_frames"]
    assert b - a >= 20 and sim.info["flight_height_m"] > 0.3


def test_rotation_differences_noise_and_bad_pairs(sim):
    st = sim.settings
    per = simulated_rotation_differences(sim, st, 5)
    R = sim.cameras.R
    errs, failed = [], []
    for c, rd in enumerate(per.values()):
        true = R[1:, c] @ np.swapaxes(R[:-1, c], -1, -2)
        ok = rd.ok
        e = np.degrees(np.linalg.norm(matrix_to_rodrigues(
            rd.dR[ok] @ np.swapaxes(true[ok], -1, -2)), axis=-1))
        errs.append(e)
        failed.append(~ok)
    e = np.concatenate(errs)
    assert 0.02 < np.median(e) < 0.08
    assert 0.003 < np.mean(e > 0.4) < 0.02                   # wrong but accepted pairs
    assert 0.005 < np.mean(np.concatenate(failed)) < 0.04


def test_two_cameras_subset(sim):
    two = two_cameras(sim)
    assert two.cameras.names == ["C3", "C5"]
    assert np.array_equal(two.people[:, :, 1], sim.people[:, :, sim.cameras.index("C5")],
                          equal_nan=True)


def test_used_people_counts_bystander_frames(sim):
    """A run that used the coach in 40 frames of the near camera: 40 bystander frames."""
    st = sim.settings
    c = sim.cameras.index(st.near_camera)
    coach = sim.kinds.index(f"coach (near {st.near_camera})")
    obs = np.round(sim.observations, 1)
    frames = np.flatnonzero(sim.person_id[:, c, coach] >= 0)[:40]
    obs[frames, c] = np.round(sim.people[coach][frames, c], 1)
    u = used_people(obs, np.arange(len(obs)), sim.cameras.names, sim)
    assert u["bystander_frames"] == 40
    assert u["bystander_frames_per_camera"][st.near_camera] == 40
    assert u["unmatched_joints"] == 0
    obs[0, 0, 0, :2] += 3.0                                   # moved: of no person
    assert used_people(obs, np.arange(len(obs)), sim.cameras.names, sim)["unmatched_joints"] \
        == int(obs[0, 0, 0, 2] > 0)


def test_undetermined_joint_frames():
    obs = np.zeros((3, 2, 2, 3))
    obs[0, :, :, 2] = 0.9                # frame 0: both joints in two cameras
    obs[1, 0, :, 2] = 0.9                # frame 1: one camera
    X = np.zeros((3, 2, 3))
    X[2, 1] = np.nan                     # frame 2: unseen; joint 1 a gap
    u = undetermined_joint_frames(obs, X)
    assert u == {"joint_frames": 6, "undetermined": 4, "undetermined_valid": 3,
                 "unseen_valid": 1}


def test_settings_change_the_data():
    a = simulate_harsh(replace(HarshSettings(), outlier_fraction=0.0), seed=22)
    assert a.outlier.sum() == 0


def test_used_people_counts_athlete_frames_missed(sim):
    obs = np.round(sim.observations, 1)
    seen = np.any(obs[..., 2] > 0, axis=-1)
    obs[:100, 0] = (np.nan, np.nan, 0.0)                      # camera C1 dropped for 100 frames
    u = used_people(obs, np.arange(len(obs)), sim.cameras.names, sim)
    assert u["athlete_frames_missed"] == int(seen[:100, 0].sum())
