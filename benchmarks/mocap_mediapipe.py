"""``photogram mocap`` with the mediapipe detector on Pose2Sim's real demo
videos (projects/pose2sim-demo/mediapipe.prj): speed, 3D distance to
Pose2Sim's triangulation, reprojection error.

Speed: camera-frames per second per core, the frames of a camera divided
by the process time (all threads) of its tracking: decoding the video, the
crops, the detector calls. ``--flow smoothed`` runs the offline flow of
steps 1-5 of photogram.mocap.tracking.athlete (three calls per frame, the
flow before the online crop tracking) for comparison.

Accuracy: the 3D joints of the reconstruction (the pipeline's
``run_mocap``, the mediapipe33 skeleton) against Pose2Sim's own
triangulation of OpenPose BODY_25B detections of the same videos
(pose2sim-triangulation-Balancing_for_IK.trc, read Y-up -> Z-up; row i is
frame i), on the 17 joints both have
(photogram.mocap.sources.mediapipe.POSE2SIM_MARKERS): per joint the median
over frames of the distance, overall the median over all frames and
joints. Pose2Sim's points are a reference, not the truth. The mean
reprojection error is that of our joints against our detections
(confidence >= 0.3), per camera and averaged.

Settings (``--setting``; the defaults were tuned on ``normal`` only):
``normal`` the 4 videos as they are; ``half`` the videos downscaled to half
size before the detector (INTER_AREA; the joints scaled back by 2);
``drop2`` every second frame dropped (30 fps; compared with TRC rows 0, 2,
...); ``no-cam01`` .. ``no-cam04`` one camera left out.

Run: .venv/bin/python benchmarks/mocap_mediapipe.py [--setting normal half]
     [--flow crop|smoothed] [--frames N]

Without mediapipe (the optional extra) or the demo data it prints a line
saying so and a ``RESULT skipped=...`` line.
"""

from __future__ import annotations

import argparse
import logging
import time
from dataclasses import replace
from pathlib import Path

import photogram  # noqa: F401  (single-threaded BLAS before numpy)
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
PROJECT = ROOT / "projects" / "pose2sim-demo" / "mediapipe.prj"
DATA = (PROJECT.parent / "../../../shared/data/pose2sim-demo").resolve()   # as the project
TRC = DATA / "pose2sim-triangulation-Balancing_for_IK.trc"
SETTINGS = ("normal", "half", "drop2", "no-cam01", "no-cam02", "no-cam03", "no-cam04")


class Frames:
    """The frames of an image sequence, every ``step``-th, optionally
    downscaled by ``scale``, at most ``limit``."""

    def __init__(self, images, step=1, scale=1.0, limit=None):
        self.images, self.step, self.scale, self.limit = images, step, scale, limit

    def __iter__(self):
        import cv2
        kept = 0
        for k, img in enumerate(self.images):
            if self.limit is not None and kept >= self.limit:
                break
            if k % self.step:
                continue
            kept += 1
            if self.scale != 1.0:
                h, w = img.shape[:2]
                img = cv2.resize(img, (round(w * self.scale), round(h * self.scale)),
                                 interpolation=cv2.INTER_AREA)
            yield img


class TrackedSource:
    """An observation source handing the pipeline tracks computed here."""

    def __init__(self, source, tracked: dict):
        self.kind, self.skeleton = source.kind, source.skeleton
        self.cameras = list(tracked)
        self.tracked = tracked
        self.first_frame = 0

    def track(self, camera, settings=None, wide=False):
        return self.tracked[camera]

    def describe(self):
        return f"{self.kind} ({self.skeleton.name}, {len(self.cameras)} cameras, benchmark)"


def track_cameras(project, cameras, flow, step, scale, limit, leave_out):
    """Per camera: the tracked athlete, its process time, its counts."""
    from photogram.mocap.sources import open_source
    from photogram.mocap.tracking.athlete import TrackingSettings, track_images_smoothed
    from photogram.mocap.tracking.crop_tracking import track_images
    ms = project.mocap
    source = open_source(ms, cameras.names, project.folder)
    tracking = TrackingSettings(**ms.tracking)
    run = track_images if flow == "crop" else track_images_smoothed
    tracked, cpu = {}, {}
    for name in cameras.names:
        if name == leave_out:
            continue
        frames = Frames(source.images[name], step, scale, limit)
        c0 = time.process_time()
        t = run(frames, source.detector, name, tracking, name in ms.source.wide)
        cpu[name] = time.process_time() - c0
        if scale != 1.0:
            t.joints[..., :2] /= scale
            t.detected /= scale
            t.boxes /= scale
        tracked[name] = t
    return source, tracked, cpu


def compare_to_trc(result, trc_path, step):
    """Per TRC marker: the median distance (m) of our joint over frames;
    all distances (frames x joints)."""
    from photogram.io.trc import read_trc
    from photogram.mocap.sources.mediapipe import POSE2SIM_MARKERS
    trc = read_trc(trc_path, rotate_to_z_up=True)
    sk = result.skeleton
    rows = (result.frames - result.frames[0]) * step          # row i of the TRC is frame i
    ok = rows < len(trc.frames)
    X = result.reconstruction.joints[ok]
    per, alld, offsets = {}, [], {}
    for marker, joint in POSE2SIM_MARKERS.items():
        d = np.linalg.norm(X[:, sk.index(joint)] - trc.markers[marker][rows[ok]], axis=-1)
        d = d[np.isfinite(d)]
        per[marker] = float(np.median(d)) if len(d) else float("nan")
        alld.append(d)
    # the hips: mean offset ours - TRC, vertical (Z) and along the TRC's
    # left-right hip axis (positive: ours wider apart)
    axis = trc.markers["LHip"][rows[ok]] - trc.markers["RHip"][rows[ok]]
    axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
    for marker, sign in (("RHip", -1.0), ("LHip", 1.0)):
        delta = X[:, sk.index(POSE2SIM_MARKERS[marker])] - trc.markers[marker][rows[ok]]
        offsets[marker] = (float(np.nanmean(delta[:, 2])),
                           float(np.nanmean(sign * np.sum(delta * axis, axis=-1))))
    return per, np.concatenate(alld), offsets


def run_setting(setting, flow, limit):
    from photogram.mocap import pipeline
    from photogram.mocap.files import cameras_from_project
    from photogram.project.reader import read_project
    project = read_project(PROJECT)
    cameras = cameras_from_project(project)
    step = 2 if setting == "drop2" else 1
    scale = 0.5 if setting == "half" else 1.0
    leave_out = setting.replace("no-cam", "cam_") if setting.startswith("no-") else None
    if step != 1:
        project.mocap = replace(project.mocap, fps=project.mocap.fps / step)
    source, tracked, cpu = track_cameras(project, cameras, flow, step, scale, limit, leave_out)
    original = pipeline.open_source
    pipeline.open_source = lambda *a, **k: TrackedSource(source, tracked)
    try:
        result = pipeline.run_mocap(project)
    finally:
        pipeline.open_source = original
    per, dist, offsets = compare_to_trc(result, TRC, step)
    n_frames = {c: len(t.joints) for c, t in tracked.items()}
    fps_core = {c: n_frames[c] / cpu[c] for c in tracked}
    total_fps = sum(n_frames.values()) / sum(cpu.values())
    reproj = {c: v["mean_px"] for c, v in result.reprojection.items() if v["mean_px"] is not None}
    reproj_med = {c: v["median_px"] for c, v in result.reprojection.items()
                  if v["median_px"] is not None}
    print(f"\n== setting {setting}, flow {flow}: {len(result.frames)} frames x "
          f"{len(tracked)} cameras ==")
    for c, t in tracked.items():
        counts = t.counts() if hasattr(t, "counts") else {}
        print(f"  {c}: {fps_core[c]:5.1f} frames/s per core ({cpu[c]:.1f} s CPU, "
              f"{n_frames[c]} frames) {counts}  reprojection mean "
              f"{reproj.get(c, float('nan')):.1f} px, median "
              f"{reproj_med.get(c, float('nan')):.1f} px")
    print("  median 3D distance to Pose2Sim's TRC per joint (cm): " +
          ", ".join(f"{k} {100 * v:.1f}" for k, v in per.items()))
    no_hips = [v for k, v in per.items() if "Hip" not in k]
    print(f"  overall median {100 * np.median(dist):.2f} cm over {len(dist)} joint-frames "
          f"(90th percentile {100 * np.percentile(dist, 90):.1f} cm; median of the "
          f"per-joint medians without the hips {100 * np.median(no_hips):.1f} cm); "
          f"mean reprojection error {np.mean(list(reproj.values())):.2f} px")
    print("  hips, ours - TRC: " + ", ".join(
        f"{k} {100 * z:+.1f} cm up, {100 * w:+.1f} cm outwards" for k, (z, w) in offsets.items()))
    return {"fps": total_fps, "median_cm": 100 * float(np.median(dist)),
            "reproj_px": float(np.mean(list(reproj.values())))}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--setting", nargs="+", default=["normal", "half"], choices=SETTINGS)
    ap.add_argument("--flow", default="crop", choices=("crop", "smoothed"))
    ap.add_argument("--frames", type=int, default=None, help="first N frames only")
    args = ap.parse_args()
    try:
        import mediapipe  # noqa: F401
    except ImportError:
        print("mediapipe is not installed (pip install 'photogram[mediapipe]'): skipped")
        print("RESULT skipped=no_mediapipe")
        return
    if not (DATA / "videos").is_dir() or not TRC.is_file():
        print("the demo videos (../shared/data/pose2sim-demo/videos) are absent: skipped")
        print("RESULT skipped=no_data")
        return
    logging.basicConfig(level=logging.WARNING, format="%(message)s")
    out = {s: run_setting(s, args.flow, args.frames) for s in args.setting}
    print("RESULT flow=" + args.flow + " " + " ".join(
        f"{s}_fps_per_core={v['fps']:.1f} {s}_median_cm={v['median_cm']:.2f} "
        f"{s}_reproj_px={v['reproj_px']:.2f}" for s, v in out.items()))


if __name__ == "__main__":
    main()
