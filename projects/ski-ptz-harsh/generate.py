"""Write the SIMULATED harsh example project projects/ski-ptz-harsh (fixed seed).

One giant-slalom run of five turns over a kicker on a non-planar slope
(450 frames at 50 fps), six pan-tilt-zoom cameras that lag and jitter on
mis-levelled bases, a poor 2D detector (about 20 px mean error, Student-t
noise, 7 % outliers, swaps in bursts, occlusions), bystanders (one nearer
camera C1 than the athlete), a 95-frame tracking loss and a jump; every
detected person has a shuffled id per frame and truth/identity.csv says
which is the athlete. The setting is described in
photogram/simulation/ski/harsh.py and harsh_detector.py, the files in
photogram/simulation/ski/harsh_project.py.

Run:  .venv/bin/python projects/ski-ptz-harsh/generate.py [--out DIR] [--seed N]

The output is byte for byte the same on every run
(tests/test_simulation_harsh.py regenerates it and compares).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import photogram  # noqa: F401  (one BLAS thread before numpy)
from photogram.simulation.ski.harsh import simulate_harsh
from photogram.simulation.ski.harsh_project import write_harsh_project

SEED = 22
HERE = Path(__file__).resolve().parent


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=HERE, help="folder to write (default: here)")
    ap.add_argument("--seed", type=int, default=SEED, help=f"seed (default {SEED})")
    args = ap.parse_args(argv)
    for path in write_harsh_project(simulate_harsh(seed=args.seed), args.out):
        print(path)


if __name__ == "__main__":
    main()
