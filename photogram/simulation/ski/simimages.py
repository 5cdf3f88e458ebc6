"""Rotation differences measured on the simulator's rendered images.

THE IMAGES ARE SIMULATED (:mod:`photogram.simulation.ski.render`): every camera of a
:class:`photogram.simulation.ski.simulate.SkiSimulation` is rendered at 960 x 540
and its frame-to-frame rotations measured by
:func:`photogram.mocap.motion.homography.rotation_differences`, outside the
athlete's box (the box of its detections), one process per camera. Used by
``projects/ski-ptz/generate.py``, ``benchmarks/ski_ptz.py`` and the tests.
"""

from __future__ import annotations

import itertools
import time
import warnings

import numpy as np

__all__ = ["detection_boxes", "simulated_differences"]


def detection_boxes(observations: np.ndarray, camera: int) -> np.ndarray:
    """The box (F, 4) ``x0, y0, x1, y1`` (px) of the detections of one
    camera per frame (NaN: no detection)."""
    xy = observations[:, camera, :, :2]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.stack([np.nanmin(xy[..., 0], 1), np.nanmin(xy[..., 1], 1),
                         np.nanmax(xy[..., 0], 1), np.nanmax(xy[..., 1], 1)], -1)


def _one_camera(sim, c, textured, settings):
    import cv2

    from photogram.mocap.motion.homography import rotation_differences
    from photogram.simulation.ski.render import render_camera
    from photogram.simulation.ski.scene import build_scene
    cv2.setNumThreads(1)
    t0 = time.process_time()
    scene = build_scene(sim, seed=0, texture=textured)
    images = render_camera(scene, sim, c)                 # streamed: one frame at a time
    first = next(images)
    rd = rotation_differences(itertools.chain([first], images), sim.cameras.models[c],
                              sim.cameras.io[c],
                              image_scale=first.shape[1] / sim.cameras.image_size[c, 0],
                              boxes=detection_boxes(sim.observations, c), settings=settings)
    return rd, time.process_time() - t0 - rd.seconds


def simulated_differences(sim, cameras=None, featureless=(), n_jobs: int = 1, settings=None):
    """Render and measure (module doc).

    Parameters
    ----------
    sim : SkiSimulation
    cameras : list of int, optional
        Camera indices (default all).
    featureless : collection of int
        Cameras rendered without any texture or objects (uniform snow and
        sky: a camera with too few background features).
    n_jobs : int
        Processes (joblib).

    Returns
    -------
    per_camera : dict
        camera name -> :class:`photogram.mocap.motion.homography.RotationDifferences`.
    render_seconds : float
        CPU seconds spent rendering (all cameras): the cameras' CPU time
        minus the measurement's own (``RotationDifferences.seconds``).
    """
    from joblib import Parallel, delayed
    cams = list(range(sim.cameras.n_cameras)) if cameras is None else list(cameras)
    jobs = [delayed(_one_camera)(sim, c, c not in featureless, settings) for c in cams]
    out = Parallel(n_jobs=n_jobs)(jobs) if n_jobs != 1 else [j[0](*j[1], **j[2]) for j in jobs]
    return ({sim.cameras.names[c]: o[0] for c, o in zip(cams, out)},
            float(sum(o[1] for o in out)))
