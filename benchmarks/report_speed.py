"""Report speed (issue 23, item 1): CPU time of report.pdf against the
whole `photogram calibrate` command, in process.

Two networks:

* CAMCAL (DBAT's camera-calibration demo, REAL data: 21 images, 2074 image
  points), ``projects/camcal/camcal.prj``; needs ../shared/data/dbat/camcal
  beside the repository, otherwise skipped with a message.
* a SIMULATED wall network (:func:`photogram.simulation.network.wall_network`,
  60 stations, 26,000 points, about 7 rays per point: about 181,000 image
  observations, the size of DBAT's ROMA network), interior fixed, 10 control
  points. ``--no-large`` skips it; ``--large-points`` changes its size.

CPU seconds (``time.process_time``, less sensitive than wall time to the
shared machine's load, though still about +-20 % from run to run) of the whole command (adjustment, results folder, report) and of the
report step alone (:func:`photogram.report.write_report`, wrapped where the
command calls it). CAMCAL runs twice: the first run is cold (it pays the
imports of matplotlib and the report's page modules, as a fresh command
process does), the second warm (figures under camcal_*; with ``--profile``
the warm run is profiled and its times include the profiler's overhead).
The large network runs once, after CAMCAL (warm; cold when CAMCAL is
skipped). Goal: report <= 15 % of the command and <= 2 s for
CAMCAL, <= 6 s for the large network.

The reports of calibrate and orient are drawn by the native PDF writer
(photogram/report/pdf, no matplotlib; ``renderer=native`` in the RESULT line,
``--matplotlib`` forces the matplotlib layout of the same pages for a
comparison). The cold CAMCAL run pays the imports the report needs and the
command does not (the writer and page modules; the results tables of a small
folder are read without pandas: ``camcal_pandas=no`` in the RESULT line).
``--floor`` measures in a fresh process what no page design can remove:
matplotlib's import with 15 pages of header and footer and 35 empty axes
(CAMCAL's report has 15 pages and 35 axes), and for the native writer the
import of the report's modules and the same 15 pages.

``--repeat N`` runs CAMCAL N more times warm and reports the medians
(``camcal_med_*``): single runs on the shared machine scatter by +-20 %.

``--process N`` also measures what the issue measured: whole command
processes. For each network, N alternating pairs of fresh ``photogram
calibrate -q PRJ --output X`` processes with and without ``--no-report``
(after one untimed run that writes the byte code), and N fresh ``photogram
report X``; user + system CPU of each child (:func:`os.wait4`), medians;
the report's share is ``1 - median(no-report) / median(full)`` (keys
``*_proc_*`` in the RESULT line, beside the in-process ones). The children
run this checkout's photogram and cli/ without PYTHONDONTWRITEBYTECODE.

Run: .venv/bin/python benchmarks/report_speed.py [--no-large] [--seed S] [--profile N]
[--floor] [--matplotlib] [--process N] [--repeat N]
Ends with one line ``RESULT key=value ...``.
"""

import argparse
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

# benchmarks/profile.py would shadow the standard library's profile module
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]
import cProfile  # noqa: E402
import pstats  # noqa: E402

import photogram  # noqa: F401  (single-threaded BLAS before numpy)
import numpy as np

import photogram.report as report_pkg
from photogram.commands.bundle import calibrate

ROOT = Path(__file__).resolve().parents[1]
CAMCAL = ROOT / "projects" / "camcal" / "camcal.prj"
DATA = ROOT.parent / "shared" / "data" / "dbat" / "camcal"


class ReportTimer:
    """Wrap :func:`photogram.report.write_report` (the command imports it
    from the package at call time) and add up its CPU seconds."""

    def __init__(self, profile=None):
        self.cpu = 0.0
        self.profile = profile
        self._orig = report_pkg.write_report

    def __enter__(self):
        def timed(*args, **kwargs):
            t = time.process_time()
            try:
                if self.profile is not None:
                    return self.profile.runcall(self._orig, *args, **kwargs)
                return self._orig(*args, **kwargs)
            finally:
                self.cpu += time.process_time() - t
        report_pkg.write_report = timed
        return self

    def __exit__(self, *exc):
        report_pkg.write_report = self._orig


def run_command(project, profile=None):
    """``(command CPU s, report CPU s)`` of calibrate on ``project`` (the
    results folder is written to a temporary folder and removed)."""
    with tempfile.TemporaryDirectory(prefix="report-speed-") as tmp:
        with ReportTimer(profile) as timer:
            t = time.process_time()
            calibrate(project, output=Path(tmp) / "results")
            total = time.process_time() - t
    return total, timer.cpu


def camcal_project():
    from photogram.project.reader import read_project
    return read_project(CAMCAL)


def large_project(n_points, seed=0):
    from photogram.simulation.network import to_project, wall_network
    net = wall_network(n_stations=60, n_points=n_points, rays=7, seed=seed)
    prj = to_project(net, control=range(10), perturb_points=0.05, perturb_stations=0.005,
                     sigma_image=0.5, rng=np.random.default_rng(seed), name="wall")
    prj.adjustment.datum = "control"
    # written and read back, as `photogram calibrate wall.prj` would read it
    from photogram.project.reader import read_project
    from photogram.project.writer import write_project
    path = write_project(prj, Path(tempfile.mkdtemp(prefix="report-speed-wall-")) / "wall.prj")
    return read_project(path), len(net.station), path.parent


_FLOOR = r"""
import time
t0 = time.process_time()
import matplotlib
from matplotlib.figure import Figure
from matplotlib.backends.backend_pdf import PdfPages
t1 = time.process_time()
import io
from contextlib import ExitStack
from photogram.report.layout import Document
from photogram.report.writer import _style
pages, axes = {pages}, {axes}
out = []
for with_axes in (False, True):
    t = time.process_time()
    with ExitStack() as stack:
        _style(stack)
        doc = Document(header="photogram calibrate report: floor")
        for i in range(pages):
            doc.start_section(f"section {{i}}", intro="one line of text")
        if with_axes:
            for i in range(axes):
                doc.page.figure.add_axes([0.1 + 0.02 * (i % 5), 0.1, 0.1, 0.1])
        figures = doc.finish("footer")
        with PdfPages(io.BytesIO()) as pdf:
            for fig in figures:
                pdf.savefig(fig)
    out.append(time.process_time() - t)
print(f"{{t1 - t0:.3f}} {{out[0]:.3f}} {{out[1]:.3f}}")
"""


_NATIVE_FLOOR = r"""
import time
import photogram.commands.bundle  # what the command has imported before its report
t1 = time.process_time()
from photogram.report.native import NativeDocument
from photogram.report.registry import sections
sections()
t2 = time.process_time()
doc = NativeDocument(header="photogram calibrate report: floor")
for i in range({pages}):
    doc.start_section(f"section {{i}}", intro="one line of text")
doc.finish("footer")
doc.tobytes()
t3 = time.process_time()
print(f"{{t2 - t1:.3f}} {{t3 - t2:.3f}}")
"""


def native_floor(pages):
    """CPU seconds, in a fresh process that has imported what `photogram
    calibrate` imports before its report, of ``(import of the native writer
    and the page modules, pages with heading/header/footer only)``."""
    import subprocess
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    out = subprocess.run([sys.executable, "-c", _NATIVE_FLOOR.format(pages=pages)],
                         capture_output=True, text=True, env=env, check=True, cwd=ROOT)
    return tuple(float(x) for x in out.stdout.split())


def force_matplotlib():
    """Register every section as non-native: the report is drawn with
    matplotlib (the layout before the native writer)."""
    from dataclasses import replace
    from photogram.report.registry import SECTIONS, sections
    sections()
    for name, sec in list(SECTIONS.items()):
        SECTIONS[name] = replace(sec, native=False)


def floor(pages, axes):
    """CPU seconds, in a fresh process, of what any matplotlib report of
    ``pages`` pages with ``axes`` (empty) axes costs: ``(import of matplotlib
    and its PDF backend, pages with heading/header/footer only, the same
    with the empty axes)``."""
    import subprocess
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    out = subprocess.run([sys.executable, "-c", _FLOOR.format(pages=pages, axes=axes)],
                         capture_output=True, text=True, env=env, check=True, cwd=ROOT)
    return tuple(float(x) for x in out.stdout.split())


# the CLI from this checkout (photogram_cli is installed from cli/, perhaps of another
# checkout): load cli/ under its installed name, then run it as the console script does
_CLI = r"""
import importlib.util, sys
spec = importlib.util.spec_from_file_location(
    "photogram_cli", {init!r}, submodule_search_locations=[{folder!r}])
mod = importlib.util.module_from_spec(spec)
sys.modules["photogram_cli"] = mod
spec.loader.exec_module(mod)
from photogram_cli.main import main
sys.argv[0] = "photogram"
sys.exit(main())
"""


def cli_argv(*args):
    """argv of a fresh ``photogram ARGS`` process running this checkout."""
    code = _CLI.format(init=str(ROOT / "cli" / "__init__.py"), folder=str(ROOT / "cli"))
    return [sys.executable, "-c", code, *map(str, args)]


def child_cpu(argv):
    """User + system CPU seconds of the process ``argv`` (its own rusage,
    from :func:`os.wait4`); raises if it fails."""
    import subprocess
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    env["PYTHONPATH"] = str(ROOT)
    with tempfile.TemporaryFile() as err:
        proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=err, env=env, cwd=ROOT)
        _, status, usage = os.wait4(proc.pid, 0)
        proc.returncode = os.waitstatus_to_exitcode(status)
        if proc.returncode != 0:
            err.seek(0)
            raise RuntimeError(f"{argv[3:]} failed ({proc.returncode}): "
                               f"{err.read().decode(errors='replace')[-2000:]}")
    return usage.ru_utime + usage.ru_stime


def process_share(prj_path, pairs):
    """The report's share of fresh ``photogram calibrate`` processes.

    ``pairs`` alternating runs of ``calibrate -q PRJ --output X`` with and
    without ``--no-report`` (after one untimed run that writes the byte code),
    then ``pairs`` runs of ``photogram report X`` alone. Returns the medians
    ``(full, no_report, report_alone)`` in CPU seconds; the share is
    ``1 - no_report / full``.
    """
    with tempfile.TemporaryDirectory(prefix="report-process-") as tmp:
        out = Path(tmp) / "results"

        def run(*extra):                    # a new results folder each time
            shutil.rmtree(out, ignore_errors=True)
            return child_cpu(cli_argv("calibrate", "-q", prj_path, "--output", out, *extra))

        run()                               # byte code, page cache
        full, bare, alone = [], [], []
        for _ in range(pairs):
            bare.append(run("--no-report"))
            full.append(run())
        for _ in range(pairs):
            alone.append(child_cpu(cli_argv("report", out)))
    return float(np.median(full)), float(np.median(bare)), float(np.median(alone))


def show_process(label, key, prj_path, pairs, fields):
    """Measure :func:`process_share`, print it and add it to ``fields``."""
    full, bare, alone = process_share(prj_path, pairs)
    share = 1.0 - bare / full
    print(f"{label}, fresh processes (median of {pairs}): calibrate {full:.2f} s CPU, "
          f"--no-report {bare:.2f} s, report's share {100 * share:.1f} %; "
          f"`photogram report` alone {alone:.2f} s")
    fields.update({f"{key}_proc_cmd": f"{full:.2f}", f"{key}_proc_noreport": f"{bare:.2f}",
                   f"{key}_proc_share": f"{share:.3f}", f"{key}_proc_report_alone": f"{alone:.2f}"})


def show(label, total, rep, goal):
    share = rep / total if total > 0 else float("nan")
    print(f"{label}: command {total:.2f} s CPU, report {rep:.2f} s CPU "
          f"({100 * share:.1f} %), goal report <= {goal:.0f} s and <= 15 %")
    return share


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--no-large", action="store_true", help="skip the simulated large network")
    ap.add_argument("--large-points", type=int, default=26_000)
    ap.add_argument("--seed", type=int, default=0, help="seed of the simulated network")
    ap.add_argument("--profile", type=int, default=0, metavar="N",
                    help="print the N costliest calls of the CAMCAL report (cumulative)")
    ap.add_argument("--floor", action="store_true",
                    help="also measure the floors (matplotlib's and the native writer's) "
                         "for CAMCAL's 15 pages and 35 axes")
    ap.add_argument("--matplotlib", action="store_true",
                    help="draw the reports with matplotlib, not the native writer")
    ap.add_argument("--repeat", type=int, default=0, metavar="N",
                    help="N more warm CAMCAL runs: medians of command, report and share "
                         "(the machine's load changes single runs by +-20 %%)")
    ap.add_argument("--process", type=int, default=0, metavar="N",
                    help="also measure fresh command processes: N alternating pairs of "
                         "calibrate with and without --no-report, and N of `photogram report`")
    args = ap.parse_args()
    if args.matplotlib:
        force_matplotlib()
    fields = {"renderer": "matplotlib" if args.matplotlib else "native"}
    if DATA.is_dir():
        # first run: cold, as a fresh `photogram calibrate` process pays it (imports of
        # matplotlib and the page modules, fonts, numba's cached kernels); then warm
        total, rep = run_command(camcal_project())
        share = show("CAMCAL (real data, 2074 image points), first run (cold)", total, rep, 2)
        fields.update(camcal_cold_cmd=f"{total:.2f}", camcal_cold_report=f"{rep:.2f}",
                      camcal_cold_share=f"{share:.3f}")
        prof = cProfile.Profile() if args.profile else None
        total, rep = run_command(camcal_project(), prof)
        share = show("CAMCAL (real data, 2074 image points), second run (warm)", total, rep, 2)
        fields.update(camcal_cmd=f"{total:.2f}", camcal_report=f"{rep:.2f}",
                      camcal_share=f"{share:.3f}")
        if args.repeat > 1:
            runs = np.array([run_command(camcal_project()) for _ in range(args.repeat)])
            total, rep = np.median(runs, axis=0)
            share = float(np.median(runs[:, 1] / runs[:, 0]))
            print(f"CAMCAL, {args.repeat} more warm runs: median command {total:.3f} s CPU, "
                  f"median report {rep:.3f} s, median share {100 * share:.1f} % "
                  f"(per run {100 * (runs[:, 1] / runs[:, 0]).min():.1f}-"
                  f"{100 * (runs[:, 1] / runs[:, 0]).max():.1f} %)")
            fields.update(camcal_runs=args.repeat, camcal_med_cmd=f"{total:.3f}",
                          camcal_med_report=f"{rep:.3f}", camcal_med_share=f"{share:.3f}")
        if prof is not None:
            pstats.Stats(prof).sort_stats("cumulative").print_stats(args.profile)
        if args.floor:
            imp, bare, with_axes = floor(15, 35)
            rest = total - rep
            print(f"floor (fresh process): import of matplotlib + PDF backend {imp:.2f} s, "
                  f"15 pages of header/heading/footer {bare:.2f} s, with 35 empty axes "
                  f"{with_axes:.2f} s; the command without its report {rest:.2f} s: "
                  f"a report at that floor would be "
                  f"{100 * (imp + with_axes) / (rest + imp + with_axes):.0f} % of the command")
            fields.update(floor_import=f"{imp:.2f}", floor_pages=f"{bare:.2f}",
                          floor_axes=f"{with_axes:.2f}", camcal_rest=f"{rest:.2f}")
            mod_imp, pages = native_floor(15)
            print(f"native floor (fresh process): import of the writer and page modules "
                  f"{mod_imp:.2f} s, 15 pages of header/heading/footer {pages:.3f} s")
            fields.update(native_floor_modules=f"{mod_imp:.2f}",
                          native_floor_pages=f"{pages:.3f}")
        # the report reads small results folders without pandas (its import alone
        # was 0.23 s CPU, more than the rest of CAMCAL's report)
        fields["camcal_pandas"] = "yes" if "pandas" in sys.modules else "no"
        if args.process:
            show_process("CAMCAL", "camcal", CAMCAL, args.process, fields)
    else:
        print(f"CAMCAL skipped: no data at {DATA} (DBAT's camcal folder beside the repository)")
        fields["camcal"] = "skipped"
    if not args.no_large:
        prj, n_obs, folder = large_project(args.large_points, args.seed)
        label = f"wall network (SIMULATED, {args.large_points} points, {n_obs} observations)"
        try:
            total, rep = run_command(prj)
            share = show(label, total, rep, 6)
            fields.update(seed=args.seed, large_points=args.large_points, large_obs=n_obs,
                          large_cmd=f"{total:.2f}", large_report=f"{rep:.2f}",
                          large_share=f"{share:.3f}")
            if args.process:
                show_process(label, "large", folder / "wall.prj", args.process, fields)
        finally:
            shutil.rmtree(folder, ignore_errors=True)
    print("RESULT " + " ".join(f"{k}={v}" for k, v in fields.items()))


if __name__ == "__main__":
    main()
