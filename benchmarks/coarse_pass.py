"""The two-level preconditioner's coarse pass and its preconditioners, timed.

``kernels N``: on the SIMULATED sphere problem of N cameras (seed 0),
linearized at the start values with damping 1e-3, the CPU seconds (best
of 3, ``time.process_time``) of the Schur-Jacobi pass
(``_numba_point.jacobi_rhs``), the coarse coupling pass alone
(``_numba_coarse.coupling_blocks``), the fused pass
(``PointSystem.schur_parts(..., coarse=pattern)``), one Schur-complement
product (``schur_matvec``, the cost of a CG step's product) and the
pattern (clustering, once per structure); plus the clusters, blocks and
clusters per point (a sample of every 50th point).

``pairs N SEED KINDS``: full 4-iteration solves of one generated problem
in one process, one per comma-separated ``cg_preconditioner`` in KINDS
(e.g. ``schur_jacobi,adaptive,schur_jacobi,adaptive``), CPU s per
iteration as in ``bal_scaling.py``, the CG steps and the final cost.
Needs numba. Usage: ``python benchmarks/coarse_pass.py kernels 1000``.
"""

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import photogram  # noqa: E402,F401  (before numpy)
import numpy as np  # noqa: E402

import bal_scaling  # noqa: E402
from photogram.adjust import _numba_point, kernels, rcs_coarse, rcs_iterative  # noqa: E402
from photogram.bundle.bal import build_bal_problem  # noqa: E402
from photogram.simulation.bal_sphere import sphere_bal  # noqa: E402


def best(f, repeat=3):
    f()
    ts = []
    for _ in range(repeat):
        t = time.process_time()
        f()
        ts.append(time.process_time() - t)
    return min(ts)


def kernels_run(n, size=64):
    kernels.use_numba(True)
    problem = build_bal_problem(sphere_bal(n, seed=0).problem, behind="keep").problem
    problem.rcs["method"] = "iterative"
    system = problem.linearize(problem.state)
    Ncc, Ainv = system.damped_inverse(problem.layout, 1e-3)
    op = rcs_iterative.SchurOperator(system, Ncc, Ainv, ordered=True)
    pl = system.plan
    t = time.process_time()
    pat = rcs_coarse.pattern_of(op, size)
    print(f"pattern (clustering, once per structure) {time.process_time() - t:.3f} s")
    cl = pat.cluster[pl.group]
    per_point = [len(np.unique(cl[pl.ptr[i]:pl.ptr[i + 1]]))
                 for i in range(0, len(pl.ptr) - 1, 50)]
    print(f"rows {len(pl.group)}, clusters {pat.n_clusters}, blocks {pat.n_blocks}, "
          f"clusters per point {np.mean(per_point):.2f}")
    n_g, s = problem.structure.group_cols.shape

    def jacobi():
        _numba_point.jacobi_rhs(system.WTp, pl.group, pl.ptr, Ainv, system.g_o,
                                np.zeros((n_g, s, s)), np.zeros((n_g, s)))

    runs = [("Schur-Jacobi pass (jacobi_rhs)", jacobi),
            ("coupling pass alone", lambda: rcs_coarse._coupling_numba(
                pat, system.WTp, pl.group, pl.ptr, Ainv)),
            ("fused pass (schur_parts, coarse=)", lambda: system.schur_parts(
                Ncc, Ainv, ordered=True, coarse=pat)),
            ("one Schur product (schur_matvec)", lambda: system.schur_matvec(
                Ainv, np.ones(problem.structure.n_r)))]
    for name, f in runs:
        print(f"{name:40s} {best(f):.3f} s")


def pairs_run(n, seed, kinds):
    bal_scaling.warm_up()
    bal = sphere_bal(n, seed=seed).problem
    for kind in kinds:
        out = bal_scaling.photogram_run(bal, 4, True, {"cg_preconditioner": kind})
        print(f"{kind:14s} {out['cpu']:.3f} s/it  CG {'+'.join(map(str, out['cg']))}  "
              f"cost {out['final']:.9g}", flush=True)


if __name__ == "__main__":
    if sys.argv[1] == "kernels":
        kernels_run(int(sys.argv[2]))
    else:
        pairs_run(int(sys.argv[2]), int(sys.argv[3]), sys.argv[4].split(","))
