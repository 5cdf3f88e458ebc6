"""Bundle Adjustment in the Large: photogram against Ceres (through
pycolmap) and scipy.optimize.least_squares, side by side in one run.

For each BAL problem (../shared/data/bal), the observations whose point is
behind its camera at the start are dropped for every solver (problem-49-7776
has 31; COLMAP would score them as zero), and each solver starts from the
file's values and minimizes 0.5 sum r^2 (unit weights):

* photogram: ``build_bal_problem`` (BAL camera model f, k1, k2 per camera,
  nothing fixed) and ``solve_bal`` (Ceres' Levenberg-Marquardt trust region
  and default tolerances; Schur complement with a dense Cholesky of the
  reduced camera system; numba kernels when numba is installed).
* Ceres 2.2 through pycolmap's bundle adjuster: a ``pycolmap.Reconstruction``
  with one RADIAL camera (f, cx = cy = 0 fixed, k1, k2) per image,
  ``create_default_ceres_bundle_adjuster(...).solve()``, DENSE_SCHUR, one
  thread, Ceres' default tolerances (function 1e-6, gradient 1e-10,
  parameter 1e-8; pycolmap's own defaults differ), at most 100 iterations.
* scipy: the SciPy cookbook "Large-scale bundle adjustment in scipy"
  verbatim: ``least_squares(fun, x0, jac_sparsity=A, x_scale="jac",
  ftol=1e-4, method="trf")`` with a finite-difference Jacobian on the
  sparsity pattern.

Times are the solve calls only (problem set-up excluded for all three);
photogram's first ("cold") run also loads numba's cached kernels and is
reported separately, the table shows the median of the warm runs.

Run: .venv/bin/python benchmarks/bal.py [--repeat 5] [--scipy-repeat 1]
     [--problems 49-7776,21-11315,16-22106] [--no-scipy] [--no-ceres]
"""

import argparse
import statistics
import time
from pathlib import Path

import photogram  # noqa: F401  (single-threaded BLAS before numpy)
import numpy as np
from scipy.optimize import least_squares
from scipy.sparse import lil_matrix

from photogram.adjust import kernels
from photogram.geometry import rodrigues_to_matrix
from photogram.bundle.bal import build_bal_problem, solve_bal
from photogram.io.bal import bal_cost, behind_camera, read_bal

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "bal"
PROBLEMS = ("49-7776", "21-11315", "16-22106")
# Ceres' final costs from /work/shared/notes.md (same observations)
NOTES = {"49-7776": 13308.48, "21-11315": 30378.65, "16-22106": 18033.90}


# ---------------------------------------------------------------- photogram
def photogram_run(bal):
    built = build_bal_problem(bal, behind="keep")      # behind-camera ones already dropped
    t = time.perf_counter()
    s = solve_bal(built)
    dt = time.perf_counter() - t
    return {"s": dt, "iterations": s.iterations, "initial": s.initial_cost,
            "final": s.final_cost, "status": s.message}


# ---------------------------------------------------------------- Ceres (pycolmap)
def ceres_available():
    try:
        import pycolmap  # noqa: F401
        return True
    except ImportError:
        return False


def colmap_reconstruction(bal):
    """BAL -> pycolmap: COLMAP's camera looks along +z with y down, BAL's
    along -z with y up: ``cam_from_world = diag(1,-1,-1) [R | t]`` and the
    observed y negated; RADIAL camera (f, cx, cy, k1, k2) with cx = cy = 0."""
    import pycolmap
    F = np.diag([1.0, -1.0, -1.0])
    rec = pycolmap.Reconstruction()
    for c in range(bal.n_cameras):
        f, k1, k2 = bal.cameras[c, 6:9]
        rec.add_camera_with_trivial_rig(pycolmap.Camera(
            model="RADIAL", width=2000, height=2000, params=[f, 0.0, 0.0, k1, k2], camera_id=c + 1))
    R = rodrigues_to_matrix(bal.cameras[:, :3])
    rows_of = [np.flatnonzero(bal.camera == c) for c in range(bal.n_cameras)]
    for c, rows in enumerate(rows_of):
        xy = bal.xy[rows] * [1.0, -1.0]
        pts = pycolmap.Point2DList([pycolmap.Point2D(v) for v in xy])
        img = pycolmap.Image(name=str(c), points2D=pts, camera_id=c + 1, image_id=c + 1)
        pose = pycolmap.Rigid3d(pycolmap.Rotation3d(F @ R[c]), F @ bal.cameras[c, 3:6])
        rec.add_image_with_trivial_frame(img, pose)
    ids = [rec.add_point3D(p, pycolmap.Track()) for p in bal.points]
    for c, rows in enumerate(rows_of):
        for i, o in enumerate(rows):
            rec.add_observation(ids[bal.point[o]], pycolmap.TrackElement(c + 1, i))
    return rec


def ceres_run(bal):
    import pycolmap
    rec = colmap_reconstruction(bal)
    opt = pycolmap.BundleAdjustmentOptions()
    opt.print_summary = False
    opt.ceres.auto_select_solver_type = False
    so = opt.ceres.solver_options
    so.linear_solver_type = type(so.linear_solver_type).DENSE_SCHUR
    so.num_threads = 1
    so.function_tolerance, so.gradient_tolerance, so.parameter_tolerance = 1e-6, 1e-10, 1e-8
    so.max_num_iterations = 100
    cfg = pycolmap.BundleAdjustmentConfig()
    for c in range(bal.n_cameras):
        cfg.add_image(c + 1)
    ba = pycolmap.create_default_ceres_bundle_adjuster(opt, cfg, rec)
    t = time.perf_counter()
    summary = ba.solve()
    dt = time.perf_counter() - t
    cs = summary.ceres_summary
    return {"s": dt, "iterations": cs.num_successful_steps + cs.num_unsuccessful_steps,
            "initial": cs.initial_cost, "final": cs.final_cost, "status": cs.message}


# ---------------------------------------------------------------- scipy (cookbook)
def rotate(points, rot_vecs):
    theta = np.linalg.norm(rot_vecs, axis=1)[:, np.newaxis]
    with np.errstate(invalid="ignore"):
        v = rot_vecs / theta
        v = np.nan_to_num(v)
    dot = np.sum(points * v, axis=1)[:, np.newaxis]
    cos_theta = np.cos(theta)
    sin_theta = np.sin(theta)
    return cos_theta * points + sin_theta * np.cross(v, points) + dot * (1 - cos_theta) * v


def project(points, camera_params):
    points_proj = rotate(points, camera_params[:, :3])
    points_proj += camera_params[:, 3:6]
    points_proj = -points_proj[:, :2] / points_proj[:, 2, np.newaxis]
    f = camera_params[:, 6]
    k1 = camera_params[:, 7]
    k2 = camera_params[:, 8]
    n = np.sum(points_proj ** 2, axis=1)
    r = 1 + k1 * n + k2 * n ** 2
    points_proj *= (r * f)[:, np.newaxis]
    return points_proj


def fun(params, n_cameras, n_points, camera_indices, point_indices, points_2d):
    camera_params = params[:n_cameras * 9].reshape((n_cameras, 9))
    points_3d = params[n_cameras * 9:].reshape((n_points, 3))
    points_proj = project(points_3d[point_indices], camera_params[camera_indices])
    return (points_proj - points_2d).ravel()


def bundle_adjustment_sparsity(n_cameras, n_points, camera_indices, point_indices):
    m = camera_indices.size * 2
    n = n_cameras * 9 + n_points * 3
    A = lil_matrix((m, n), dtype=int)
    i = np.arange(camera_indices.size)
    for s in range(9):
        A[2 * i, camera_indices * 9 + s] = 1
        A[2 * i + 1, camera_indices * 9 + s] = 1
    for s in range(3):
        A[2 * i, n_cameras * 9 + point_indices * 3 + s] = 1
        A[2 * i + 1, n_cameras * 9 + point_indices * 3 + s] = 1
    return A


def scipy_run(bal):
    x0 = np.hstack((bal.cameras.ravel(), bal.points.ravel()))
    args = (bal.n_cameras, bal.n_points, bal.camera, bal.point, bal.xy)
    A = bundle_adjustment_sparsity(bal.n_cameras, bal.n_points, bal.camera, bal.point)
    f0 = fun(x0, *args)
    t = time.perf_counter()
    res = least_squares(fun, x0, jac_sparsity=A, verbose=0, x_scale="jac", ftol=1e-4,
                        method="trf", args=args)
    dt = time.perf_counter() - t
    return {"s": dt, "iterations": res.njev, "initial": 0.5 * float(f0 @ f0),
            "final": float(res.cost), "status": res.message}


# ---------------------------------------------------------------- driver
def median_of(runs):
    out = dict(runs[0])
    out["s"] = statistics.median(r["s"] for r in runs)
    out["all_s"] = [r["s"] for r in runs]
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5, help="runs of photogram and Ceres")
    ap.add_argument("--scipy-repeat", type=int, default=1)
    ap.add_argument("--problems", default=",".join(PROBLEMS))
    ap.add_argument("--no-scipy", action="store_true")
    ap.add_argument("--no-ceres", action="store_true")
    args = ap.parse_args()
    if not DATA.is_dir():
        print(f"BAL data not found at {DATA}")
        print("RESULT status=skipped")
        return
    have_ceres = not args.no_ceres and ceres_available()
    if not args.no_ceres and not have_ceres:
        print("pycolmap is not installed (pip install photogram[bench]): no Ceres column")
    print(f"numba kernels: {'on' if kernels.use_numba() else 'off (numpy path)'}; "
          f"median of {args.repeat} runs (scipy: {args.scipy_repeat})")
    result = {}
    rows = []
    for key in args.problems.split(","):
        bal = read_bal(DATA / f"problem-{key}-pre.txt.bz2")
        behind = behind_camera(bal)
        bal = bal.subset(~behind)
        print(f"\nproblem-{key}: {bal.n_cameras} cameras, {bal.n_points} points, "
              f"{bal.n_observations} observations ({int(behind.sum())} behind their camera "
              f"dropped), initial cost {bal_cost(bal):.6g}")
        cold = photogram_run(bal)
        ours = median_of([photogram_run(bal) for _ in range(args.repeat)])
        ours["cold"] = cold["s"]
        table = {"photogram": ours}
        if have_ceres:
            table["ceres"] = median_of([ceres_run(bal) for _ in range(args.repeat)])
        if not args.no_scipy:
            table["scipy"] = median_of([scipy_run(bal) for _ in range(args.scipy_repeat)])
        print(f"{'solver':<12} {'median s':>9} {'runs s':>28} {'iter':>5} {'initial cost':>14} "
              f"{'final cost':>14}  stop")
        for name, r in table.items():
            runs = " ".join(f"{v:.2f}" for v in r["all_s"][:6])
            print(f"{name:<12} {r['s']:9.3f} {runs:>28} {r['iterations']:>5} {r['initial']:14.6f} "
                  f"{r['final']:14.6f}  {str(r['status'])[:60]}")
        print(f"photogram first run{' (numba kernels loaded)' if kernels.use_numba() else ''}: "
              f"{cold['s']:.3f} s")
        tag = "p" + key.split("-")[0]
        result[f"{tag}_s"] = f"{ours['s']:.3f}"
        result[f"{tag}_cost"] = f"{ours['final']:.4f}"
        row = {"key": key, "ours": ours}
        if "ceres" in table:
            c = table["ceres"]
            ratio = ours["s"] / c["s"]
            rel = (ours["final"] - c["final"]) / c["final"]
            print(f"photogram / Ceres time {ratio:.2f}; final cost relative to Ceres {rel:+.2e} "
                  f"(notes: Ceres {NOTES.get(key)})")
            result[f"{tag}_ceres_s"] = f"{c['s']:.3f}"
            result[f"{tag}_ratio_ceres"] = f"{ratio:.2f}"
            result[f"{tag}_cost_vs_ceres"] = f"{rel:.1e}"
            row["ratio"], row["rel"] = ratio, rel
        if "scipy" in table:
            sp_ = table["scipy"]
            speed = sp_["s"] / ours["s"]
            print(f"scipy / photogram time {speed:.1f}; scipy final cost relative to photogram "
                  f"{(sp_['final'] - ours['final']) / ours['final']:+.2e}")
            result[f"{tag}_scipy_s"] = f"{sp_['s']:.2f}"
            result[f"{tag}_speedup_scipy"] = f"{speed:.1f}"
            row["speedup"] = speed
        rows.append(row)
    if rows and all("ratio" in r for r in rows):
        result["max_ratio_ceres"] = f"{max(r['ratio'] for r in rows):.2f}"
        result["max_cost_vs_ceres"] = f"{max(abs(r['rel']) for r in rows):.1e}"
    if rows and all("speedup" in r for r in rows):
        result["min_speedup_scipy"] = f"{min(r['speedup'] for r in rows):.1f}"
    result["numba"] = "on" if kernels.use_numba() else "off"
    result["ceres"] = "yes" if have_ceres else "missing"
    print("RESULT " + " ".join(f"{k}={v}" for k, v in result.items()))


if __name__ == "__main__":
    main()
