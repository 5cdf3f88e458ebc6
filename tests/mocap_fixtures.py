"""Mocap runs that several test modules make on the same input, computed
once per test process (issue 23, item 6: the test budget).

The functions are memoised (``functools.lru_cache``): the first caller pays,
the others reuse the result. Callers only read the result; a test that
changes a setting runs the pipeline itself.
"""

import functools
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DEMO_PRJ = ROOT / "projects" / "pose2sim-demo" / "demo.prj"


@functools.lru_cache(maxsize=1)
def pose2sim_demo_run():
    """``run_mocap`` of ``projects/pose2sim-demo/demo.prj`` as shipped (its
    default settings: multi-view choice, DCT 12 Hz + Butterworth 6 Hz,
    sigma^2 = 400 px^2); REAL data, read in place (the callers skip without
    it). Shared by test_mocap_people, test_mocap_smoothing and
    test_mocap_project (four identical runs before)."""
    from photogram.mocap.pipeline import run_mocap
    from photogram.project import read_project
    return run_mocap(read_project(DEMO_PRJ))
