"""Statistics memory (issue 23, item 4): peak memory and CPU of the
statistics after the solve, `photogram calibrate` in a subprocess.

Two SIMULATED networks (known truth, Gaussian image noise):

* ``wall``: :func:`photogram.simulation.network.wall_geometry` -- points
  on a wall with relief, stations along it (c = 1000 px, 4000 x 3000 px),
  about ``--rays`` rays per point; the default is the issue's goal, 500
  stations, 100,000 points, about 10^6 image observations. Self-calibration
  (c, x0, y0, K1, K2, P1, P2 of the one camera free), 10 control points
  held fixed. Observed in chunks of points, so that the generator itself
  does not need an S x P array.
* ``aicon``: an industrial-sized convergent network like the AICON one
  of the issue: 115 images on a ring (rolled 0/90/180/270 degrees) round a
  frame of 150 points, almost every point in every image (about 17,000
  image points), the AICON camera model with all 10 distortion and
  interior parameters free (about 1,150 unknowns), 6 control points with
  sigmas (weighted datum).

Every network is written as a project (points.csv, image_points.csv, ...)
into a temporary folder and adjusted by ``photogram calibrate`` in a child
process; the peak memory is the child's maximum resident set size
(``ru_maxrss``), the CPU seconds of the command the child's user + system time, those of the
solve and of the statistics from summary.json (``timings.cpu``), the
results folder's and the report's the rest after the adjustment. The child
reports its own peak RSS (``VmHWM`` of /proc/self/status: ``ru_maxrss``
would carry the parent's size over the fork) and CPU seconds when it ends;
summary.json's ``timings.peak_rss_mb`` has the peak before and after the
statistics.

Run: .venv/bin/python benchmarks/stats_memory.py [--network wall|aicon|both]
[--stations 500 --points 100000 --rays 10] [--seed 0] [--no-report]
(``--no-report`` needs the command's ``--no-report`` option of item 1).
Ends with one line ``RESULT key=value ...``.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

# benchmarks/profile.py would shadow the standard library's profile module
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

import photogram  # noqa: E402,F401  (single-threaded BLAS before numpy)
import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]

WALL_FREE = ("c", "x0", "y0", "K1", "K2", "P1", "P2")


def wall_network_chunked(n_stations, n_points, rays, seed=0, sigma=0.5, chunk=4000):
    """The wall network of :func:`photogram.simulation.network.wall_network`
    (the same geometry), observed ``chunk`` points at a time in the order
    of their position along the wall, each chunk only from the stations
    whose image can reach it (the full projection would be S x P); the
    noise is drawn chunk by chunk from the same generator."""
    from photogram.simulation.network import SyntheticNetwork, observe, wall_geometry
    distance = 10.0
    pts, X0, R, io, size, rng = wall_geometry(n_stations, n_points, distance, rays, seed)
    reach = 1.5 * distance * (size[0] / 2) / io[0]      # half the wall width an image sees, +50 %
    cams = np.zeros(n_stations, int)
    order = np.argsort(pts[:, 0], kind="stable")
    st, pt, xy_t, xy = [], [], [], []
    for lo in range(0, n_points, chunk):
        idx = order[lo:lo + chunk]
        x = pts[idx, 0]
        cand = np.flatnonzero((X0[:, 0] > x.min() - reach) & (X0[:, 0] < x.max() + reach))
        net = observe("brown", io, cams[cand], R[cand], X0[cand], pts[idx], size, sigma=sigma,
                      rng=rng, margin=5)
        st.append(cand[net.station])
        pt.append(idx[net.point])
        xy_t.append(net.xy_true)
        xy.append(net.xy)
    st, pt = np.concatenate(st), np.concatenate(pt)
    by_station = np.lexsort((pt, st))           # image by image, as a measuring program writes
    return SyntheticNetwork("brown", np.atleast_2d(io), size, cams, R, X0, pts,
                            st[by_station], pt[by_station],
                            np.concatenate(xy_t)[by_station], np.concatenate(xy)[by_station])


def wall_project(n_stations, n_points, rays, seed=0):
    """The self-calibrating wall project (module doc) and its network."""
    from photogram.simulation.network import to_project
    net = wall_network_chunked(n_stations, n_points, rays, seed)
    control = np.linspace(0, n_points - 1, 10).astype(int)
    prj = to_project(net, control=control, perturb_points=0.05, perturb_stations=0.005,
                     sigma_image=0.5, free_interior=WALL_FREE,
                     rng=np.random.default_rng(seed + 1), name="wall")
    prj.adjustment.datum = "control"
    return prj, net


def aicon_project(seed=0, n_stations=115, n_points=150):
    """The AICON-sized self-calibration project (module doc) and its network."""
    from photogram.simulation.network import observe, ring_stations, to_project
    rng = np.random.default_rng(seed)
    pts = rng.uniform([-1.0, -1.0, 0.0], [1.0, 1.0, 0.6], (n_points, 3))
    X0, R = ring_stations(n_stations, 3.0, 1.5, np.array([0.0, 0.0, 0.3]), jitter=0.1,
                          rng=rng, rolls=[0, np.pi / 2, np.pi, -np.pi / 2])
    io = np.array([2400.0, 1000.0, 750.0, -3e-9, 1e-16, 0, 2e-7, -1e-7, 1e-5, -1e-5, 0.0])
    net = observe("aicon", io, np.zeros(n_stations, int), R, X0, pts, (2000, 1500),
                  sigma=0.1, rng=rng)
    free = ("c", "xh", "yh", "A1", "A2", "A3", "B1", "B2", "C1", "C2")
    control = np.arange(0, n_points, n_points // 6)[:6]
    prj = to_project(net, control=control, sigma_image=0.1, free_interior=free,
                     point_sigma=0.0005, perturb_points=0.01, perturb_stations=0.002,
                     rng=np.random.default_rng(seed + 1), name="aicon")
    prj.adjustment.datum = "control"
    return prj, net


# the worktree's command line (cli/ is installed as photogram_cli); the
# child prints its own peak RSS and CPU seconds as its last stderr line
CHILD = """
import resource, sys
sys.path.insert(0, {root!r})
import cli, cli.main
sys.modules["photogram_cli"] = cli
sys.modules["photogram_cli.main"] = cli.main
sys.argv = ["photogram"] + sys.argv[1:]
try:
    rc = cli.main.main()
finally:
    ru = resource.getrusage(resource.RUSAGE_SELF)
    hwm = [ln.split()[1] for ln in open("/proc/self/status") if ln.startswith("VmHWM:")]
    print(f"CHILD maxrss_kb={{hwm[0] if hwm else ru.ru_maxrss}} "
          f"cpu={{ru.ru_utime + ru.ru_stime}}", file=sys.stderr)
sys.exit(rc)
"""


def run_calibrate(project_path, output, no_report=False):
    """``photogram calibrate`` in a child process: (peak RSS MB, CPU s of
    the child, wall s, return code)."""
    args = [sys.executable, "-c", CHILD.format(root=str(ROOT)), "calibrate", str(project_path),
            "--output", str(output), "--quiet"]
    if no_report:
        args.append("--no-report")
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    t = time.perf_counter()
    proc = subprocess.run(args, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t
    if proc.returncode:
        print(proc.stdout[-2000:], proc.stderr[-4000:], file=sys.stderr)
    line = [x for x in proc.stderr.splitlines() if x.startswith("CHILD ")]
    if not line:        # killed: the children's maximum (of every child so far)
        ru = resource.getrusage(resource.RUSAGE_CHILDREN)
        return ru.ru_maxrss / 1024.0, ru.ru_utime + ru.ru_stime, wall, proc.returncode
    kv = dict(x.split("=") for x in line[-1].split()[1:])
    return float(kv["maxrss_kb"]) / 1024.0, float(kv["cpu"]), wall, proc.returncode


def measure(name, prj, n_obs, keep=None, no_report=False):
    """Write ``prj``, adjust it in a child and gather the figures."""
    from photogram.project.writer import write_project
    tmp = Path(tempfile.mkdtemp(prefix=f"stats-memory-{name}-"))
    try:
        path = write_project(prj, tmp / f"{name}.prj")
        del prj
        peak, cpu, wall, rc = run_calibrate(path, tmp / "results", no_report)
        out = {"peak_mb": peak, "cpu": cpu, "wall": wall, "rc": rc, "image_points": n_obs}
        summary = tmp / "results" / "summary.json"
        if summary.exists():
            s = json.loads(summary.read_text())
            c = s["timings"].get("cpu", {})           # absent before issue 23
            rss = s["timings"].get("peak_rss_mb", {})
            out.update(status=s["status"], iterations=s["iterations"], sigma0=s["sigma0"],
                       unknowns=s["counts"]["unknowns"],
                       observations=s["counts"]["observations"],
                       solve_cpu=c.get("adjustment", float("nan")),
                       stats_cpu=c.get("statistics", float("nan")),
                       solve_peak_mb=rss.get("after_adjustment", float("nan")),
                       stats_peak_mb=rss.get("after_statistics", float("nan")))
            out["rest_cpu"] = cpu - c.get("total", float("nan"))
        if keep:
            shutil.copytree(tmp / "results", keep, dirs_exist_ok=True)
        return out
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def show(name, r):
    ratio = r.get("stats_cpu", np.nan) / r.get("solve_cpu", np.nan)
    print(f"{name} (SIMULATED): {r['image_points']} image points, {r.get('unknowns')} unknowns, "
          f"status {r.get('status')} after {r.get('iterations')} iterations, "
          f"sigma0 {r.get('sigma0', np.nan):.3f}; peak RSS {r.get('solve_peak_mb', np.nan):.0f} MB "
          f"after the solve, {r.get('stats_peak_mb', np.nan):.0f} MB after the statistics, "
          f"{r['peak_mb']:.0f} MB of the whole command; CPU command "
          f"{r['cpu']:.1f} s, solve {r.get('solve_cpu', np.nan):.1f} s, statistics "
          f"{r.get('stats_cpu', np.nan):.1f} s ({ratio:.2f} x solve), results folder and "
          f"report {r.get('rest_cpu', np.nan):.1f} s; rc {r['rc']}")
    return ratio


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--network", choices=("wall", "aicon", "both"), default="both")
    ap.add_argument("--stations", type=int, default=500)
    ap.add_argument("--points", type=int, default=100_000)
    ap.add_argument("--rays", type=int, default=10)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--no-report", action="store_true")
    ap.add_argument("--keep", default=None, help="copy the results folder here")
    args = ap.parse_args()
    fields = {"seed": args.seed}
    if args.network in ("aicon", "both"):
        prj, net = aicon_project(args.seed)
        r = measure("aicon", prj, len(net.station), args.keep, args.no_report)
        ratio = show("aicon-sized network", r)
        fields.update(aicon_obs=r.get("observations"), aicon_unknowns=r.get("unknowns"),
                      aicon_peak_mb=f"{r['peak_mb']:.0f}",
                      aicon_stats_peak_mb=f"{r.get('stats_peak_mb', np.nan):.0f}",
                      aicon_solve_cpu=f"{r.get('solve_cpu', np.nan):.2f}",
                      aicon_stats_cpu=f"{r.get('stats_cpu', np.nan):.2f}",
                      aicon_ratio=f"{ratio:.2f}", aicon_rc=r["rc"])
    if args.network in ("wall", "both"):
        prj, net = wall_project(args.stations, args.points, args.rays, args.seed)
        r = measure("wall", prj, len(net.station), args.keep, args.no_report)
        del net
        ratio = show(f"wall network {args.stations} stations {args.points} points", r)
        fields.update(wall_stations=args.stations, wall_points=args.points,
                      wall_image_points=r["image_points"], wall_unknowns=r.get("unknowns"),
                      wall_peak_mb=f"{r['peak_mb']:.0f}",
                      wall_stats_peak_mb=f"{r.get('stats_peak_mb', np.nan):.0f}",
                      wall_cpu=f"{r['cpu']:.1f}",
                      wall_solve_cpu=f"{r.get('solve_cpu', np.nan):.1f}",
                      wall_stats_cpu=f"{r.get('stats_cpu', np.nan):.1f}",
                      wall_rest_cpu=f"{r.get('rest_cpu', np.nan):.1f}",
                      wall_ratio=f"{ratio:.2f}", wall_rc=r["rc"])
    print("RESULT " + " ".join(f"{k}={v}" for k, v in fields.items()))


if __name__ == "__main__":
    main()
