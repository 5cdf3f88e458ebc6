"""The example projects run from a clean copy, and the figures that must not
change when the code is only restructured (issue 17, "no behaviour change").

:func:`run_examples` copies ``projects/`` (without results folders) into a
temporary folder beside a link to ``../shared`` (so the real-data projects
find their tables by the same relative paths), runs every example's command
through the command-line entry point (``python -m photogram_cli``, a fresh
interpreter per step; the test runs them in its own process with one BLAS
thread, :func:`_run_step`), and returns per step:

* ``summary``: the figures of ``summary.json`` that the issue names (sigma0,
  redundancy; for motion capture the reprojection, limb and accuracy
  figures) as written;
* ``tables``: SHA-256 of the result tables written with a fixed number of
  digits (the stick-model tables ``exposures.csv``, ``points3d.csv``,
  ``lines3d.csv``; the lab's measured ``image_points.csv``), so "equal to the
  last digit written" is checked byte for byte.

``tests/data/examples_before_issue17.json`` holds these figures as produced
by the code before the restructuring (commit def3da7); it was written with
``python tests/examples_run.py --record`` on that commit.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import shutil
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared"
RECORD = Path(__file__).parent / "data" / "examples_before_issue17.json"

#: (step name, command line relative to the copied projects/, results folder,
#: needs ../shared/data, tables compared byte for byte)
STEPS = [
    ("measure lab", ["measure", "lab/frame.toml", "--no-report"], "lab/results-measure",
     False, ["image_points.csv"]),
    ("calibrate lab", ["calibrate", "lab/lab.prj"], "lab/results", False, []),
    ("orient field", ["orient", "field/field.prj"], "field/results", False, []),
    ("intersect jumps", ["intersect", "jumps/jumps.prj"], "jumps/results", False,
     ["exposures.csv", "points3d.csv", "lines3d.csv"]),
    ("mocap ski-ptz", ["mocap", "ski-ptz/ski-ptz.prj"], "ski-ptz/results", False, []),
    ("mocap ski-ptz-estimate", ["mocap", "ski-ptz/ski-ptz-estimate.prj"],
     "ski-ptz/results-estimate", False, []),
    ("simulate situation-b", ["simulate", "designs/situation-b.toml", "--output", "designs/sim-b"],
     "designs/sim-b", False, ["situation-b_image_points.csv", "situation-b_points.csv",
                              "situation-b_stations.csv"]),
    ("calibrate situation-b", ["calibrate", "designs/sim-b/situation-b.prj"],
     "designs/sim-b/results", False, []),
    ("calibrate camcal", ["calibrate", "camcal/camcal.prj"], "camcal/results", True, []),
    ("orient sxb", ["orient", "sxb/sxb.prj"], "sxb/results", True, []),
    ("mocap pose2sim-demo", ["mocap", "pose2sim-demo/demo.prj"], "pose2sim-demo/results",
     True, []),
]

#: commands run with --no-report (measure's is in its STEPS entry; simulate writes none)
NO_REPORT = ("calibrate", "orient", "intersect", "mocap")
#: summary.json keys compared as written (nested dicts compared whole)
SUMMARY_KEYS = ("sigma0", "redundancy", "iterations", "reprojection", "limb_lengths",
                "bone_cv_mean", "accuracy", "reconstruction", "metrics_mean")
#: parts of the summary that are not results (run times, versions)
NOT_RESULTS = ("timings", "seconds", "time_s", "wall_s", "cpu_s")


def _drop_timings(value):
    if isinstance(value, dict):
        return {k: _drop_timings(v) for k, v in value.items()
                if not any(t in k for t in NOT_RESULTS)}
    if isinstance(value, list):
        return [_drop_timings(v) for v in value]
    return value


def have_shared_data() -> bool:
    return (SHARED / "data" / "dbat" / "camcal").is_dir()


def stage_projects(dest: Path) -> Path:
    """Copy projects/ without results into ``dest``/repo/projects and link
    ``dest``/shared to ../shared; returns the copied projects folder."""
    dest = Path(dest)
    projects = dest / "repo" / "projects"
    shutil.copytree(REPO / "projects", projects,
                    ignore=shutil.ignore_patterns("results", "results-*", ".*", "__pycache__"))
    if SHARED.is_dir():
        (dest / "shared").symlink_to(SHARED, target_is_directory=True)
    return projects


def _options(options: list[str], projects: Path) -> list[str]:
    """The options of a step, with the folder after --output inside the copy."""
    return [str(projects / a) if k and options[k - 1] == "--output" else a
            for k, a in enumerate(options)]


def _run_step(args: list[str], cwd: Path, in_process: bool) -> tuple[int, str]:
    """``photogram ARGS`` with ``cwd`` as the working folder: (exit code,
    stderr). In a fresh interpreter, as a user runs it: photogram then sets
    one BLAS thread before numpy loads (inside pytest numpy is already
    loaded, and threaded BLAS changes the last digits of the estimate). Or
    ``in_process``: through the same entry point in this process with BLAS
    held to one thread (threadpoolctl), which gives the same numbers without
    the interpreter's start and imports (about 1.5 s CPU a step)."""
    if not in_process:
        done = subprocess.run([sys.executable, "-m", "photogram_cli", *args],
                              capture_output=True, text=True, cwd=cwd)
        return done.returncode, done.stderr
    from threadpoolctl import threadpool_limits

    from photogram_cli.main import main
    err = io.StringIO()
    with threadpool_limits(limits=1, user_api="blas"), contextlib.chdir(cwd), \
            contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        code = main(args)
    return code, err.getvalue()


def run_examples(dest: Path, *, with_shared: bool | None = None,
                 in_process: bool = False) -> dict:
    """Run every example step in a copy under ``dest``; returns the figures
    per step (see the module docstring; ``in_process``: :func:`_run_step`)."""
    if with_shared is None:
        with_shared = have_shared_data()
    projects = stage_projects(dest)
    figures = {}
    for name, argv, folder, shared, tables in STEPS:
        if shared and not with_shared:
            continue
        _run_example(name, projects, dest, in_process)
        figures[name] = _figures(projects / folder, tables)
    return figures


def _run_example(name: str, projects: Path, cwd: Path, in_process: bool) -> None:
    """Run the example step ``name`` in the staged ``projects`` folder."""
    argv = next(s[1] for s in STEPS if s[0] == name)
    # the examples' figures are in summary.json and the tables: no report.pdf
    # (it costs more CPU than the adjustment; tests/test_report*.py test it)
    skip = ["--no-report"] if argv[0] in NO_REPORT else []
    # nor mocap's PNG figures (tests/test_mocap_project.py and the report tests test them)
    skip += ["--no-figures"] if argv[0] == "mocap" else []
    args = [argv[0], str(projects / argv[1]), *_options(argv[2:], projects), "-q", *skip]
    code, err = _run_step(args, cwd, in_process)
    if code != 0:
        raise RuntimeError(f"photogram {' '.join(args)} exited {code}: {err[-3000:]}")


def _figures(results: Path, tables: list[str]) -> dict:
    """The compared figures of one step's results folder (module docstring)."""
    entry = {"tables": {}}
    summary_path = results / "summary.json"
    if summary_path.is_file():
        summary = json.loads(summary_path.read_text())
        entry["summary"] = {k: _drop_timings(summary[k]) for k in SUMMARY_KEYS if k in summary}
    for table in tables:
        entry["tables"][table] = hashlib.sha256((results / table).read_bytes()).hexdigest()
    return entry


#: steps whose inputs are the results of earlier steps
NEEDS = {"calibrate lab": "measure lab", "orient field": "calibrate lab",
         "intersect jumps": "orient field", "calibrate situation-b": "simulate situation-b"}
#: the steps conftest.py's ``oriented_projects`` has run (the same command lines)
ORIENTED = {"measure lab": "lab/results-measure", "calibrate lab": "lab/results",
            "orient field": "field/results"}


class ExampleSteps:
    """The example steps of one test session, each run once on first use
    (in this process, :func:`_run_step`) in one staged copy of projects/, so
    that tests of an example's results share its run with
    tests/test_examples_unchanged.py.

    ``oriented``: a folder as conftest.py's ``oriented_projects`` leaves it
    (lab measured and calibrated, field oriented by the same command lines
    as the steps "measure lab", "calibrate lab", "orient field"); its results
    folders are copied in as those steps' results instead of running them
    again. The folders returned by :meth:`results` are shared: read them,
    copy them before changing anything.
    """

    def __init__(self, dest: Path, oriented: Path | None = None):
        self.dest = Path(dest)
        self.projects = stage_projects(self.dest)
        self.done: set = set()
        if oriented is not None:
            for name, folder in ORIENTED.items():
                shutil.copytree(Path(oriented) / folder, self.projects / folder)
                self.done.add(name)

    def results(self, name: str) -> Path:
        """The results folder of step ``name``, the step (and the steps it
        needs) run first if not yet run."""
        if name not in self.done:
            if name in NEEDS:
                self.results(NEEDS[name])
            _run_example(name, self.projects, self.dest, in_process=True)
            self.done.add(name)
        return self.projects / next(s[2] for s in STEPS if s[0] == name)

    def copy(self, names, dest: Path) -> Path:
        """Copy the staged project folders ``names`` (with the results of
        the steps run so far) into ``dest``, the paths of the staged copy
        in the results' summary.json and log.txt replaced by ``dest``'s, as
        if the steps had run there; returns ``dest``."""
        dest = Path(dest)
        for name in names:
            shutil.copytree(self.projects / name, dest / name, symlinks=True)
            for path in (dest / name).glob("results*/*"):
                if path.name in ("summary.json", "log.txt"):
                    text = path.read_text(encoding="utf-8")
                    path.write_text(text.replace(str(self.projects), str(dest)),
                                    encoding="utf-8")
        return dest

    def figures(self, name: str) -> dict:
        """The compared figures of step ``name`` (module docstring)."""
        tables = next(s[4] for s in STEPS if s[0] == name)
        return _figures(self.results(name), tables)


def load_record() -> dict:
    return json.loads(RECORD.read_text())


if __name__ == "__main__":
    import tempfile
    if "--record" not in sys.argv:
        sys.exit("usage: python tests/examples_run.py --record   (writes " + str(RECORD) + ")")
    with tempfile.TemporaryDirectory() as tmp:
        figures = run_examples(Path(tmp), with_shared=True)
    RECORD.write_text(json.dumps(figures, indent=1, sort_keys=True) + "\n")
    print(f"wrote {RECORD} ({len(figures)} steps)")
