"""Window seams and the rotation chain across tracking gaps (issue 22, items 3-4).

SIMULATED data (photogram.simulation.ski.simulate.simulate_session): one giant-slalom
run of ``--frames`` frames (default 450) filmed by six pan-tilt-zoom cameras,
degraded here:

* ``normal``: seed 8, the simulator's detections, camera C3 without any
  detection for 95 frames from frame F/3 (a tracking loss);
* ``harsh`` (not tuned on): seed 21, Student-t (3 degrees of freedom)
  noise of 2.5 % of the athlete's image height added to every detection, 5 %
  more outliers moved by 50-300 px, C3 blank for 95 frames from F/2 - 40
  and C5 for the first 60 frames of the run (a gap with a chain on one side
  only), rotation differences with 0.05 deg of noise per axis and pair
  instead of 0.02 deg.

Both modes run: known rotations (``reconstruct``) and estimated rotations
(``estimate_poses_and_rotations`` from the true differences plus noise, as
``benchmarks/ski_ptz.py --differences truth``). Measured against the truth:

* seam jump: ``|dCoM_rec(t) - dCoM_true(t)|`` between consecutive frames,
  the centre of mass's frame-to-frame motion minus the true motion, mean and
  maximum over the frame pairs in window overlaps and elsewhere;
* the windows' disagreement before blending (``seam_disagreement_m`` of the
  last stage; not reported by code before issue 22);
* global MPJPE, speed MAE of the CoM (metrics.biomechanics), rotation error
  (median over all camera-frames, and median / maximum in the blanked
  frames), run time.

Run: .venv/bin/python benchmarks/mocap_seams.py [--frames 450] [--settings normal harsh]
"""

import argparse
import time

import photogram  # noqa: F401  (one BLAS thread before numpy)
import numpy as np

from photogram.geometry.rotations import rodrigues_to_matrix
from photogram.mocap.body.skeleton import SKI24
from photogram.mocap.evaluation.metrics import biomechanics, centre_of_mass
from photogram.mocap.reconstruction.dct import plan_windows
from photogram.mocap.reconstruction.estimate import (estimate_poses_and_rotations,
                                                     estimate_settings)
from photogram.mocap.reconstruction.reconstruct import ReconstructionSettings, reconstruct
from photogram.simulation.ski.simulate import simulate_session

SETTINGS = {
    "normal": dict(seed=8, noise=0.0, outliers=0.0, dR_noise_deg=0.02,
                   blanks=lambda F: [(2, F // 3, 95)]),
    "harsh": dict(seed=21, noise=0.025, outliers=0.05, dR_noise_deg=0.05,
                  blanks=lambda F: [(2, F // 2 - 40, 95), (4, 0, 60)]),
}


def degraded(name, frames):
    """The simulation and its degraded detections (module doc)."""
    cfg = SETTINGS[name]
    sim = simulate_session(seed=cfg["seed"], n_runs=1, frames_per_run=frames)
    rng = np.random.default_rng(cfg["seed"] + 100)
    obs = sim.observations.copy()
    F, C, J, _ = obs.shape
    if cfg["noise"]:
        xy = sim.image_truth
        with np.errstate(invalid="ignore"):
            h = np.nanmax(xy[..., 1], axis=2) - np.nanmin(xy[..., 1], axis=2)
        obs[..., :2] += rng.standard_t(3, (F, C, J, 2)) * (cfg["noise"] * h)[..., None, None]
    if cfg["outliers"]:
        out = rng.uniform(0, 1, (F, C, J)) < cfg["outliers"]
        ang = rng.uniform(0, 2 * np.pi, (F, C, J))
        dist = rng.uniform(50, 300, (F, C, J))
        shift = np.stack([np.cos(ang), np.sin(ang)], -1) * dist[..., None]
        obs[..., :2] += np.where(out[..., None], shift, 0.0)
    blank = np.zeros((F, C), bool)
    for c, start, n in cfg["blanks"](F):
        blank[start:start + n, c] = True
    obs[blank] = np.nan
    R = sim.cameras.R
    true = R[1:] @ np.swapaxes(R[:-1], -1, -2)
    noise = rng.normal(0, np.radians(cfg["dR_noise_deg"]), (F - 1) * C * 3).reshape(-1, 3)
    dR = rodrigues_to_matrix(noise).reshape(true.shape) @ true
    return sim, obs, blank, dR


def _com(X):
    return centre_of_mass({n: X[:, k] for k, n in enumerate(SKI24.joints)})


def seam_jumps(X, truth, settings, breaks):
    """Mean and maximum excess CoM motion between consecutive frames in window
    overlaps and elsewhere (module doc)."""
    F = len(X)
    jump = np.linalg.norm(np.diff(_com(X), axis=0) - np.diff(_com(truth), axis=0), axis=1)
    cover = np.zeros(F, int)
    for w in plan_windows(F, settings.window, settings.overlap, settings.coefficients, breaks):
        cover[w.start:w.stop] += 1
    seam = (cover[:-1] > 1) | (cover[1:] > 1)
    ok = np.isfinite(jump)
    return {"seam_mean": float(np.mean(jump[seam & ok])),
            "seam_max": float(np.max(jump[seam & ok])),
            "inside_mean": float(np.mean(jump[~seam & ok])),
            "inside_max": float(np.max(jump[~seam & ok]))}


def _angles(R, R_true):
    E = np.einsum("fcab,fcdb->fcad", R, R_true)
    return np.degrees(np.arccos(np.clip((np.trace(E, axis1=2, axis2=3) - 1) / 2, -1, 1)))


def measure(name, mode, frames):
    sim, obs, blank, dR = degraded(name, frames)
    t0, c0 = time.perf_counter(), time.process_time()
    if mode == "known":
        s = ReconstructionSettings()
        rec = reconstruct(obs, sim.cameras, SKI24, s, breaks=sim.breaks)
    else:
        s = estimate_settings()
        rec = estimate_poses_and_rotations(obs, sim.cameras, SKI24, dR, None, s, sim.breaks)
    seconds, cpu = time.perf_counter() - t0, time.process_time() - c0
    b = biomechanics(rec.joints, SKI24, sim.fps, sim.breaks, sim.slope_normal)
    t = biomechanics(sim.joints, SKI24, sim.fps, sim.breaks, sim.slope_normal)
    out = seam_jumps(rec.joints, sim.joints, s, sim.breaks)
    out.update(mpjpe=float(np.nanmean(np.linalg.norm(rec.joints - sim.joints, axis=-1))),
               speed_mae=float(np.nanmean(np.abs(b["speed"] - t["speed"]))), seconds=seconds,
               cpu=cpu)
    dis = rec.stages[-1].get("seam_disagreement_m") or {}
    out["disagreement_p95"] = dis.get("p95", float("nan"))
    if mode == "estimate":
        ang = _angles(rec.R, sim.cameras.R)
        out.update(rot_median=float(np.median(ang)), rot_gap_median=float(np.median(ang[blank])),
                   rot_gap_max=float(np.max(ang[blank])))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=450)
    ap.add_argument("--settings", nargs="+", default=["normal", "harsh"], choices=list(SETTINGS))
    args = ap.parse_args()
    line = f"RESULT frames={args.frames} cameras=6"
    for name in args.settings:
        for mode in ("known", "estimate"):
            r = measure(name, mode, args.frames)
            print(f"{name:>6} {mode:>8}: seam jump mean {100 * r['seam_mean']:.2f} cm max "
                  f"{100 * r['seam_max']:.2f} cm (elsewhere {100 * r['inside_mean']:.2f} / "
                  f"{100 * r['inside_max']:.2f} cm), windows' disagreement p95 "
                  f"{100 * r['disagreement_p95']:.2f} cm, MPJPE {100 * r['mpjpe']:.2f} cm, speed "
                  f"MAE {r['speed_mae']:.3f} m/s"
                  + (f", rotation error median {r['rot_median']:.3f} deg, in the gaps median "
                     f"{r['rot_gap_median']:.3f} max {r['rot_gap_max']:.2f} deg"
                     if mode == "estimate" else "")
                  + f", wall {r['seconds']:.1f} s, cpu {r['cpu']:.1f} s")
            key = f"{name}_{mode}"
            line += (f" {key}_seam_jump_cm={100 * r['seam_mean']:.2f} {key}_seam_max_cm="
                     f"{100 * r['seam_max']:.2f} {key}_speed_mae={r['speed_mae']:.3f} "
                     f"{key}_mpjpe_m={r['mpjpe']:.4f}")
            if mode == "estimate":
                line += (f" {key}_rot_median_deg={r['rot_median']:.3f} {key}_rot_gap_median_deg="
                         f"{r['rot_gap_median']:.3f} {key}_rot_gap_max_deg={r['rot_gap_max']:.2f}"
                         f" {key}_cpu_s={r['cpu']:.1f}")
    print(line)


if __name__ == "__main__":
    main()
