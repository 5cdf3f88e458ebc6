"""Camera rotation differences from rendered images (issue 8, part 2).

SIMULATED data: photogram.simulation.ski.simulate (seed 8; one run of 279 frames by
default, ``--runs`` for more) filmed by six pan-tilt-zoom cameras; every
frame of every camera is rendered at 960 x 540 (photogram.simulation.ski.render:
textured slope, gates, fences, trees, sky, the skier from the truth joints,
exact lens model) and the frame-to-frame rotations are estimated from the
images (photogram.mocap.motion.homography: ORB outside the athlete's box, guided
matching, RANSAC homography, rotation refit on the inliers), one OpenCV
thread, runs processed separately. The athlete boxes are the truth joints'
image boxes (a tracker's boxes in practice).

Prints per camera: pairs, failed pairs, median inliers, the error of the
rotation differences per axis of the camera (x tilt, y pan, z roll; median
and 95th percentile, degrees) raw and filtered (median 7 + Gaussian sigma 3,
as the paper), the estimation speed in frames per second per core (CPU
time, rendering excluded) and the rendering time per frame; ends with one
``RESULT key=value ...`` line. Goal: >= 50 frames per second per core.

Run: .venv/bin/python benchmarks/homographies.py [--runs 1] [--seed 8]
     [--method rays|homography] [--video-dir DIR]
"""

import argparse
import time
from pathlib import Path

import photogram  # noqa: F401  (one BLAS thread before numpy)
import cv2
import numpy as np

from photogram.errors import GeometryError
from photogram.mocap.motion.homography import HomographySettings, rotation_differences
from photogram.mocap.motion.rotation_series import (check_rotation_differences,
                                                    filter_rotation_differences,
                                                    rotation_difference_errors)
from photogram.simulation.ski.render import build_scene, render_camera, write_video
from photogram.simulation.ski.simulate import simulate_session


class Timed:
    """Iterator wrapper that sums the CPU time spent producing the items."""

    def __init__(self, items):
        self.items, self.cpu, self.n = iter(items), 0.0, 0

    def __iter__(self):
        return self

    def __next__(self):
        t0 = time.process_time()
        try:
            item = next(self.items)
        finally:
            self.cpu += time.process_time() - t0
        self.n += 1
        return item


def boxes_of(sim):
    xy = sim.image_truth
    with np.errstate(invalid="ignore"):
        return np.stack([np.nanmin(xy[..., 0], 2), np.nanmin(xy[..., 1], 2),
                         np.nanmax(xy[..., 0], 2), np.nanmax(xy[..., 1], 2)], -1)


def fmt(e):
    return " ".join(f"{e[k]['median']:.4f}/{e[k]['p95']:.4f}" for k in ("x", "y", "z"))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=1)
    ap.add_argument("--seed", type=int, default=8)
    ap.add_argument("--method", default="rays", choices=["rays", "homography"])
    ap.add_argument("--video-dir", type=Path, default=None,
                    help="also write the rendered videos (MJPG .avi) there")
    args = ap.parse_args()
    cv2.setNumThreads(1)
    sim = simulate_session(seed=args.seed, n_runs=args.runs)
    t0 = time.process_time()
    scene = build_scene(sim)
    scene_s = time.process_time() - t0
    F, C = len(sim.joints), sim.cameras.n_cameras
    starts = [0] + list(sim.breaks) + [F]
    boxes = boxes_of(sim)
    settings = HomographySettings(method=args.method)
    print(f"simulated session: seed {args.seed}, {args.runs} run(s), {F} frames x {C} cameras, "
          f"rendered at 960 x 540; scene built in {scene_s:.2f} s")
    print("camera  frames pairs failed inliers   raw error x/y/z deg (median/p95)"
          "          filtered x/y/z (median/p95)          fps/core render ms")
    totals = dict(frames=0, est=0.0, render=0.0, rendered=0, failed=0)
    raw_all, filt_all, inliers = [], [], []
    for c in range(C):
        dR_raw, dR_filt, inl, failed, est = [], [], [], 0, 0.0
        render = Timed(())
        for a, b in zip(starts[:-1], starts[1:]):
            frames = list(range(a, b))
            render.items = iter(render_camera(scene, sim, c, frames))
            images = render
            if args.video_dir is not None:
                images = list(render)
                write_video(args.video_dir / f"{sim.cameras.names[c]}_run{len(dR_raw)}.avi",
                            images, sim.fps)
            rd = rotation_differences(images, "opencv", sim.cameras.io[c][frames], 0.5,
                                      boxes[frames, c], settings)
            try:
                check_rotation_differences(rd, sim.cameras.names[c], settings)
                filt = filter_rotation_differences(rd.dR, rd.ok, settings.median, settings.sigma)
            except GeometryError as exc:
                print("  " + exc.one_line())
                filt = np.full_like(rd.dR, np.nan)
            R = sim.cameras.R[frames, c]
            dR_raw.append((rd.dR, R))
            dR_filt.append((filt, R))
            inl.append(rd.inliers)
            failed += rd.failed
            est += rd.seconds
        e_raw = _errors(dR_raw)
        e_filt = _errors(dR_filt)
        inl = np.concatenate(inl)
        n = render.n
        print(f"{sim.cameras.names[c]:6s}  {n:6d} {len(inl):5d} {failed:6d} "
              f"{np.median(inl):7.0f}   {fmt(e_raw)}   {fmt(e_filt)}   {n / est:8.1f} {1e3 * render.cpu / n:9.1f}")
        totals["frames"] += n
        totals["est"] += est
        totals["render"] += render.cpu
        totals["failed"] += failed
        raw_all += dR_raw
        filt_all += dR_filt
        inliers.append(inl)
    e_raw, e_filt = _errors(raw_all), _errors(filt_all)
    fps = totals["frames"] / totals["est"]
    render_ms = 1e3 * totals["render"] / totals["frames"]
    print(f"all     {totals['frames']:6d}        {totals['failed']:6d} "
          f"{np.median(np.concatenate(inliers)):7.0f}   {fmt(e_raw)}   {fmt(e_filt)}   "
          f"{fps:8.1f} {render_ms:9.1f}")
    print(f"RESULT frames={totals['frames'] // C} cameras={C} method={args.method} "
          f"fps_per_core={fps:.1f} failed_pairs={totals['failed']} "
          f"median_inliers={np.median(np.concatenate(inliers)):.0f} "
          f"err_median_deg={e_raw['angle']['median']:.4f} err_p95_deg={e_raw['angle']['p95']:.4f} "
          f"filtered_median_deg={e_filt['angle']['median']:.4f} "
          f"filtered_p95_deg={e_filt['angle']['p95']:.4f} render_ms={render_ms:.1f}")


def _errors(pairs):
    """Errors over several segments: (dR (n-1, 3, 3), R (n, 3, 3)) each."""
    dR = np.concatenate([d for d, _ in pairs])
    true = np.concatenate([R[1:] @ np.swapaxes(R[:-1], -1, -2) for _, R in pairs])
    # rotation_difference_errors wants rotations; chain the true differences
    R = np.empty((len(true) + 1, 3, 3))
    R[0] = np.eye(3)
    for k in range(len(true)):
        R[k + 1] = true[k] @ R[k]
    return rotation_difference_errors(dR, R)


if __name__ == "__main__":
    main()
