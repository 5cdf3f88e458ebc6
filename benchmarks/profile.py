"""Where the time of one engine iteration goes, and how it scales.

For each problem the stages of one Gauss-Newton / Levenberg-Marquardt
iteration are timed separately at the start values (median of
``--repeat``):

* residuals + Jacobian: ``Problem.evaluate`` (camera model, whitening)
* blocks: ``assemble`` (per-row ``Je^T Je``, ``Je^T Jc``, per-group
  ``Jc^T Jc``, gradient)
* Schur complement: damping, 3x3 point inverses and ``S = N_cc - W A^-1 W^T``
  (``reduced_camera_system``)
* factorization: Jacobi scaling and dense Cholesky of S
* back-substitution: ``dx_c`` from the factor, ``dx_e = -A^-1 (g_e + W^T dx_c)``
* cost: the residuals of the trial point (no Jacobian)

Problems: the BAL problems (../shared/data/bal, when present) and synthetic
wall networks (photogram.simulation.network's wall geometry: 100 stations,
~20 rays per point, brown camera with fixed interior orientation, 10 fixed
control points, start = truth + 5 cm) with 10^4, 10^5 and 10^6 image
observations. Both kernel paths (numba, numpy) when numba is installed.

Run: .venv/bin/python benchmarks/profile.py [--sizes 1e4,1e5,1e6] [--paths numba,numpy]
     [--no-bal] [--repeat 3] [--solve]
"""

import argparse
import statistics
import time
from pathlib import Path

import photogram  # noqa: F401  (single-threaded BLAS before numpy)
import numpy as np
import scipy.linalg as la

from photogram.adjust import kernels
from photogram.adjust.build import build_problem
from photogram.adjust.normal import assemble
from photogram.adjust.schur import damped, invert_point_blocks, reduced_camera_system
from photogram.adjust.solver import SolverOptions, solve
from photogram.simulation.network import SyntheticNetwork, observe, to_project, wall_geometry

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "bal"
STAGES = ("jacobian", "blocks", "schur", "factorization", "back_substitution", "cost")


def wall(n_points, n_stations=100, distance=10.0, rays=20, sigma=0.5, seed=0, chunk=4000):
    """The geometry of ``photogram.simulation.network.wall_network``, with
    the points projected in chunks (10^6 observations without a 5 GB
    temporary)."""
    pts, X0, R, io, (w, h), rng = wall_geometry(n_stations, n_points, distance, rays, seed)
    cam = np.zeros(n_stations, int)
    parts = [observe("brown", io, cam, R, X0, pts[i:i + chunk], (w, h), sigma=sigma, rng=rng,
                     margin=5) for i in range(0, n_points, chunk)]
    offsets = np.arange(0, n_points, chunk)
    return SyntheticNetwork(
        "brown", parts[0].io, (w, h), cam, R, X0, pts,
        np.concatenate([p.station for p in parts]),
        np.concatenate([p.point + o for p, o in zip(parts, offsets)]),
        np.concatenate([p.xy_true for p in parts]), np.concatenate([p.xy for p in parts]))


def wall_problem(n_obs):
    n_points = max(50, int(round(n_obs / 19.4)))   # ~19.4 rays per point on this wall
    net = wall(n_points)
    prj = to_project(net, control=range(10), perturb_points=0.05, perturb_stations=0.005,
                     sigma_image=0.5, rng=np.random.default_rng(0))
    prj.adjustment.datum = "control"
    return build_problem(prj).problem, len(net.station), 0.0


def bal_problem(key):
    from photogram.bundle.bal import build_bal_problem
    from photogram.io.bal import read_bal
    built = build_bal_problem(read_bal(DATA / f"problem-{key}-pre.txt.bz2"))
    return built.problem, built.bal.n_observations, 1e-4    # trust region: always damped


def stage_times(p, damping, repeat):
    """Median ms of each stage of one iteration."""
    out = {k: [] for k in STAGES}
    lay = p.layout
    n_r = lay.n_reduced
    for _ in range(repeat):
        t0 = time.perf_counter()
        rs, Js = p.evaluate(p.state)
        t1 = time.perf_counter()
        system = assemble(p.structure, rs, Js)
        t2 = time.perf_counter()
        Ncc, A = damped(system, lay, damping)
        Ainv = invert_point_blocks(A)
        S, YGe = reduced_camera_system(system, Ainv, Ncc)
        t3 = time.perf_counter()
        d = 1.0 / np.sqrt(np.where(np.diag(S) > 0, np.diag(S), 1.0))
        cho = la.cho_factor(S * d[:, None] * d[None, :])
        t4 = time.perf_counter()
        g_c, g_e = system.g[:n_r], system.g[n_r:].reshape(-1, 3)
        dx_c = d * la.cho_solve(cho, d * (-g_c + YGe))
        rhs_e = -g_e - system.wt_times_c(dx_c)
        dx_e = np.matmul(Ainv, rhs_e[:, :, None])[:, :, 0].ravel()
        dx = np.concatenate([dx_c, dx_e])
        dx[~lay.free] = 0.0
        t5 = time.perf_counter()
        p.cost(p.state.updated(lay, dx))
        t6 = time.perf_counter()
        for k, (a, b) in zip(STAGES, ((t0, t1), (t1, t2), (t2, t3), (t3, t4), (t4, t5), (t5, t6))):
            out[k].append(1e3 * (b - a))
    return {k: statistics.median(v) for k, v in out.items()}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="1e4,1e5,1e6", help="wall network observations")
    ap.add_argument("--paths", default="numba,numpy" if kernels.HAVE_NUMBA else "numpy")
    ap.add_argument("--no-bal", action="store_true")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--solve", action="store_true", help="also solve each wall network")
    args = ap.parse_args()
    cases = []
    if not args.no_bal and DATA.is_dir():
        cases += [("BAL " + k, lambda k=k: bal_problem(k)) for k in ("49-7776", "21-11315", "16-22106")]
    cases += [(f"wall {float(s):.0e}", lambda s=s: wall_problem(float(s))) for s in args.sizes.split(",")]
    paths = args.paths.split(",")
    print(f"{'problem':<14} {'path':<6} {'obs':>9} {'n_r':>5} "
          + " ".join(f"{k[:13]:>13}" for k in STAGES) + f" {'total ms':>9} {'us/obs':>7}")
    rows = []
    for name, make in cases:
        t = time.perf_counter()
        p, n_obs, damping = make()
        t_build = time.perf_counter() - t
        for path in paths:
            kernels.use_numba(path == "numba", min_rows=0 if path == "numba" else None)
            stage_times(p, damping, 1)                      # warm-up (numba load, pair plans)
            st = stage_times(p, damping, args.repeat)
            total = sum(st.values())
            rows.append((name, path, n_obs, st, total))
            print(f"{name:<14} {path:<6} {n_obs:>9} {p.layout.n_reduced:>5} "
                  + " ".join(f"{st[k]:13.1f}" for k in STAGES)
                  + f" {total:9.1f} {1e3 * total / n_obs:7.2f}", flush=True)
            if args.solve and name.startswith("wall"):
                state0 = p.state.copy()
                t = time.perf_counter()
                s = solve(p, SolverOptions(max_iterations=30))
                dt = time.perf_counter() - t
                p.state = state0
                print(f"{'':<14} solve: {s.iterations} iterations, {dt:.2f} s, sigma0 {s.sigma0:.3f}, "
                      f"build {t_build:.1f} s", flush=True)
    walls = [r for r in rows if r[0].startswith("wall") and r[1] == paths[0]]
    res = {f"{r[0].split()[1]}_{paths[0]}_ms": f"{r[4]:.0f}" for r in walls}
    if len(walls) >= 2:
        first, last = walls[0], walls[-1]
        res["growth_vs_linear"] = f"{(last[4] / first[4]) / (last[2] / first[2]):.2f}"
        res.update({f"{k}_ms": f"{last[3][k]:.0f}" for k in STAGES})
    print("RESULT " + " ".join(f"{k}={v}" for k, v in res.items()))


if __name__ == "__main__":
    main()
