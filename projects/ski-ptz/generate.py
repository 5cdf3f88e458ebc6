"""Write the SIMULATED example project projects/ski-ptz (fixed seed).

A giant-slalom run with three turns (279 frames at 50 fps, 15.5-19.5 m/s),
a 24-joint skier with skis and poles, six pan-tilt-zoom cameras on a circle
of 40 m radius around the course that follow the athlete (known rotations
and zoom per frame), noisy 2D detections with confidences, 5 % outliers and
occasional left/right swaps; the truth in truth/; the camera images are
rendered and the rotation differences measured on them for the project
with unknown rotations (ski-ptz-estimate.prj). The scene is described in
photogram/simulation/ski/simulate.py, the files in photogram/simulation/ski/simproject.py.

Run:  .venv/bin/python projects/ski-ptz/generate.py [--out DIR] [--runs N]

The output is byte for byte the same on every run (tests/test_mocap_project.py
regenerates it and compares).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import photogram  # noqa: F401  (one BLAS thread before numpy)
from photogram.mocap.motion.rotation_series import write_rotation_differences
from photogram.simulation.ski.simimages import simulated_differences
from photogram.simulation.ski.simproject import write_estimate_project, write_simulated_project
from photogram.simulation.ski.simulate import simulate_session

SEED = 8
HERE = Path(__file__).resolve().parent


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=HERE, help="folder to write (default: here)")
    ap.add_argument("--runs", type=int, default=1, help="runs of 279 frames (default 1)")
    ap.add_argument("--no-differences", action="store_true",
                    help="skip rendering the images and measuring the rotation differences")
    args = ap.parse_args(argv)
    sim = simulate_session(seed=SEED, n_runs=args.runs)
    for path in write_simulated_project(sim, args.out):
        print(path)
    if not args.no_differences:
        per, _ = simulated_differences(sim, n_jobs=2)
        print(write_rotation_differences(
            args.out / "rotation_differences.csv", per, comment=(
                f"SIMULATED data (photogram.simulation.ski.simulate, seed {SEED}): not measured.\n"
                "Written by projects/ski-ptz/generate.py: the camera images rendered by "
                "photogram.simulation.ski.render (960 x 540),\nthe rotation differences measured on "
                "them by photogram.mocap.motion.homography (raw; photogram filters them).")))
        print(write_estimate_project(sim, args.out))


if __name__ == "__main__":
    main()
