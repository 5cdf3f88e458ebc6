"""Markerless ski motion capture with known camera rotations (issue 8, part 1).

SIMULATED data (photogram.mocap.simulate, seed 8): six giant-slalom runs of
three turns, 279 frames each (1674 frames at 50 fps), a 24-joint skier
with skis and poles at 15.5-19.5 m/s, six pan-tilt-zoom cameras on a circle
of 40 m radius that follow the athlete (known rotations and zoom per
frame), noisy detections with 5 % outliers and left/right swaps. The runs
are independent segments (windows never cross them).

Reconstructs all 1674 frames x 6 cameras x 24 joints with the default
solver (Gauss-Newton/IRLS with PCG, photogram.mocap.solvers) and with the
paper's L-BFGS (same energy, same continuation), and prints accuracy
against the truth, the energy reached and the time of each; the goals are
global MPJPE <= 0.05 m, knee-flexion MAE <= 3 deg and <= 30 s.

Run: .venv/bin/python benchmarks/ski_ptz.py [--runs 6] [--no-lbfgs]
"""

import argparse
import time

import photogram  # noqa: F401  (one BLAS thread before numpy)
import numpy as np

from photogram.mocap.metrics import accuracy_3d, biomechanics
from photogram.mocap.reconstruct import ReconstructionSettings, reconstruct
from photogram.mocap.simulate import simulate_session
from photogram.mocap.skeleton import SKI24


def evaluate(rec, sim):
    acc = accuracy_3d(rec.joints, sim.joints, SKI24)
    b = biomechanics(rec.joints, SKI24, sim.fps, sim.breaks, sim.slope_normal)
    t = biomechanics(sim.joints, SKI24, sim.fps, sim.breaks, sim.slope_normal)
    knee = np.concatenate([np.abs(b[k] - t[k]) for k in ("knee_flexion_r", "knee_flexion_l")])
    hip = np.concatenate([np.abs(b[k] - t[k]) for k in ("hip_flexion_r", "hip_flexion_l")])
    com = np.stack([b[k] - t[k] for k in ("com_x", "com_y", "com_z")], -1)
    acc.update(knee_mae=float(np.nanmean(knee)), hip_mae=float(np.nanmean(hip)),
               lean_mae=float(np.nanmean(np.abs(b["lean"] - t["lean"]))),
               fore_aft_mae=float(np.nanmean(np.abs(b["fore_aft_angle"] - t["fore_aft_angle"]))),
               com_error=float(np.nanmean(np.linalg.norm(com, axis=-1))),
               speed_mae=float(np.nanmean(np.abs(b["speed"] - t["speed"]))))
    return acc


def run(sim, solver):
    s = ReconstructionSettings(solver=solver)
    t0, c0 = time.perf_counter(), time.process_time()
    rec = reconstruct(sim.observations, sim.cameras, SKI24, s, breaks=sim.breaks)
    return rec, time.perf_counter() - t0, time.process_time() - c0


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=6, help="runs of 279 frames (default 6)")
    ap.add_argument("--no-lbfgs", action="store_true", help="skip the L-BFGS comparison")
    args = ap.parse_args()
    sim = simulate_session(seed=8, n_runs=args.runs)
    F, C, J, _ = sim.observations.shape
    print(f"simulated: {F} frames x {C} cameras x {J} joints, {args.runs} runs, "
          f"speed {sim.info['speed_min']:.1f}-{sim.info['speed_max']:.1f} m/s, "
          f"{int(sim.outlier.sum())} outliers, {int(sim.swapped.sum())} swapped camera frames")
    rows = {}
    for solver in ("gauss-newton",) + (() if args.no_lbfgs else ("lbfgs",)):
        rec, wall, cpu = run(sim, solver)
        acc = evaluate(rec, sim)
        rows[solver] = (rec, wall, cpu, acc)
        print(f"{solver:>12}: energy {rec.energy:.1f}  iterations {rec.iterations}  "
              f"windows {rec.n_windows}  wall {wall:.1f} s  cpu {cpu:.1f} s")
        print(f"{'':>12}  MPJPE {1000 * acc['mpjpe']:.1f} mm (hip-centred "
              f"{1000 * acc['mpjpe_hip']:.1f}, normalised {1000 * acc['mpjpe_normalized']:.1f}, "
              f"body {1000 * acc['mpjpe_body']:.1f}), knee {acc['knee_mae']:.2f} deg, hip "
              f"{acc['hip_mae']:.2f} deg, lean {acc['lean_mae']:.2f} deg, fore/aft "
              f"{acc['fore_aft_mae']:.2f} deg, CoM {1000 * acc['com_error']:.1f} mm, speed "
              f"{acc['speed_mae']:.3f} m/s")
    rec, wall, cpu, acc = rows["gauss-newton"]
    ok = acc["mpjpe"] <= 0.05 and acc["knee_mae"] <= 3.0 and wall <= 30.0
    line = (f"RESULT frames={F} cameras={C} joints={J} solver=gauss-newton "
            f"mpjpe_m={acc['mpjpe']:.4f} mpjpe_body_m={acc['mpjpe_body']:.4f} "
            f"knee_mae_deg={acc['knee_mae']:.2f} time_s={wall:.1f} cpu_s={cpu:.1f} "
            f"energy={rec.energy:.1f}")
    if "lbfgs" in rows:
        rl, wl, cl, al = rows["lbfgs"]
        line += (f" lbfgs_energy={rl.energy:.1f} lbfgs_time_s={wl:.1f} "
                 f"lbfgs_mpjpe_m={al['mpjpe']:.4f}")
    print(line + f" goals={'met' if ok else 'missed'}")


if __name__ == "__main__":
    main()
