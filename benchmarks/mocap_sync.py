"""Synchronisation of the cameras of ``photogram mocap`` (issue 20, item 5).

SIMULATED data (photogram.simulation.ski.simulate, one run of 279 frames at
50 fps, six pan-tilt-zoom cameras): the session is re-recorded with known
per-camera offsets (camera c's frame f shows the instant f - o_c: the true
joints interpolated linearly in time, its rotation and zoom those of that
instant, so that the camera_frames stay numbered like its detections),
then noisy detections are drawn:

* normal: noise 0.8 % of the athlete's image height x (0.5 + U(0, 1)),
  5 % outliers moved by 50-150 px (the simulator's levels);
* harsh (not tuned on): noise x 3, 15 % outliers, and one camera that
  sees the athlete in only 30 % of the frames (one contiguous stretch).

Each setting is drawn ``--draws`` times with offsets (frames) of
C2 +2, C3 -1.4, C4 +0.5, C5 -3 (C1 and C6 at 0); the estimator
(photogram.mocap.evaluation.sync.estimate_offsets) reports each offset with a
block-bootstrap sigma. Printed: the errors, |error| / sigma and the share
of offsets within 2 sigma.

REAL data: Pose2Sim's demo (4 cameras, 100 frames at 60 fps, /work/shared/data;
skipped when absent): cam_03's estimated offset, and the same after
shifting cam_03's detections by 2 frames (must come back as +2), and the
cameras' median residual vectors.

Run: .venv/bin/python benchmarks/mocap_sync.py [--draws 4]
"""

from __future__ import annotations

import argparse
import time
import warnings
from dataclasses import replace
from pathlib import Path

import photogram  # noqa: F401  (one BLAS thread before numpy)
import numpy as np

from photogram.mocap.evaluation.sync import (estimate_offsets, shift_observations,
                                             shift_rotations, shift_series)

TRUE_OFFSETS = {1: 2.0, 2: -1.4, 3: 0.5, 4: -3.0}
DEMO = Path(__file__).resolve().parents[1] / "projects" / "pose2sim-demo" / "demo.prj"


def desynchronised(sim, offsets: dict, rng, noise: float = 1.0, outliers: float = 0.05,
                   few: int | None = None, few_share: float = 0.3):
    """Detections (F, C, J, 3) and cameras of ``sim`` recorded with
    ``offsets`` (camera index -> frames; module doc); ``few``: a camera
    that keeps only ``few_share`` of the frames (one stretch)."""
    cams = sim.cameras
    F, C, J = sim.observations.shape[:3]
    R = np.array(cams.rotations(F))
    io = [np.array(np.broadcast_to(p, (F, p.shape[1]))) for p in cams.io]
    xy = np.empty((F, C, J, 2))
    for c in range(C):
        o = float(offsets.get(c, 0.0))
        R[:, c] = shift_rotations(R[:, c], -o)
        io[c] = shift_series(io[c], -o, edge=True)
        one = replace(cams.select_cameras([cams.names[c]]), R=R[:, c:c + 1], io=[io[c]])
        xy[:, c] = one.project(shift_series(sim.joints, -o))[:, 0]
    cams = replace(cams, R=R, io=io)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)     # frames outside the recording
        height = np.nanmax(xy[..., 1], axis=2) - np.nanmin(xy[..., 1], axis=2)
    u = rng.uniform(0, 1, (F, C, J))
    sigma = noise * 0.008 * height[..., None] * (0.5 + u)
    obs = np.empty((F, C, J, 3))
    obs[..., :2] = xy + rng.normal(0, 1, (F, C, J, 2)) * sigma[..., None]
    obs[..., 2] = np.clip(0.95 - 0.45 * u, 0.05, 1.0)
    out = rng.uniform(0, 1, (F, C, J)) < outliers
    ang = rng.uniform(0, 2 * np.pi, (F, C, J))
    dist = rng.uniform(50, 150, (F, C, J))
    obs[..., :2] += np.where(out[..., None], np.stack([np.cos(ang), np.sin(ang)], -1)
                             * dist[..., None], 0.0)
    gone = ~np.all(np.isfinite(xy), -1) | (rng.uniform(0, 1, (F, C, J)) < 0.01)
    if few is not None:
        n = int(few_share * F)
        start = int(rng.integers(0, F - n))
        keep = np.zeros(F, bool)
        keep[start:start + n] = True
        gone[~keep, few] = True
    obs[gone] = np.nan
    obs[gone, 2] = 0.0
    return obs, cams


def run_setting(sim, label: str, draws: int, harsh: bool, seed: int) -> dict:
    errs, zs = [], []
    t0 = time.perf_counter()
    for d in range(draws):
        rng = np.random.default_rng(seed + d)
        obs, cams = desynchronised(sim, TRUE_OFFSETS, rng, noise=3.0 if harsh else 1.0,
                                   outliers=0.15 if harsh else 0.05,
                                   few=int(rng.integers(1, 6)) if harsh else None)
        est = estimate_offsets(obs, cams, sim.fps, reference=0, seed=d)
        truth = np.array([TRUE_OFFSETS.get(c, 0.0) for c in range(len(cams.names))])
        e = est.offsets - truth
        for c in range(1, len(truth)):
            errs.append(e[c])
            zs.append(abs(e[c]) / est.sigma[c])
        print(f"  {label} draw {d}: " + ", ".join(
            f"{n} {o:+.2f}+-{s:.2f} (true {t:+.1f})"
            for n, o, s, t in zip(cams.names[1:], est.offsets[1:], est.sigma[1:], truth[1:])))
    errs, zs = np.abs(errs), np.array(zs)
    res = {"max_err": float(errs.max()), "rms_err": float(np.sqrt(np.mean(errs ** 2))),
           "within2": float(np.mean(zs <= 2.0)), "rms_z": float(np.sqrt(np.mean(zs ** 2))),
           "seconds": (time.perf_counter() - t0) / draws}
    print(f"{label}: |error| max {res['max_err']:.3f} RMS {res['rms_err']:.3f} frames, "
          f"within 2 sigma {100 * res['within2']:.0f} %, RMS error/sigma {res['rms_z']:.2f}, "
          f"{res['seconds']:.1f} s per draw")
    return res


def demo_figures() -> dict | None:
    """cam_03's offset on Pose2Sim's demo, and with its detections shifted by 2 frames."""
    from photogram.mocap.files import cameras_from_project
    from photogram.mocap.pipeline import _observations
    from photogram.project import read_project
    try:
        project = read_project(DEMO)
    except Exception as exc:                     # data absent: skip
        print(f"Pose2Sim demo skipped ({exc})")
        return None
    cams = cameras_from_project(project)
    _, _, obs = _observations(project, cams)
    ms = project.mocap
    est = estimate_offsets(obs, cams, ms.fps, reference=0)
    for line in est.lines():
        print("  demo: " + line)
    c = cams.index("cam_03")
    moved = obs.copy()
    moved[:, c] = shift_observations(obs[:, c], -2.0)
    est2 = estimate_offsets(moved, cams, ms.fps, reference=0)
    print(f"  demo, cam_03 recorded 2 frames later: {est2.offsets[c]:+.2f} +- "
          f"{est2.sigma[c]:.2f} (expected {est.offsets[c] + 2:+.2f})")
    return {"cam03": float(est.offsets[c]), "cam03_sigma": float(est.sigma[c]),
            "cam03_shifted2": float(est2.offsets[c])}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=int, default=4)
    args = ap.parse_args()
    from photogram.simulation.ski.simulate import simulate_session
    sim = simulate_session(seed=8)
    print(f"SIMULATED: {len(sim.joints)} frames, {len(sim.cameras.names)} cameras, offsets "
          + ", ".join(f"C{c + 1} {o:+.1f}" for c, o in TRUE_OFFSETS.items()))
    normal = run_setting(sim, "normal", args.draws, False, 100)
    harsh = run_setting(sim, "harsh", args.draws, True, 200)
    demo = demo_figures()
    d = "n/a" if demo is None else f"{demo['cam03']:+.3f}"
    ds = "n/a" if demo is None else f"{demo['cam03_sigma']:.3f}"
    d2 = "n/a" if demo is None else f"{demo['cam03_shifted2']:+.3f}"
    print(f"RESULT normal_max_err={normal['max_err']:.3f} normal_within2={normal['within2']:.2f} "
          f"harsh_max_err={harsh['max_err']:.3f} harsh_within2={harsh['within2']:.2f} "
          f"demo_cam03={d} demo_cam03_sigma={ds} demo_cam03_shift2={d2}")


if __name__ == "__main__":
    main()
