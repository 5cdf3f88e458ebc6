"""Shared fixtures."""

from __future__ import annotations

import contextlib
import io
import os
import shutil
import sys
from pathlib import Path

# photogram's policy (photogram/__init__.py): one BLAS thread. Test modules
# import numpy before photogram, which made that too late: OpenBLAS threads
# spinning on the shared 2-core machine (a 1062 x 1062 Cholesky of the mocap
# joint solver: 0.18-0.6 s CPU with two threads under load, 0.016 s with one).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
# OpenCV's thread pool likewise (read when cv2 is first imported): its
# parallel remap, blur and connected components cost more CPU than they
# save on that machine (tests/test_rig_rendered.py: 19.2 s CPU, 3.8 s of
# it system time, with two threads; 15.1 s, 0.5 s system, with one).
os.environ.setdefault("OPENCV_FOR_THREADS_NUM", "1")

import pytest  # noqa: E402

PROJECTS = Path(__file__).resolve().parents[1] / "projects"


@pytest.fixture(scope="session")
def oriented_projects(tmp_path_factory):
    """A folder with copies of projects/lab (its photographs measured and
    calibrated), projects/field (oriented) and projects/jumps, as `make
    demo` leaves them: ``root/lab/results``, ``root/field/results``, the
    jumps project reading them by its relative paths. Built once per test
    session, so that tests of the later steps run in a fresh clone too."""
    from lab_stage import stage_lab
    from photogram_cli.main import main
    root = tmp_path_factory.mktemp("oriented")
    for name in ("field", "jumps"):
        shutil.copytree(PROJECTS / name, root / name,
                        ignore=shutil.ignore_patterns("results*", "video", ".*"))
    stage_lab(root / "lab", calibrate=True, measured_copy=True)
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        assert main(["orient", "--no-report", "-q", str(root / "field" / "field.prj")]) == 0
    return root


@pytest.fixture(scope="session")
def example_steps(oriented_projects, tmp_path_factory):
    """The example projects' steps (tests/examples_run.py), each run once per
    session on first use, the lab and field steps taken from
    ``oriented_projects`` (the same command lines): ``.results(step)`` is the
    results folder (shared: copy it before changing anything),
    ``.figures(step)`` what tests/test_examples_unchanged.py compares."""
    from examples_run import ExampleSteps
    return ExampleSteps(tmp_path_factory.mktemp("examples"), oriented=oriented_projects)


@pytest.fixture(scope="session")
def jumps_report(oriented_projects, tmp_path_factory):
    """The intersect results of projects/jumps (SIMULATED) with report.pdf,
    in a fresh folder (``intersect_and_write`` on ``oriented_projects``):
    shared by the intersect report tests, read only."""
    from photogram.commands.intersect import intersect_and_write
    from photogram.project import read_project
    out = tmp_path_factory.mktemp("jumps-report") / "results"
    folder, _ = intersect_and_write(read_project(oriented_projects / "jumps" / "jumps.prj"),
                                    output=out)
    return folder


def _malloc_trim():
    """``malloc_trim(0)`` of glibc (None elsewhere)."""
    import ctypes
    import ctypes.util
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        return libc.malloc_trim
    except (OSError, AttributeError):
        return None


_TRIM = _malloc_trim()


def _resident() -> int:
    """This process's resident size in bytes (0 where /proc is missing)."""
    try:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError):
        return 0


_TRIMMED = [0]       # the resident size after the last trim


def pytest_collection_finish(session):
    """Move what the imports and the collection made (modules, test
    items: live for the whole session) out of the garbage collector's
    reach (``gc.freeze``): every full collection of the session walked
    them again. In the mocap, track and example tests the collector's CPU
    3.1 -> 1.8 s (gc callbacks); cyclic garbage is still collected."""
    import gc
    gc.collect()
    gc.freeze()


def pytest_runtest_teardown(item, nextitem):
    """After the last test of a module: drop the rendered rig sets' caches
    and give the heap that its tests freed back to the system (about 3 ms;
    glibc keeps it otherwise, and the session's resident size only grows).
    After tests/test_board_rig_render.py 0.48 GB without either, 0.35 GB
    with the trim, 0.26 GB with both. Within a module, a trim after a test
    that left the process 100 MB above the last trim."""
    if nextitem is not None and nextitem.module is item.module:
        if _TRIM is not None and _resident() > _TRIMMED[0] + 100_000_000:
            _TRIM(0)
            _TRIMMED[0] = _resident()
        return
    # the rendered rig sets' per-camera caches (165 MB), render_plane's maps (64 MB)
    for name in ("photogram.simulation.board_rig.render", "photogram.measure.render"):
        render = sys.modules.get(name)
        if render is not None:
            render.clear_caches()
    if _TRIM is not None:
        _TRIM(0)
        _TRIMMED[0] = _resident()
