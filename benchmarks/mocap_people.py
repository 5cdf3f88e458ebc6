"""The athlete among other people (issue 20, item 4): the multi-view choice
(photogram.mocap.tracking.multiview) against the per-camera tracker
(photogram.mocap.tracking.athlete.select_person).

SIMULATED (photogram.simulation.ski.simulate, 150 frames at 50 fps, six
pan-tilt-zoom cameras) plus composed bystanders
(photogram.mocap.tracking.crowd):

* normal (seed 8): one bystander in C1, the athlete's skeleton of 50 frames
  later 1.5x larger, 300 px beside it, confidence 0.95;
* harsh (seed 11, not tuned on): copies in C1 and C2 at once, one walking
  across the athlete in C5 (-400..+400 px), a real 3D person 4 m nearer to
  C3 seen by C3 and C4, C1 losing the athlete for 20 frames and only C5 and
  C6 seeing it for 10 frames.

The per-camera choice of the simulations is the pipeline's for pan-tilt
cameras (photogram.mocap.tracking.reacquire with the image centre, issue
22); before issue 22 it was the largest, surest person's track (per camera
150 and 358 bystander camera-frames, docs/benchmarks.md).

The harsh scene is also run on ten more simulations (seeds 20-29,
association only). For each: camera-frames where a bystander was taken
(per camera / multi view), camera-frames left out (inconsistent, ambiguous, undecided) and the
MPJPE against the truth of the reconstruction from the athlete's own
detections, from the per-camera choice and from the multi-view choice.

REAL (Pose2Sim's demo, /work/shared/data/pose2sim-demo, skipped if absent):
the demo as it is (per-camera vs multi-view: mean reprojection error
against the per-camera detections, distance to Pose2Sim's TRC) and with one
more person in cameras 3 and 4 (the athlete 50 frames later, 1.5x larger,
shifted), and with a real 3D person in cameras 1 and 2 (the reconstructed
athlete 50 frames later, 1.5 m nearer to camera 1).

Run: .venv/bin/python benchmarks/mocap_people.py
"""

from __future__ import annotations

import json
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from photogram.mocap.body.skeleton import BODY25B, SKI24
from photogram.mocap.reconstruction.reconstruct import ReconstructionSettings, reconstruct
from photogram.mocap.tracking import multiview as mv
from photogram.mocap.tracking.athlete import select_person
from photogram.mocap.tracking.crowd import compose, copied_bystander, projected_bystander
from photogram.simulation.ski.simulate import simulate_session

ROOT = Path(__file__).resolve().parents[1]
DEMO = ROOT.parent / "shared" / "data" / "pose2sim-demo"
F = 150
CENTRE = (960.0, 540.0)     # the image centre of the simulated pan-tilt cameras


def sweep(seeds):
    """The harsh scene on other simulations: bystander camera-frames taken
    and athlete camera-frames left out, per seed (association only)."""
    taken, left = [], []
    for seed in seeds:
        sim = simulate_session(seed=seed, frames_per_run=F)
        athlete, bys = _scene(sim, True)
        dets = compose(athlete, SKI24, sim.cameras.names, bys)
        a = mv.associate(dets, sim.cameras, F)
        taken.append(sum(int(np.sum((a.rows[:, c] >= 0) & (d.person[np.maximum(a.rows[:, c], 0)]
                                                           > 0))) for c, d in enumerate(dets)))
        present = athlete[..., 2].max(-1) > 0
        left.append(int(np.sum(present & (a.status != mv.USED))))
    print(f"harsh scene on seeds {seeds[0]}-{seeds[-1]}: bystander camera-frames taken "
          f"{taken}, athlete camera-frames left out {left} (of ~{int(present.sum())})")
    return sum(taken), max(left)


def _mpjpe(obs, sim):
    rec = reconstruct(obs, sim.cameras, SKI24, ReconstructionSettings())
    return float(np.nanmean(np.linalg.norm(rec.joints - sim.joints, axis=-1)))


def _scene(sim, harsh):
    obs = sim.observations.copy()
    bys = [(0, copied_bystander(obs[:, 0], 50, 1.5, (300.0, 0.0)))]
    if harsh:
        walk = np.stack([np.linspace(-400, 400, F), np.zeros(F)], -1)
        towards = sim.cameras.X0[2] - sim.joints.mean((0, 1))
        person = sim.joints[(np.arange(F) + 40) % F] + 4.0 * towards / np.linalg.norm(towards)
        real = projected_bystander(sim.cameras, person)
        bys += [(1, copied_bystander(obs[:, 1], 30, 1.6, (-250.0, 50.0))),
                (4, copied_bystander(obs[:, 4], 70, 1.2, walk)), (2, real[:, 2]), (3, real[:, 3])]
        obs[30:50, 0] = (np.nan, np.nan, 0.0)
        obs[60:70, :4] = (np.nan, np.nan, 0.0)
    return obs, bys


def simulated(seed, harsh):
    sim = simulate_session(seed=seed, frames_per_run=F)
    athlete, bys = _scene(sim, harsh)
    dets = compose(athlete, SKI24, sim.cameras.names, bys)
    t0 = time.perf_counter()
    a = mv.associate(dets, sim.cameras, F)
    seconds = time.perf_counter() - t0
    pc = [select_person(d, image_centre=CENTRE) for d in dets]   # pan-tilt, as the pipeline
    per_camera = np.full_like(athlete, np.nan)
    per_camera[..., 2] = 0.0
    by_pc = by_mv = 0
    for c, d in enumerate(dets):
        per_camera[pc[c] >= 0, c] = d.joints[pc[c][pc[c] >= 0]]
        by_pc += int(np.sum((pc[c] >= 0) & (d.person[np.maximum(pc[c], 0)] > 0)))
        by_mv += int(np.sum((a.rows[:, c] >= 0) & (d.person[np.maximum(a.rows[:, c], 0)] > 0)))
    present = athlete[..., 2].max(-1) > 0
    out = {"bystander_per_camera": by_pc, "bystander_multiview": by_mv,
           "left_out": int(np.sum(present & (a.status != mv.USED))),
           "inconsistent": int(np.sum(a.status == mv.INCONSISTENT)),
           "ambiguous": int(np.sum(a.status == mv.AMBIGUOUS)),
           "undecided": int(np.sum(a.status == mv.UNDECIDED)),
           "present": int(present.sum()), "seconds": seconds,
           "mpjpe_alone_mm": 1000 * _mpjpe(athlete, sim),
           "mpjpe_per_camera_mm": 1000 * _mpjpe(per_camera, sim),
           "mpjpe_multiview_mm": 1000 * _mpjpe(a.joints(dets), sim)}
    name = "harsh" if harsh else "normal"
    print(f"{name} (seed {seed}, {F} frames, 6 cameras): bystander camera-frames taken: per "
          f"camera {by_pc}, multi-view {by_mv}; athlete camera-frames left out "
          f"{out['left_out']} of {out['present']} (inconsistent {out['inconsistent']}, "
          f"ambiguous {out['ambiguous']}, undecided {out['undecided']}); association "
          f"{seconds:.2f} s")
    print(f"  MPJPE: athlete alone {out['mpjpe_alone_mm']:.1f} mm, per-camera choice "
          f"{out['mpjpe_per_camera_mm']:.1f} mm, multi-view choice "
          f"{out['mpjpe_multiview_mm']:.1f} mm")
    return out


def _demo_run(pose=None, multiview=True, folder=None):
    from photogram.mocap.pipeline import run_mocap
    from photogram.project import read_project
    prj = ROOT / "projects" / "pose2sim-demo" / "demo.prj"
    if pose is not None:
        text = prj.read_text().replace('"../../../shared/data/pose2sim-demo/pose"', f'"{pose}"')
        text = text.replace("../../../shared/data/pose2sim-demo", str(DEMO))
        prj = Path(folder) / "demo.prj"
        prj.write_text(text)
    p = read_project(prj)
    p.mocap.tracking["multiview"] = multiview
    return run_mocap(p)


def _add_bystanders(pose):
    from photogram.mocap.sources.openpose import read_openpose_folder
    for cam, shift in (("cam3_json", (-350.0, 100.0)), ("cam4_json", (300.0, -50.0))):
        det = read_openpose_folder(pose / cam, BODY25B)
        rows = select_person(det)
        athlete = np.full((det.n_frames, 25, 3), np.nan)
        athlete[..., 2] = 0.0
        athlete[rows >= 0] = det.joints[rows[rows >= 0]]
        by = copied_bystander(athlete, 50, 1.5, shift)
        for f, path in enumerate(sorted((pose / cam).glob("*.json"))):
            data = json.loads(path.read_text())
            data["people"].append({"person_id": [-1],
                                   "pose_keypoints_2d": np.nan_to_num(by[f]).ravel().tolist()})
            path.write_text(json.dumps(data))


def _add_real_person(pose, result):
    """A real 3D person in cameras 1 and 2: the reconstructed athlete of 50
    frames later (back and forth), 1.5 m nearer to camera 1."""
    X = result.reconstruction.joints
    F = len(X)
    k = (np.arange(F) + 50) % (2 * F - 2)
    X = X[np.where(k < F, k, 2 * F - 2 - k)]
    towards = result.cameras.X0[0] - np.nanmean(X, axis=(0, 1))
    X = X + 1.5 * towards / np.linalg.norm(towards)
    det = projected_bystander(result.cameras, X)
    for c, cam in ((0, "cam1_json"), (1, "cam2_json")):
        for f, path in enumerate(sorted((pose / cam).glob("*.json"))):
            data = json.loads(path.read_text())
            data["people"].append({"person_id": [-1], "pose_keypoints_2d":
                                   np.nan_to_num(det[f, c]).ravel().tolist()})
            path.write_text(json.dumps(data))


def real():
    from photogram.mocap.pipeline import reprojection_errors
    if not (DEMO / "Calib_qualisys.toml").is_file():
        print("real: /work/shared/data/pose2sim-demo is absent, skipped")
        return {}
    before, after = _demo_run(multiview=False), _demo_run(multiview=True)
    det = before.observations

    def mean_px(r):
        e = reprojection_errors(r.reconstruction.joints, before.cameras, det)
        return float(np.mean([v["mean_px"] for v in e.values()]))
    out = {"demo_mean_px_before": mean_px(before), "demo_mean_px_after": mean_px(after),
           "demo_trc_mm_before": 1000 * before.reference["mpjpe_to_reference"],
           "demo_trc_mm_after": 1000 * after.reference["mpjpe_to_reference"]}
    people = after.info["people"]["cameras"]
    print("real, Pose2Sim demo (100 frames, 4 cameras; bystanders in cameras 1 and 2):")
    for cam, d in people.items():
        print(f"  {cam}: used {d['used']}, other person than per camera {d['other_person']}, "
              f"inconsistent {d['inconsistent']}, ambiguous {d['ambiguous']}, median "
              f"{d['median_error_px']:.1f} px")
    print(f"  mean reprojection error (per-camera detections): per camera "
          f"{out['demo_mean_px_before']:.2f} px, multi-view {out['demo_mean_px_after']:.2f} px; "
          f"distance to Pose2Sim's TRC {out['demo_trc_mm_before']:.2f} -> "
          f"{out['demo_trc_mm_after']:.2f} mm")
    with tempfile.TemporaryDirectory() as tmp:
        pose = Path(tmp) / "pose"
        shutil.copytree(DEMO / "pose", pose)
        _add_bystanders(pose)
        pc = _demo_run(pose, False, tmp)
        mv_ = _demo_run(pose, True, tmp)
        shutil.rmtree(pose)
        shutil.copytree(DEMO / "pose", pose)
        _add_real_person(pose, before)
        pc3 = _demo_run(pose, False, tmp)
        mv3 = _demo_run(pose, True, tmp)
    out["real3d_trc_mm_per_camera"] = 1000 * pc3.reference["mpjpe_to_reference"]
    out["real3d_trc_mm_multiview"] = 1000 * mv3.reference["mpjpe_to_reference"]
    other3 = {c: (d["other_person"], d["inconsistent"], d["ambiguous"])
              for c, d in mv3.info["people"]["cameras"].items()}
    print(f"real + a 3D person 1.5 m nearer to camera 1, seen by cameras 1 and 2: distance to "
          f"Pose2Sim's TRC per camera {out['real3d_trc_mm_per_camera']:.1f} mm, multi-view "
          f"{out['real3d_trc_mm_multiview']:.2f} mm; per camera (other person, inconsistent, "
          f"ambiguous): {other3}")
    out["crowd_trc_mm_per_camera"] = 1000 * pc.reference["mpjpe_to_reference"]
    out["crowd_trc_mm_multiview"] = 1000 * mv_.reference["mpjpe_to_reference"]
    other = {c: d["other_person"] for c, d in mv_.info["people"]["cameras"].items()}
    print(f"real + a 1.5x larger person in cameras 3 and 4: distance to Pose2Sim's TRC per "
          f"camera {out['crowd_trc_mm_per_camera']:.1f} mm, multi-view "
          f"{out['crowd_trc_mm_multiview']:.2f} mm; frames where the multi-view choice took "
          f"another person than the per-camera choice: {other}")
    return out


def main() -> int:
    t0 = time.perf_counter()
    n = simulated(8, False)
    h = simulated(11, True)
    sweep_taken, sweep_left = sweep(list(range(20, 30)))
    r = real()
    line = (f"RESULT normal_bystander_taken={n['bystander_multiview']} "
            f"normal_per_camera_taken={n['bystander_per_camera']} "
            f"normal_mpjpe_mm={n['mpjpe_multiview_mm']:.1f} "
            f"normal_alone_mm={n['mpjpe_alone_mm']:.1f} "
            f"normal_per_camera_mm={n['mpjpe_per_camera_mm']:.1f} "
            f"harsh_bystander_taken={h['bystander_multiview']} "
            f"harsh_per_camera_taken={h['bystander_per_camera']} "
            f"harsh_left_out={h['left_out']} harsh_mpjpe_mm={h['mpjpe_multiview_mm']:.1f} "
            f"harsh_alone_mm={h['mpjpe_alone_mm']:.1f} "
            f"harsh_per_camera_mm={h['mpjpe_per_camera_mm']:.1f} "
            f"sweep_bystander_taken={sweep_taken} sweep_max_left_out={sweep_left}")
    if r:
        line += (f" demo_mean_px={r['demo_mean_px_before']:.2f}->{r['demo_mean_px_after']:.2f}"
                 f" demo_trc_mm={r['demo_trc_mm_before']:.2f}->{r['demo_trc_mm_after']:.2f}"
                 f" crowd_trc_mm_per_camera={r['crowd_trc_mm_per_camera']:.1f}"
                 f" crowd_trc_mm_multiview={r['crowd_trc_mm_multiview']:.2f}"
                 f" real3d_trc_mm_per_camera={r['real3d_trc_mm_per_camera']:.1f}"
                 f" real3d_trc_mm_multiview={r['real3d_trc_mm_multiview']:.2f}")
    print(f"total {time.perf_counter() - t0:.0f} s")
    print(line)
    return 0


if __name__ == "__main__":
    sys.exit(main())
