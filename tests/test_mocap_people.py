"""The athlete among other people: the multi-view choice
(photogram.mocap.tracking.multiview) on composed multi-person detections
with known truth (the ski simulator's athlete plus bystanders) and on
Pose2Sim's real demo."""

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from photogram.mocap.body.skeleton import SKI24
from photogram.mocap.reconstruction.reconstruct import ReconstructionSettings, reconstruct
from photogram.mocap.tracking import multiview as mv
from photogram.mocap.tracking import multiview_frames as mvf
from photogram.mocap.tracking.athlete import select_person
from photogram.mocap.tracking.crowd import compose, copied_bystander, projected_bystander
from photogram.simulation.ski.simulate import simulate_session

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[1]
POSE2SIM = ROOT.parent / "shared" / "data" / "pose2sim-demo"
F = 100


def _mpjpe(obs, sim, frames=slice(None)):
    rec = reconstruct(obs, sim.cameras, SKI24, ReconstructionSettings())
    return float(np.nanmean(np.linalg.norm(rec.joints - sim.joints, axis=-1)[frames]))


def _bystander_rows(assoc, dets):
    """Camera-frames where a bystander (person > 0) was taken."""
    return sum(int(np.sum((assoc.rows[:, c] >= 0) & (d.person[np.maximum(assoc.rows[:, c], 0)]
                                                     > 0))) for c, d in enumerate(dets))


def _per_camera_bystanders(dets):
    rows = [select_person(d) for d in dets]
    return sum(int(np.sum((r >= 0) & (d.person[np.maximum(r, 0)] > 0)))
               for r, d in zip(rows, dets))


@pytest.fixture(scope="module")
def normal():
    return simulate_session(seed=8, frames_per_run=F)


@pytest.fixture(scope="module")
def harsh():
    return simulate_session(seed=3, frames_per_run=F)


def test_noise_free_views_triangulate_exactly(normal):
    """The DLT of the association on exact projections gives the truth."""
    sim = normal
    exact = projected_bystander(sim.cameras, sim.joints)
    dets = compose(exact, SKI24, sim.cameras.names)
    a = mv.associate(dets, sim.cameras, F)
    assert np.all(a.status == mv.USED)
    assert np.nanmax(a.error_px) < 1e-3
    assert np.allclose(a.root, np.median(sim.joints, axis=1), atol=1e-6)


def test_a_larger_bystander_in_one_camera_never_enters(normal):
    """The athlete's skeleton of another time, 1.5x larger and beside it, with
    a high confidence: the per-camera tracker takes it in every frame, the
    multi-view choice never; the observations are the athlete's."""
    sim = normal
    obs = sim.observations
    by = copied_bystander(obs[:, 0], 50, 1.5, (300.0, 0.0))
    dets = compose(obs, SKI24, sim.cameras.names, [(0, by)])
    assert _per_camera_bystanders(dets) >= 0.9 * F
    a = mv.associate(dets, sim.cameras, F)
    assert _bystander_rows(a, dets) == 0
    assert np.mean(a.status == mv.USED) > 0.99
    chosen = a.joints(dets)
    used = a.status == mv.USED
    assert np.array_equal(np.nan_to_num(chosen[used]), np.nan_to_num(obs[used]))
    pc = [select_person(d) for d in dets]
    report = a.report(sim.cameras.names, pc)
    assert report["C1"]["other_person"] >= 0.9 * F and report["C2"]["other_person"] == 0
    clean = _mpjpe(obs, sim)
    assert _mpjpe(chosen, sim) < clean + 0.0005


def test_harsh_crowd_never_picks_a_bystander(harsh):
    """Another simulation (seed 3, not tuned on): copied bystanders in C1 and
    C2 at once, one walking across the athlete in C5, a real 3D person 4 m
    nearer to C3 seen by C3 and C4 (its two views agree with each other),
    C1 loses the athlete for 20 frames, and for 10 frames only C5 and C6 see
    the athlete (the 3D bystander then forms an equally large consistent
    pair: the temporal gate rules it out)."""
    sim = harsh
    obs = sim.observations.copy()
    walk = np.stack([np.linspace(-400, 400, F), np.zeros(F)], -1)
    towards = sim.cameras.X0[2] - sim.joints.mean((0, 1))
    person = sim.joints[(np.arange(F) + 40) % F] + 4.0 * towards / np.linalg.norm(towards)
    real = projected_bystander(sim.cameras, person)
    bystanders = [(0, copied_bystander(obs[:, 0], 50, 1.5, (300.0, 0.0))),
                  (1, copied_bystander(obs[:, 1], 30, 1.6, (-250.0, 50.0))),
                  (4, copied_bystander(obs[:, 4], 70, 1.2, walk)),
                  (2, real[:, 2]), (3, real[:, 3])]
    lost = obs.copy()
    lost[30:50, 0] = (np.nan, np.nan, 0.0)
    lost[60:70, :4] = (np.nan, np.nan, 0.0)
    dets = compose(lost, SKI24, sim.cameras.names, bystanders)
    assert _per_camera_bystanders(dets) > 2 * F
    a = mv.associate(dets, sim.cameras, F)
    assert _bystander_rows(a, dets) == 0
    assert np.all(a.status[30:50, 0] == mv.INCONSISTENT)          # flagged, not guessed
    assert np.all(a.status[60:70, 2:4] == mv.INCONSISTENT)
    # with two cameras left the walker beside the athlete in C5 (80-140 px
    # away) triangulates with C6 within the threshold and the gate: those
    # frames are flagged, not guessed
    assert np.all(np.isin(a.status[60:70, 4:], (mv.USED, mv.AMBIGUOUS)))
    assert np.any(a.status[60:70, 4:] == mv.USED)
    present = lost[..., 2].max(-1) > 0
    present[60:70] = False
    assert np.mean(a.status[present] == mv.USED) > 0.99
    chosen = a.joints(dets)
    used = a.status == mv.USED
    assert np.array_equal(np.nan_to_num(chosen[used]), np.nan_to_num(lost[used]))
    decided = np.r_[0:55, 75:F]                    # away from the flagged frames 60-67
    clean = _mpjpe(lost, sim, decided)             # the same losses, nobody else
    ours = _mpjpe(chosen, sim, decided)
    assert ours < clean + 0.001
    assert _mpjpe(chosen, sim) < 0.05              # the flagged frames bridged


def test_a_camera_it_cannot_decide_is_left_out_not_guessed(normal):
    """C2 holds two candidates 8 px left and right of the athlete (a split
    detection that disagrees; the athlete itself is not there): both fit
    the other cameras equally well, C2 is left out and flagged ambiguous. A
    rival 30 px away fits clearly worse (the athlete is taken, but for the
    few frames where its own detection is poor: flagged); a duplicate 3 px
    away is not a rival."""
    sim = normal
    obs = sim.observations
    names = sim.cameras.names
    left, right = obs.copy(), obs[:, 1].copy()
    left[:, 1, :, 0] -= 8.0
    right[..., 0] += 8.0
    dets = compose(left, SKI24, names, [(1, right)])
    a = mv.associate(dets, sim.cameras, F)
    assert np.mean(a.status[:, 1] == mv.AMBIGUOUS) > 0.9
    assert np.mean(a.status[:, [0, 2, 3, 4, 5]] == mv.USED) > 0.99
    for shift, share in ((30.0, 0.95), (3.0, 0.99)):
        other = obs[:, 1].copy()
        other[..., 0] += shift
        dets = compose(obs, SKI24, names, [(1, other)])
        a = mv.associate(dets, sim.cameras, F)
        if shift > 3.0:                            # a duplicate may be taken: the same person
            assert _bystander_rows(a, dets) == 0
        assert np.mean(a.status[:, 1] == mv.USED) > share
        assert np.all(np.isin(a.status[:, 1], (mv.USED, mv.AMBIGUOUS)))


def test_runs_are_seeded_apart():
    """Two runs back to back (the athlete jumps back to the start): each run
    is tracked alone, nothing is left out."""
    sim = simulate_session(seed=5, n_runs=2, frames_per_run=40)
    dets = compose(sim.observations, SKI24, sim.cameras.names)
    a = mv.associate(dets, sim.cameras, 80, breaks=sim.breaks)
    assert len(a.seeds) == 2 and np.mean(a.status == mv.USED) > 0.99
    assert a.undecided_runs == []


# --------------------------------------------------------------------------
# Pose2Sim's demo (real detections; bystanders in cameras 1 and 2)
# --------------------------------------------------------------------------
needs_demo = pytest.mark.skipif(not (POSE2SIM / "Calib_qualisys.toml").is_file(),
                                reason="../shared/data/pose2sim-demo is absent")


def _demo_project(folder: Path, pose: Path) -> Path:
    text = (ROOT / "projects" / "pose2sim-demo" / "demo.prj").read_text()
    text = text.replace('"../../../shared/data/pose2sim-demo/pose"', f'"{pose}"')
    text = text.replace("../../../shared/data/pose2sim-demo", str(POSE2SIM))
    (folder / "demo.prj").write_text(text)
    return folder / "demo.prj"


@needs_demo
def test_pose2sim_demo_not_worse(tmp_path):
    """The real demo: the multi-view choice takes the per-camera choice
    everywhere but a split detection (ambiguous), and the reconstruction is
    as close to Pose2Sim's TRC as without it."""
    from photogram.mocap.pipeline import reprojection_errors, run_mocap
    from photogram.project import read_project
    from mocap_fixtures import pose2sim_demo_run
    p = read_project(ROOT / "projects" / "pose2sim-demo" / "demo.prj")
    p.mocap.tracking["multiview"] = False
    before = run_mocap(p)
    after = pose2sim_demo_run()                 # the default: multiview = true
    people = after.info["people"]["cameras"]
    assert all(d["other_person"] == 0 for d in people.values())
    assert sum(d["used"] for d in people.values()) >= 4 * 100 - 2
    assert after.reference["mpjpe_to_reference"] < before.reference["mpjpe_to_reference"] + 5e-4
    # the same detections (the per-camera choice) for both reprojection errors
    e0 = reprojection_errors(before.reconstruction.joints, before.cameras, before.observations)
    e1 = reprojection_errors(after.reconstruction.joints, before.cameras, before.observations)
    assert np.mean([v["mean_px"] for v in e1.values()]) < \
        np.mean([v["mean_px"] for v in e0.values()]) + 0.2


@needs_demo
def test_pose2sim_demo_with_a_nearer_bystander(tmp_path):
    """The demo's JSON with one more person in cameras 3 and 4: the athlete's
    skeleton of 50 frames later, 1.5x larger and shifted, confidence 0.95.
    The per-camera tracker takes it; ``photogram mocap`` does not, and the
    reconstruction stays as close to Pose2Sim's TRC."""
    from photogram.mocap.pipeline import run_mocap
    from photogram.mocap.sources.openpose import read_openpose_folder
    from photogram.mocap.body.skeleton import BODY25B
    from photogram.project import read_project
    pose = tmp_path / "pose"
    shutil.copytree(POSE2SIM / "pose", pose)
    for cam, shift in (("cam3_json", (-350.0, 100.0)), ("cam4_json", (300.0, -50.0))):
        det = read_openpose_folder(pose / cam, BODY25B)
        rows = select_person(det)
        athlete = np.full((100, 25, 3), np.nan)
        athlete[..., 2] = 0.0
        athlete[rows >= 0] = det.joints[rows[rows >= 0]]
        by = copied_bystander(athlete, 50, 1.5, shift)
        for f, path in enumerate(sorted((pose / cam).glob("*.json"))):
            data = json.loads(path.read_text())
            kp = np.nan_to_num(by[f]).ravel().tolist()
            data["people"].append({"person_id": [-1], "pose_keypoints_2d": kp})
            path.write_text(json.dumps(data))
        det = read_openpose_folder(pose / cam, BODY25B)
        rows = select_person(det)
        assert np.mean(det.joints[rows[rows >= 0], :, 2].max(-1) == 0.95) > 0.9   # taken
    p = read_project(_demo_project(tmp_path, pose))
    r = run_mocap(p)
    people = r.info["people"]["cameras"]
    for cam in ("cam_03", "cam_04"):
        assert people[cam]["other_person"] > 90 and people[cam]["used"] > 95
    assert np.all(np.nan_to_num(r.observations[:, 2:, :, 2]) != 0.95)      # never entered
    from mocap_fixtures import pose2sim_demo_run
    clean = pose2sim_demo_run()
    assert abs(r.reference["mpjpe_to_reference"] - clean.reference["mpjpe_to_reference"]) < 1e-4


# --------------------------------------------------------------------------
# through the command and the project file
# --------------------------------------------------------------------------
def _with_bystander(csv: Path, sim, camera: int = 0):
    """The simulated detections.csv with a ``person`` column (athlete 0)
    and a 1.5x larger copy of the athlete in one camera (person 1)."""
    lines = csv.read_text().splitlines()
    out = []
    for ln in lines:
        if ln.startswith("#"):
            out.append(ln)
        elif ln.startswith("frame,"):
            out.append(ln + ",person")
        else:
            out.append(ln + ",0")
    by = copied_bystander(sim.observations[:, camera], 10, 1.5, (300.0, 0.0))
    name = sim.cameras.names[camera]
    for f, j in zip(*np.nonzero(by[..., 2] > 0)):
        out.append(f"{f},{name},{SKI24.joints[j]},{by[f, j, 0]:.2f},{by[f, j, 1]:.2f},0.95,1")
    csv.write_text("\n".join(out) + "\n")
    return by


@pytest.mark.filterwarnings("ignore:No analog data")
def test_command_reports_the_choice_and_keeps_the_bystander_out(tmp_path, capsys):
    from photogram.simulation.ski.simproject import write_simulated_project
    from photogram_cli.main import main
    sim = simulate_session(seed=6, frames_per_run=40)
    write_simulated_project(sim, tmp_path, name="ski")
    by = _with_bystander(tmp_path / "detections.csv", sim)
    assert main(["mocap", "--no-report", "--no-figures", "-q", str(tmp_path / "ski.prj")]) == 0
    s = json.loads((tmp_path / "results" / "summary.json").read_text())
    people = s["people"]["cameras"]
    # the per-camera track of a pan-tilt camera keeps the copy 300 px off the
    # image centre out as well (issue 22): both choices agree
    assert people["C1"]["used"] >= 38
    assert all(people[c]["other_person"] == 0 for c in ("C1", "C2", "C3", "C4", "C5", "C6"))
    assert s["tracking"]["C1"]["persons"] == {"0": 40}
    assert s["accuracy"]["mpjpe"] < 0.03
    log = (tmp_path / "results" / "log.txt").read_text()
    assert "camera C1: multi-view choice in" in log
    import pandas as pd
    det = pd.read_csv(tmp_path / "results" / "detections.csv", comment="#")
    c1 = det[det["camera"] == "C1"]
    assert len(c1) > 30 * 20
    xs = by[c1["frame"].to_numpy(), [SKI24.joints.index(j) for j in c1["joint"]], 0]
    assert not np.any(np.isclose(c1["x"].to_numpy(), xs, atol=0.01))   # never an observation
    # the setting is read from [mocap.tracking]; a bad value is one line
    prj = tmp_path / "ski.prj"
    prj.write_text(prj.read_text() + "\n[mocap.tracking]\nassociation_px = -5\n")
    capsys.readouterr()
    assert main(["mocap", "--no-report", str(prj), "--force"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "association_px" in err[0]


def test_image_detector_frames_of_another_person_are_left_out(normal):
    """An image detector's one candidate per camera (the tracked athlete):
    frames where it locked onto somebody else are left out as inconsistent."""
    from types import SimpleNamespace
    sim = normal
    obs = sim.observations.copy()
    wrong = copied_bystander(obs[:, 3], 40, 1.3, (200.0, -80.0))
    obs[20:30, 3] = wrong[20:30]
    cands = [mv.tracked_candidates(SimpleNamespace(camera=n, joints=obs[:, c]), SKI24)
             for c, n in enumerate(sim.cameras.names)]
    dets = [d for d, _ in cands]
    a = mv.associate(dets, sim.cameras, F)
    assert np.all(a.status[20:30, 3] == mv.INCONSISTENT)
    assert np.mean(np.delete(a.status, np.s_[20:30], axis=0) == mv.USED) > 0.99
    rep = a.report(sim.cameras.names, [r for _, r in cands])
    assert rep["C4"]["per_camera_left_out"] == 10 and rep["C4"]["other_person"] == 0


def test_crowded_frames_combine_only_candidates_near_the_prediction(normal):
    """Two copies in every camera (3^6 = 729 combinations of all cameras: a
    crowded frame): after the seed only candidates near the predicted
    skeleton are combined; no bystander is taken, nothing is lost."""
    sim = normal
    obs = sim.observations
    bys = [(c, copied_bystander(obs[:, c], 30 + 7 * c, 1.5, (300.0, 0.0))) for c in range(6)]
    bys += [(c, copied_bystander(obs[:, c], 60 + 7 * c, 1.2, (-300.0, 40.0))) for c in range(6)]
    dets = compose(obs, SKI24, sim.cameras.names, bys)
    assert mv.CROWDED < 3 ** 6
    a = mv.associate(dets, sim.cameras, F)
    assert _bystander_rows(a, dets) == 0
    assert np.mean(a.status == mv.USED) > 0.99


def test_nanmedian_matches_numpy():
    import warnings
    rng = np.random.default_rng(1)
    a = rng.normal(size=(40, 6, 9))
    a[rng.uniform(size=a.shape) < 0.3] = np.nan
    a[0, 0] = np.nan
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        ref = np.nanmedian(a, axis=-1)
    assert np.allclose(mvf._nanmedian(a), ref, equal_nan=True)
