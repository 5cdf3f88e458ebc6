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


# --------------------------------------------------------------------------
# rendered SIMULATED frames of the default session (seed 8), shared by
# test_mocap_homography, test_mocap_lagged_differences and
# test_mocap_estimate_project (issue 23, item 6: the same frames were
# rendered and measured in each module)
# --------------------------------------------------------------------------
RENDER_FRAMES = tuple(range(100, 130))          # 30 frames
WIDE, ZOOMED = 2, 0                             # C3 (f ~ 4000 px) and C1 (f ~ 13000 px)


@functools.lru_cache(maxsize=1)
def ski_session():
    """``simulate_session(seed=8, n_runs=1)`` and its scene
    ``build_scene(sim)`` (texture seed 0; the scene caches each camera's
    clipmap). Callers only read them."""
    from photogram.simulation.ski.scene import build_scene
    from photogram.simulation.ski.simulate import simulate_session
    sim = simulate_session(seed=8, n_runs=1)
    return sim, build_scene(sim)


@functools.lru_cache(maxsize=1)
def ski_boxes():
    """(F, C, 4) boxes of the true image points (x0, y0, x1, y1; NaN where
    none), read-only."""
    import numpy as np
    xy = ski_session()[0].image_truth
    with np.errstate(invalid="ignore"):
        boxes = np.stack([np.nanmin(xy[..., 0], 2), np.nanmin(xy[..., 1], 2),
                          np.nanmax(xy[..., 0], 2), np.nanmax(xy[..., 1], 2)], -1)
    boxes.setflags(write=False)
    return boxes


@functools.lru_cache(maxsize=1)
def ski_images():
    """{camera: [frame, ...]} the rendered frames ``RENDER_FRAMES`` of
    cameras ``WIDE`` and ``ZOOMED`` (960 x 540 BGR, read-only: a test that
    wrote into them fails)."""
    from photogram.simulation.ski.render import render_camera
    sim, scene = ski_session()
    out = {}
    for c in (WIDE, ZOOMED):
        out[c] = list(render_camera(scene, sim, c, RENDER_FRAMES))
        for img in out[c]:
            img.setflags(write=False)
    return out


_IMAGE_USERS = {"test_mocap_homography", "test_mocap_lagged_differences"}
_IMAGES_DONE: set = set()


def release_images(module: str):
    """``module`` (one of ``_IMAGE_USERS``) has finished with the frames:
    when every user has, they are dropped (93 MB), and the session with its
    scene (the clipmaps of two cameras, ~40 MB); the measurements stay.
    A later caller computes them again."""
    _IMAGES_DONE.add(module)
    if _IMAGE_USERS <= _IMAGES_DONE:
        for cached in (ski_images, ski_boxes, ski_session):
            cached.cache_clear()


@functools.lru_cache(maxsize=None)
def ski_measured(cam, **settings):
    """``rotation_differences`` of camera ``cam``'s rendered frames with
    ``HomographySettings(**settings)`` (memoised per camera and settings:
    the default measurement was made by two modules)."""
    from photogram.mocap.motion.homography import HomographySettings, rotation_differences
    sim = ski_session()[0]
    frames = list(RENDER_FRAMES)
    rd = rotation_differences(ski_images()[cam], "opencv", sim.cameras.io[cam][frames], 0.5,
                              ski_boxes()[frames, cam], HomographySettings(**settings))
    for part in (rd, rd.lagged):                # read-only for the callers
        for value in (vars(part).values() if part is not None else ()):
            if hasattr(value, "setflags"):
                value.setflags(write=False)
    return rd
