"""CAMCAL (DBAT's camera-calibration demo, real data): speed of the
self-calibrating bundle adjustment against scipy.optimize.least_squares on
the same problem, measured side by side, and against DBAT's reported time.

Both solvers start from the same approximate values (the approximation
chain) and minimize the same whitened residuals with the same analytic
Jacobian; scipy uses method "trf" with x_scale="jac" and a sparse Jacobian.
DBAT (MATLAB) is not available here: its 0.50 s is the figure its report
prints for the same bundle (dbat-report.txt, "Bundle: 0.50").

Run: .venv/bin/python benchmarks/camcal.py [--repeat 5]
Needs ../shared/data/dbat/camcal beside the repository.
"""

import argparse
import copy
import statistics
import time
from pathlib import Path

import photogram  # noqa: F401  (single-threaded BLAS before numpy)
import numpy as np
import scipy.sparse as sp
from scipy.optimize import least_squares

from photogram.adjust.build import build_problem
from photogram.adjust.solver import solve
from photogram.init.chain import approximate
from photogram.io.dbat import load_dbat_project

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "dbat" / "camcal"
DBAT_SECONDS = 0.50
FREE = ("c", "x0", "y0", "K1", "K2", "K3", "P1", "P2", "B1")


def camcal_project():
    prj = load_dbat_project(DATA / "markpts.txt", DATA / "camcal-fixed.txt", DATA / "c4040z.xml")
    cam = next(iter(prj.cameras.values()))
    for name in FREE:
        cam.parameters[name].free = True
    prj.adjustment.datum = "control"
    prj, _ = approximate(prj)
    return prj


def photogram_run(prj):
    built = build_problem(prj)
    t = time.perf_counter()
    s = solve(built.problem)
    return time.perf_counter() - t, s.iterations, s.final_cost, s.sigma0


def scipy_run(prj):
    """The same problem through scipy.optimize.least_squares (trf)."""
    p = build_problem(prj).problem
    lay = p.layout
    free = np.flatnonzero(lay.free)
    col_of = np.full(lay.n_columns, -1)
    col_of[free] = np.arange(len(free))
    state0 = p.state

    def x_to_state(x):
        dx = np.zeros(lay.n_columns)
        dx[free] = x
        return state0.updated(lay, dx)

    def fun(x):
        rs, _ = p.evaluate(x_to_state(x), jacobians=False)
        return np.concatenate([r.ravel() for r in rs])

    def jac(x):
        # the increment parametrization is exact at x only for x = 0, so
        # rebuild around the current point: J(x) ~ J at the updated state
        # (rotation increments compose; adequate for a benchmark peer)
        _, Js = p.evaluate(x_to_state(x))
        rows, cols, vals, off = [], [], [], 0
        for blk, J in zip(p.blocks, Js):
            n, d = len(blk), blk.dim
            ridx = off + np.arange(n * d).reshape(n, d)
            for Jj, c in zip(J, blk.slot_cols):
                rr = np.broadcast_to(ridx[:, :, None], Jj.shape)
                cc = np.broadcast_to(col_of[c][:, None, :], Jj.shape)
                m = cc >= 0
                rows.append(rr[m]), cols.append(cc[m]), vals.append(Jj[m])
            off += n * d
        return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                             shape=(off, len(free)))

    t = time.perf_counter()
    res = least_squares(fun, np.zeros(len(free)), jac=jac, method="trf", x_scale="jac",
                        tr_solver="lsmr")
    return time.perf_counter() - t, res.nfev, res.cost, np.sqrt(2 * res.cost / p.redundancy())


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    if not DATA.is_dir():
        print(f"CAMCAL data not found at {DATA}")
        print("RESULT status=skipped")
        return
    prj = camcal_project()
    ours = [photogram_run(copy.deepcopy(prj)) for _ in range(args.repeat)]
    theirs = [scipy_run(copy.deepcopy(prj)) for _ in range(max(1, args.repeat // 2))]
    t_ours = statistics.median(r[0] for r in ours)
    t_scipy = statistics.median(r[0] for r in theirs)
    _, it, cost, s0 = ours[0]
    _, nfev, cost_sp, s0_sp = theirs[0]
    print(f"{'solver':<28} {'median s':>9} {'iterations':>10} {'final cost':>12} {'sigma0':>8}")
    print(f"{'photogram (Schur GN/LM)':<28} {t_ours:9.3f} {it:>10} {cost:12.4f} {s0:8.4f}")
    print(f"{'scipy least_squares trf':<28} {t_scipy:9.3f} {nfev:>10} {cost_sp:12.4f} {s0_sp:8.4f}")
    print(f"{'DBAT 0.9.2 (reported)':<28} {DBAT_SECONDS:9.3f} {8:>10} {'':>12} {1.6148:8.4f}")
    print(f"RESULT camcal_s={t_ours:.3f} iterations={it} sigma0={s0:.5f} scipy_s={t_scipy:.3f} "
          f"speedup_vs_scipy={t_scipy / t_ours:.1f} speedup_vs_dbat_reported={DBAT_SECONDS / t_ours:.1f}")


if __name__ == "__main__":
    main()
