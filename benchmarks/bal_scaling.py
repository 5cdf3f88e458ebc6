"""BAL scaling (issue 23, item 5): time per iteration of photogram's solver
against Ceres' settings on SIMULATED BAL problems from 3e5 to 1e7
observations.

Problems: :func:`photogram.simulation.bal_sphere.sphere_bal` (cameras on a
sphere looking in, 3-10 neighbouring views per point, about 3000
observations per camera, 0.5 px noise, perturbed start; SIMULATED).
Every solver starts from the same values and runs ``--iterations``
iterations of Levenberg-Marquardt (Ceres' trust region; photogram's
``solve_bal`` with ``linear_solver="auto"``, which switches to the
iterative reduced-camera-system solve from 500 reduced columns on with
the fused BAL path of ``photogram/adjust/point_rows.py``, numba or its
numpy twin).

Timing: CPU seconds (``time.process_time``, all threads of the process)
and wall seconds of the solve call, divided by the iterations done
(photogram: up to its last accepted iteration, so the worst-observation
listing printed at ``max_iterations`` is not counted; Ceres: its total
over its iterations, set-up included for both). The ratio uses CPU
seconds: on a shared 2-core machine wall time measures the other jobs.

Ceres 2.2 through pycolmap (``benchmarks/bal.py`` builds the problem):
DENSE_SCHUR, SPARSE_SCHUR and ITERATIVE_SCHUR (SCHUR_JACOBI), 1 and 2
threads; a setting is skipped at sizes where ``--ceres-limit`` seconds
(default 600) would be exceeded by its extrapolated time (cubic in the
cameras for DENSE_SCHUR, linear otherwise) or at more than
``--ceres-max-obs`` observations.

Run: /work/venv-bal/bin/python benchmarks/bal_scaling.py
     [--cameras 100,333,1000,3333] [--iterations 4] [--no-numpy] [--seed 1]
     [--preconditioner auto|schur_jacobi|two_level] [--cluster-size 64]
     [--ceres-settings ITERATIVE_SCHUR:1,...]
     [--ceres-from earlier_output.txt]
Prints a table and ``RESULT key=value ...``; per photogram row also the
user and system CPU seconds and minor page faults per iteration
(``getrusage``, same span), the user + system CPU of every LM iteration
(``getrusage`` in the solver's iteration callback) and a second figure,
the steady-state CPU per iteration: the mean over LM iterations 2..N,
what an iteration costs once the one-off setup of the first
linearization (allocation and first touch of the work arrays, the plan)
is paid; the setup is iteration 1 minus that mean. ``exponent_numba`` (whole
solve / iterations) stays the main figure; ``exponent_steady_numba`` is
the fit of the steady figure (explanatory).
"""

import argparse
import math
import re
import resource
import sys
import time
from pathlib import Path

import photogram  # noqa: F401  (single-threaded BLAS before numpy)
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from photogram.adjust import kernels, rcs_iterative  # noqa: E402
from photogram.bundle.bal import bal_options, build_bal_problem, solve_bal  # noqa: E402
from photogram.simulation.bal_sphere import sphere_bal  # noqa: E402

SETTINGS = [(k, t) for k in ("DENSE_SCHUR", "SPARSE_SCHUR", "ITERATIVE_SCHUR") for t in (1, 2)]


def warm_up():
    """Load numba's cached kernels (both RCS solves, both preconditioners) before any timing: a
    problem above the kernels' row threshold (20,000 E-rows), solved for
    two iterations with the dense and with the iterative RCS."""
    if not kernels.HAVE_NUMBA:
        return
    kernels.use_numba(True)
    warm = sphere_bal(20, obs_per_camera=1500, seed=99).problem
    for method, pre in (("dense", "auto"), ("iterative", "schur_jacobi"),
                        ("iterative", "two_level")):
        solve_bal(build_bal_problem(warm, behind="keep"),
                  bal_options(max_iterations=2, linear_solver=method, cg_preconditioner=pre,
                              coarse_cluster_size=5))


def photogram_run(bal, iterations, numba, precond=None):
    kernels.use_numba(numba)
    steps, original = [], rcs_iterative.pcg

    def pcg(*args, **kw):                  # count the CG steps of every RCS solve
        x, it = original(*args, **kw)
        steps.append(it)
        return x, it
    rcs_iterative.pcg = pcg
    try:
        out = _photogram_run(bal, iterations, precond or {})
    finally:
        rcs_iterative.pcg = original
    out["cg"] = steps
    return out


def _photogram_run(bal, iterations, precond):
    built = build_bal_problem(bal, behind="keep")
    marks = []
    opt = bal_options(max_iterations=iterations, **precond,
                      callback=lambda i, c, lam: marks.append((i, time.process_time(),
                                                               time.perf_counter(), _usage())))
    c0, w0, u0 = time.process_time(), time.perf_counter(), _usage()
    s = solve_bal(built, opt)
    c1, w1, u1 = time.process_time(), time.perf_counter(), _usage()
    it, cpu, wall = s.iterations, c1 - c0, w1 - w0
    if s.status == "max_iterations" and marks:
        it, cpu, wall, u1 = marks[-1][0], marks[-1][1] - c0, marks[-1][2] - w0, marks[-1][3]
    user, system, faults = (u1 - u0) / it
    spans = iteration_spans([(m[0], m[3][0] - u0[0], m[3][1] - u0[1]) for m in marks])
    steady, setup = steady_and_setup([m[0] for m in marks],
                                     [m[3][0] + m[3][1] - u0[0] - u0[1] for m in marks])
    return {"cpu": cpu / it, "wall": wall / it, "iterations": it, "final": s.final_cost,
            "solver": s.linear_solver, "precond": s.cg_preconditioner,
            "user": user, "sys": system, "minflt": faults, "status": s.status,
            "spans": spans, "steady": steady, "setup": setup}


def iteration_spans(marks):
    """Per accepted LM iteration: ``(first, last, user, system)``, the CPU
    seconds from the previous accepted iteration's callback (the start of
    the solve for the first) to this one's. ``marks`` holds ``(iteration,
    user, system)`` at each callback, cumulative from the start of the
    solve; ``first < last`` when rejected steps lie in the span."""
    out, prev = [], (0, 0.0, 0.0)
    for it, user, system in marks:
        out.append((prev[0] + 1, it, user - prev[1], system - prev[2]))
        prev = (it, user, system)
    return out


def steady_and_setup(iterations, cpu):
    """Steady-state CPU per LM iteration and the one-off setup cost.

    Parameters
    ----------
    iterations : sequence of int
        The LM iteration number at each accepted iteration's callback.
    cpu : sequence of float
        CPU seconds from the start of the solve to each callback.

    Returns
    -------
    steady : float
        ``(cpu[-1] - cpu[0]) / (iterations[-1] - iterations[0])``: the mean
        over the iterations after the first (NaN with fewer than two).
    setup : float
        ``cpu[0] - iterations[0] * steady``: what the first iteration costs
        beyond a steady one (the first linearization's allocation and first
        touch of the work arrays, the plan). ``setup + n * steady`` is the
        CPU of the first ``n = iterations[-1]`` iterations.
    """
    if len(iterations) < 2 or iterations[-1] == iterations[0]:
        return math.nan, math.nan
    steady = (cpu[-1] - cpu[0]) / (iterations[-1] - iterations[0])
    return steady, cpu[0] - iterations[0] * steady


def _usage():
    """User and system CPU seconds and minor page faults of the process
    so far (``getrusage``): the system time is mostly the kernel zeroing
    the pages of freshly allocated arrays."""
    r = resource.getrusage(resource.RUSAGE_SELF)
    return np.array([r.ru_utime, r.ru_stime, r.ru_minflt], dtype=float)


def ceres_run(bal, iterations, kind, threads):
    import pycolmap
    from bal import colmap_reconstruction
    rec = colmap_reconstruction(bal)
    opt = pycolmap.BundleAdjustmentOptions()
    opt.print_summary = False
    opt.ceres.auto_select_solver_type = False
    so = opt.ceres.solver_options
    so.linear_solver_type = getattr(type(so.linear_solver_type), kind)
    if kind == "ITERATIVE_SCHUR":
        so.preconditioner_type = type(so.preconditioner_type).SCHUR_JACOBI
    so.num_threads = threads
    so.function_tolerance, so.gradient_tolerance, so.parameter_tolerance = 1e-6, 1e-10, 1e-8
    so.max_num_iterations = iterations
    cfg = pycolmap.BundleAdjustmentConfig()
    for c in range(bal.n_cameras):
        cfg.add_image(c + 1)
    ba = pycolmap.create_default_ceres_bundle_adjuster(opt, cfg, rec)
    c0, w0 = time.process_time(), time.perf_counter()
    summary = ba.solve()
    c1, w1 = time.process_time(), time.perf_counter()
    cs = summary.ceres_summary
    it = max(cs.num_successful_steps + cs.num_unsuccessful_steps, 1)
    return {"cpu": (c1 - c0) / it, "wall": (w1 - w0) / it, "iterations": it,
            "final": cs.final_cost}


def earlier_ceres(path):
    """Ceres rows of an earlier output: {cameras: {(kind, threads): row}}."""
    out, n_c = {}, None
    for line in path.read_text().splitlines():
        words = line.split()
        if len(words) > 2 and words[1] == "cameras," and words[0].isdigit():
            n_c = int(words[0])
            out[n_c] = {}
        elif words[:1] == ["Ceres"] and n_c is not None:
            key = (words[1], int(words[2]))
            m = re.search(r"thr\s+([\d.]+) \(\s*([\d.]+)\)\s+(\d+) it, cost (\S+)", line)
            out[n_c][key] = None if m is None else {
                "cpu": float(m[1]), "wall": float(m[2]), "iterations": int(m[3]),
                "final": float(m[4])}
    return out


def predicted(history, kind, n_cams, iterations):
    """Extrapolated CPU seconds of a Ceres setting at ``n_cams`` cameras
    from its largest run so far (None: no run yet)."""
    if not history:
        return None
    n0, per = history[-1]
    power = 3.0 if kind == "DENSE_SCHUR" else 1.0
    return per * (n_cams / n0) ** power * iterations


def fit_exponent(obs, t):
    """Least-squares slope of log t against log observations."""
    x, y = np.log(np.asarray(obs, float)), np.log(np.asarray(t, float))
    return float(np.polyfit(x, y, 1)[0]) if len(x) > 1 else float("nan")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cameras", default="100,333,1000,3333")
    ap.add_argument("--iterations", type=int, default=4)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--no-numpy", action="store_true", help="skip the pure-numpy path")
    ap.add_argument("--preconditioner", default="auto",
                    choices=("auto", "schur_jacobi", "two_level", "adaptive"),
                    help="SolverOptions.cg_preconditioner of photogram's iterative RCS solve")
    ap.add_argument("--cluster-size", type=int, default=None,
                    help="SolverOptions.coarse_cluster_size (default: the option's default)")
    ap.add_argument("--no-ceres", action="store_true")
    ap.add_argument("--ceres-settings", default=None,
                    help="only these Ceres settings, e.g. ITERATIVE_SCHUR:1,SPARSE_SCHUR:1 "
                         "(default: all six)")
    ap.add_argument("--ceres-limit", type=float, default=600.0)
    ap.add_argument("--ceres-max-obs", type=float, default=1.1e7)
    ap.add_argument("--numpy-max-obs", type=float, default=1.1e7)
    ap.add_argument("--ceres-from", type=Path, default=None,
                    help="take the Ceres rows from this earlier output of the script (same "
                         "--seed and --iterations) instead of running Ceres again")
    args = ap.parse_args()
    try:
        import pycolmap  # noqa: F401
        have_ceres = not args.no_ceres
    except ImportError:
        have_ceres = False
        print("pycolmap is not installed: no Ceres columns")
    sizes = [int(c) for c in args.cameras.split(",")]
    settings = SETTINGS if args.ceres_settings is None else [
        (k, int(t)) for k, t in (w.split(":") for w in args.ceres_settings.split(","))]
    print(f"SIMULATED sphere BAL problems, seed {args.seed}, {args.iterations} iterations; "
          f"numba {'installed' if kernels.HAVE_NUMBA else 'missing'}; times per iteration, "
          "CPU s (wall s)")
    precond = {"cg_preconditioner": args.preconditioner}
    if args.cluster_size is not None:
        precond["coarse_cluster_size"] = args.cluster_size
    print(f"photogram: cg_preconditioner={args.preconditioner}"
          + (f", coarse_cluster_size={args.cluster_size}" if args.cluster_size else ""))
    warm_up()
    rows, hist = [], {s: [] for s in settings}
    for n_c in sizes:
        bal = sphere_bal(n_c, seed=args.seed).problem
        n_obs = bal.n_observations
        row = {"cameras": n_c, "obs": n_obs, "points": bal.n_points}
        if kernels.HAVE_NUMBA:
            row["numba"] = photogram_run(bal, args.iterations, True, precond)
        if not args.no_numpy and n_obs <= args.numpy_max_obs:
            row["numpy"] = photogram_run(bal, args.iterations, False, precond)
        row["ceres"] = {}
        if args.ceres_from is not None:
            row["ceres"] = earlier_ceres(args.ceres_from).get(n_c, {})
        elif have_ceres and n_obs <= args.ceres_max_obs:
            for kind, threads in settings:
                guess = predicted(hist[(kind, threads)], kind, n_c, args.iterations)
                if guess is not None and guess > args.ceres_limit:
                    row["ceres"][(kind, threads)] = None
                    continue
                r = ceres_run(bal, args.iterations, kind, threads)
                hist[(kind, threads)].append((n_c, r["cpu"]))
                row["ceres"][(kind, threads)] = r
        rows.append(row)
        report(row)
    summary(rows)


def report(row):
    print(f"\n{row['cameras']} cameras, {row['points']} points, {row['obs']} observations")
    for key in ("numba", "numpy"):
        r = row.get(key)
        if r:
            cg = f", CG steps {'+'.join(map(str, r['cg']))}" if r.get("cg") else ""
            solver = r["solver"] + (f", {r['precond']}" if r.get("precond") else "")
            print(f"  photogram {key:<6} ({solver:<9}) {r['cpu']:8.3f} ({r['wall']:7.3f})  "
                  f"{r['iterations']} it, cost {r['final']:.6g}{cg}")
            if "user" in r:
                print(f"    per iteration: user {r['user']:.3f} s, system {r['sys']:.3f} s, "
                      f"{r['minflt']:.0f} minor page faults")
            if r.get("spans"):
                print_spans(r)
    for (kind, threads), r in row["ceres"].items():
        if r is None:
            print(f"  Ceres {kind:<15} {threads} thr   skipped (extrapolated beyond the limit)")
        else:
            print(f"  Ceres {kind:<15} {threads} thr {r['cpu']:8.3f} ({r['wall']:7.3f})  "
                  f"{r['iterations']} it, cost {r['final']:.6g}")
    sys.stdout.flush()


def print_spans(r):
    """Per LM iteration user + system CPU (getrusage), the steady mean and the setup."""
    words = [(f"{a}" if a == b else f"{a}-{b}") + f": {u:.3f}+{y:.3f}"
             for a, b, u, y in r["spans"]]
    print("    per LM iteration, user+system CPU s: " + ", ".join(words))
    last = r["spans"][-1][1]
    print(f"    steady (iterations {r['spans'][0][1] + 1}-{last}) {r['steady']:.3f} s/it, "
          f"setup (iteration 1 - steady) {r['setup']:.3f} s")
    if r["status"] != "max_iterations" or last < 4:
        print(f"    NOTE: the solve stopped after {r['iterations']} iterations "
              f"({r['status']})")


def summary(rows):
    steady_table(rows)
    print(f"\n{'cameras':>7} {'obs':>9} {'numba s/it':>10} {'numpy s/it':>10} "
          f"{'Ceres best':>26} {'numba/C':>8} {'numpy/C':>8}")
    res = {}
    worst_nb, worst_np = 0.0, 0.0
    for row in rows:
        done = {k: v for k, v in row["ceres"].items() if v}
        best = min(done.items(), key=lambda kv: kv[1]["cpu"]) if done else None
        nb, npy = row.get("numba"), row.get("numpy")
        rb = nb["cpu"] / best[1]["cpu"] if nb and best else math.nan
        rn = npy["cpu"] / best[1]["cpu"] if npy and best else math.nan
        if best:
            worst_nb = max(worst_nb, rb if nb else 0.0)
            worst_np = max(worst_np, rn if npy else 0.0)
        label = f"{best[0][0]} {best[0][1]}t {best[1]['cpu']:.3f}" if best else "-"
        print(f"{row['cameras']:>7} {row['obs']:>9} {nb['cpu'] if nb else math.nan:10.3f} "
              f"{npy['cpu'] if npy else math.nan:10.3f} {label:>26} {rb:8.2f} {rn:8.2f}")
    obs = [r["obs"] for r in rows]
    for key in ("numba", "numpy"):
        have = [(r["obs"], r[key]["cpu"]) for r in rows if r.get(key)]
        if len(have) > 1:
            res[f"exponent_{key}"] = f"{fit_exponent(*zip(*have)):.2f}"
        steady = [(r["obs"], r[key]["steady"]) for r in rows
                  if r.get(key) and math.isfinite(r[key].get("steady", math.nan))]
        if len(steady) > 1:
            res[f"exponent_steady_{key}"] = f"{fit_exponent(*zip(*steady)):.2f}"
    res["max_obs"] = max(obs)
    compared = any(any(r["ceres"].values()) for r in rows)
    res["max_ratio_numba_ceres"] = f"{worst_nb:.2f}" if compared and worst_nb else "n/a"
    res["max_ratio_numpy_ceres"] = f"{worst_np:.2f}" if compared and worst_np else "n/a"
    res["ceres_max_obs"] = max((r["obs"] for r in rows if any(r["ceres"].values())), default=0)
    res["data"] = "SIMULATED"
    print("RESULT " + " ".join(f"{k}={v}" for k, v in res.items()))


def steady_table(rows):
    """Whole solve / iterations against the steady mean of iterations 2..N."""
    for key in ("numba", "numpy"):
        have = [r for r in rows if r.get(key) and "steady" in r[key]]
        if not have:
            continue
        print(f"\n{key}: {'cameras':>7} {'obs':>9} {'total s/it':>10} {'steady s/it':>11} "
              f"{'setup s':>8} {'it':>3}")
        for r in have:
            p = r[key]
            print(f"{'':{len(key) + 2}}{r['cameras']:>7} {r['obs']:>9} {p['cpu']:10.3f} "
                  f"{p['steady']:11.3f} {p['setup']:8.3f} {p['iterations']:>3}")


if __name__ == "__main__":
    main()
