"""Scaling of the adjustment engine with the number of object points.

Synthetic wall networks (photogram.simulation.network.wall_network): 100
stations, ~20 rays per point, 0.5 px noise, 10 fixed control points, interior
orientation fixed; approximations = truth + 5 cm / 5 mrad. For 1250 ... 10000
points (25,000 ... 200,000 image points) the script prints the time per
Gauss-Newton iteration and per 1000 points; linear growth means a constant
last column.

The smallest network is solved once untimed first (loading numba's cached
kernels when numba is installed).

Run: .venv/bin/python benchmarks/scaling.py [--points 1250,2500,5000,10000]
"""

import argparse
import time

import photogram  # noqa: F401  (sets single-threaded BLAS before numpy)
import numpy as np

from photogram.adjust import kernels
from photogram.adjust.build import build_problem
from photogram.adjust.solver import SolverOptions, solve
from photogram.simulation.network import to_project, wall_network


def run(n_points, seed=0):
    net = wall_network(n_stations=100, n_points=n_points, seed=seed)
    prj = to_project(net, control=range(10), perturb_points=0.05, perturb_stations=0.005,
                     sigma_image=0.5, rng=np.random.default_rng(seed))
    prj.adjustment.datum = "control"
    t0 = time.perf_counter()
    built = build_problem(prj)
    t1 = time.perf_counter()
    s = solve(built.problem, SolverOptions(max_iterations=30))
    t2 = time.perf_counter()
    err = np.sqrt(np.mean((built.problem.state.points - net.points) ** 2))
    return {"points": n_points, "observations": len(net.station), "build": t1 - t0,
            "solve": t2 - t1, "iterations": s.iterations, "status": s.status,
            "sigma0": s.sigma0, "per_iteration": (t2 - t1) / max(s.iterations, 1),
            "rmse_points": err}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", default="1250,2500,5000,10000")
    args = ap.parse_args()
    sizes = [int(n) for n in args.points.split(",")]
    run(sizes[0])        # warm-up: numba's cached kernels load once per process
    print(f"numba kernels: {'on' if kernels.use_numba() else 'off (numpy path)'}")
    rows = [run(n) for n in sizes]
    print(f"{'points':>7} {'obs':>8} {'iter':>4} {'status':>10} {'sigma0':>7} "
          f"{'build s':>8} {'solve s':>8} {'s/iter':>7} {'ms/iter/1000 pts':>17} {'rmse m':>8}")
    for r in rows:
        print(f"{r['points']:>7} {r['observations']:>8} {r['iterations']:>4} {r['status']:>10} "
              f"{r['sigma0']:7.3f} {r['build']:8.3f} {r['solve']:8.3f} {r['per_iteration']:7.3f} "
              f"{1000 * r['per_iteration'] / (r['points'] / 1000):17.1f} {r['rmse_points']:8.4f}")
    first, last = rows[0], rows[-1]
    growth = (last["per_iteration"] / first["per_iteration"]) / (last["points"] / first["points"])
    print(f"RESULT points={last['points']} observations={last['observations']} "
          f"iterations={last['iterations']} status={last['status']} "
          f"s_per_iteration={last['per_iteration']:.3f} solve_s={last['solve']:.2f} "
          f"growth_vs_linear={growth:.2f}")


if __name__ == "__main__":
    main()
