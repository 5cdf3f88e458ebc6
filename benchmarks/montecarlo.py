"""Speed of photogram montecarlo: the field orientation plus the intersection
of the 24-exposure jump (projects/jumps/montecarlo.prj), per run.

Runs the lab measurement, the lab calibration and the field orientation
first if their results are missing (as `make demo` does), then

* N1 runs with 1 worker (this process): runs per second;
* N runs with 2 workers (local processes, loky): runs per second and the
  wall time of the whole command (setup: truth, kernels and first-order
  propagation; the runs; the result files).

Target: 1000 runs with 2 workers in <= 15 s on the 2-core machine.

Run: .venv/bin/python benchmarks/montecarlo.py [--runs 1000] [--runs1 200]
"""

import argparse
import os
import tempfile
import time
from pathlib import Path

import photogram  # noqa: F401  (single-threaded BLAS before numpy)

from photogram.commands.bundle import calibrate, orient
from photogram.commands.montecarlo import write_pdf
from photogram.montecarlo import run_montecarlo
from photogram.project import read_project

ROOT = Path(__file__).resolve().parents[1]
PROJECTS = ROOT / "projects"


def _prepare():
    if not (PROJECTS / "lab" / "results-measure" / "image_points.csv").is_file():
        from photogram.commands.measure import measure_to_folder
        measure_to_folder(PROJECTS / "lab" / "frame.toml", report=False)
    if not (PROJECTS / "lab" / "results" / "covariance.npz").is_file():
        calibrate(read_project(PROJECTS / "lab" / "lab.prj"))
    if not (PROJECTS / "field" / "results" / "stations.csv").is_file():
        orient(read_project(PROJECTS / "field" / "field.prj"))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=1000, help="runs with 2 workers")
    ap.add_argument("--runs1", type=int, default=200, help="runs with 1 worker")
    args = ap.parse_args()
    _prepare()
    chain = read_project(PROJECTS / "jumps" / "montecarlo.prj")
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        _, s1 = run_montecarlo(chain, runs=args.runs1, workers=1, output=Path(tmp) / "w1",
                               progress=False)
        write_pdf(Path(tmp) / "w1")               # report.pdf, as the command writes it
        t1 = time.perf_counter() - t0
        t0 = time.perf_counter()
        _, s2 = run_montecarlo(chain, runs=args.runs, workers=2, output=Path(tmp) / "w2",
                               progress=False)
        write_pdf(Path(tmp) / "w2")
        t2 = time.perf_counter() - t0
    e1, e2 = s1["execution"], s2["execution"]
    r1 = e1["runs_per_second"]
    r2 = e2["runs_per_second"]
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"1 worker : {args.runs1} runs in {e1['seconds']:.2f} s = {r1:.1f} runs/s "
          f"(setup {e1['setup_seconds']:.2f} s, command {t1:.2f} s)")
    print(f"2 workers: {args.runs} runs in {e2['seconds']:.2f} s = {r2:.1f} runs/s "
          f"(setup {e2['setup_seconds']:.2f} s, command {t2:.2f} s)")
    h = s2["headline"]
    print("sigma_mc / sigma_prop (median): "
          + ", ".join(f"{g} {v['ratio']['median']:.3f}" for g, v in h.items()))
    cpu = e2["cpu_ms_per_run"]
    idle = e2["setup_seconds"] + args.runs * cpu / 1e3 / 2
    print(f"CPU per run: {cpu:.2f} ms (1 worker: {e1['cpu_ms_per_run']:.2f} ms); on an idle "
          f"2-core machine the {args.runs} runs would take about {idle:.1f} s plus the start "
          f"of the worker processes")
    print(f"load average before the end: {load:.2f} (other processes slow the wall times)")
    print(f"RESULT runs={args.runs} workers=2 total_s={t2:.2f} runs_s={e2['seconds']:.2f} "
          f"setup_s={e2['setup_seconds']:.2f} runs_per_s_1={r1:.1f} runs_per_s_2={r2:.1f} "
          f"failed={s2['failed']} ratio_jumper={h['jumper']['ratio']['median']:.3f} "
          f"ratio_stick={h['stick']['ratio']['median']:.3f} cpu_ms_per_run={cpu:.2f} "
          f"load={load:.2f} target_s=15 "
          f"ok={'yes' if t2 <= 15 else 'no'}")


if __name__ == "__main__":
    main()
