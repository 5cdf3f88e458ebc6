"""Where the estimated-rotation mode's error is: per frame (SIMULATED).

Generates the estimate-mode project of one setting and seed as
``benchmarks/ski_ptz.py`` does (harsh: photogram.simulation.ski.harsh;
old: photogram.simulation.ski.simulate), runs ``photogram mocap`` on it in
process and prints every ``--step`` frames the MPJPE against the truth, the
error of the joints' centroid (x, y, z), the distance to the nearest camera,
the number of cameras with detections, and the rotation error of every
camera (final and bootstrap), then the per-camera medians.

Run: .venv/bin/python benchmarks/ski_ptz_frames.py [--setting harsh|old] [--seed 22] [--step 10]
"""

import argparse
import sys
import tempfile
import time
from pathlib import Path

import photogram  # noqa: F401  (one BLAS thread before numpy)
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from ski_ptz import build_projects  # noqa: E402


def angles(A, B):
    """Angles (deg) between rotation stacks A and B (..., 3, 3)."""
    E = np.einsum("...ab,...db->...ad", A, B)
    return np.degrees(np.arccos(np.clip((np.trace(E, axis1=-2, axis2=-1) - 1) / 2, -1, 1)))


def main():
    from photogram.mocap.pipeline import run_mocap
    from photogram.project import read_project
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--setting", choices=("harsh", "old"), default="harsh")
    ap.add_argument("--seed", type=int, default=22)
    ap.add_argument("--step", type=int, default=10)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        sim, _, prjs = build_projects(args.setting, args.seed, Path(tmp))
        t0 = time.perf_counter()
        r = run_mocap(read_project(prjs["estimate"]))
        wall = time.perf_counter() - t0
    X = r.reconstruction.joints
    T = sim.joints[:len(X)]
    mpjpe = np.nanmean(np.linalg.norm(X - T, axis=-1), axis=1)
    centroid = np.nanmean(X, 1) - np.nanmean(T, 1)
    Rt = sim.cameras.R[:len(X)]
    err, boot = angles(r.reconstruction.R, Rt), angles(r.reconstruction.R_bootstrap, Rt)
    dist = np.linalg.norm(np.nanmean(T, 1)[:, None] - r.cameras.X0[None], axis=-1)
    seen = np.sum(np.sum(np.isfinite(r.observations[..., 0]), axis=2) >= 4, axis=1)
    print(f"SIMULATED {args.setting} seed {args.seed}: {len(X)} frames, {wall:.1f} s; global "
          f"MPJPE {np.nanmean(mpjpe):.3f} m, rotation error median {np.median(err):.3f} deg "
          f"(bootstrap {np.median(boot):.3f})")
    names = " ".join(f"{n:>5}" for n in r.cameras.names)
    print(f"frame MPJPE_m centroid_error_xyz_m  nearest_m cams  rotation error deg {names}"
          f" | bootstrap")
    for f in range(0, len(X), args.step):
        print(f"{f:5d} {mpjpe[f]:7.3f} {np.array2string(centroid[f], precision=2):>22} "
              f"{dist[f].min():8.1f} {seen[f]:4d}  {'':18} "
              + " ".join(f"{a:5.2f}" for a in err[f]) + " | "
              + " ".join(f"{a:5.2f}" for a in boot[f]))
    print("per camera rotation error median " + " ".join(f"{a:.3f}" for a in np.median(err, 0))
          + ", p95 " + " ".join(f"{a:.2f}" for a in np.percentile(err, 95, 0)))
    acc = r.accuracy or {}
    print(f"accuracy: MPJPE {acc.get('mpjpe', np.nan):.4f} m, speed MAE "
          f"{acc.get('speed_mae', np.nan):.3f} m/s, knee MAE "
          f"{acc.get('knee_flexion_mae', np.nan):.2f} deg")


if __name__ == "__main__":
    main()
