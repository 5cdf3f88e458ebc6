"""BAL to convergence (issue 23, item 5, follow-up): total CPU seconds,
Levenberg-Marquardt iterations, conjugate-gradient steps and final cost of
photogram's iterative reduced-camera-system solve on a SIMULATED sphere
problem (:func:`photogram.simulation.bal_sphere.sphere_bal`), for one CG
tolerance (``SolverOptions.cg_tolerance``).

Run: /work/venv-bal/bin/python benchmarks/bal_converge.py CAMERAS SEED
     [--tolerance 0.1] [--criterion residual|model] [--numpy] [--method iterative|dense|auto]
     [--point-order] [--max-iterations 50]
Prints one line ``RESULT ...`` (CPU s from ``time.process_time``; the
set-up inside the solve is included).
"""

import argparse
import time

import photogram  # noqa: F401  (single-threaded BLAS before numpy)
import numpy as np

from photogram.adjust import kernels, rcs_iterative
from photogram.bundle.bal import bal_options, build_bal_problem, solve_bal
from photogram.simulation.bal_sphere import sphere_bal
from bal_scaling import warm_up


def counting_pcg(steps):
    """Wrap :func:`rcs_iterative.pcg` so that its step counts land in ``steps``."""
    original = rcs_iterative.pcg

    def pcg(*args, **kw):
        x, it = original(*args, **kw)
        steps.append(it)
        return x, it
    rcs_iterative.pcg = pcg


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("cameras", type=int)
    ap.add_argument("seed", type=int)
    ap.add_argument("--tolerance", type=float, default=0.1)
    ap.add_argument("--criterion", default="residual", choices=("residual", "model"),
                    help="CG stopping test (SolverOptions.cg_criterion)")
    ap.add_argument("--numpy", action="store_true", help="the pure-numpy path")
    ap.add_argument("--method", default="iterative", choices=("iterative", "dense", "auto"))
    ap.add_argument("--point-order", action="store_true",
                    help="observations sorted by point instead of by camera")
    ap.add_argument("--max-iterations", type=int, default=50)
    args = ap.parse_args()
    warm_up()
    kernels.use_numba(not args.numpy)
    steps = []
    counting_pcg(steps)
    bal = sphere_bal(args.cameras, seed=args.seed).problem
    if args.point_order:
        bal = bal.subset(np.argsort(bal.point, kind="stable"))
    built = build_bal_problem(bal, behind="keep")
    opt = bal_options(max_iterations=args.max_iterations, cg_tolerance=args.tolerance,
                      cg_criterion=args.criterion,
                      linear_solver=args.method)
    c0, w0 = time.process_time(), time.perf_counter()
    s = solve_bal(built, opt)
    cpu, wall = time.process_time() - c0, time.perf_counter() - w0
    it = max(s.iterations, 1)
    print(f"RESULT cameras={args.cameras} seed={args.seed} obs={bal.n_observations} "
          f"path={'numpy' if args.numpy else 'numba'} method={s.linear_solver} "
          f"tolerance={args.tolerance} criterion={args.criterion} point_order={args.point_order} status={s.status} "
          f"iterations={s.iterations} cpu={cpu:.1f} wall={wall:.1f} cpu_per_it={cpu / it:.3f} "
          f"final_cost={s.final_cost:.8g} cg_steps={sum(steps)} per_solve={','.join(map(str, steps))} "
          "data=SIMULATED")


if __name__ == "__main__":
    main()
