"""Camera setup and ideal image coordinates of a project's observations.

:func:`camera_setup` gives every camera's model, interior orientation and
principal distance; :func:`to_ideal` corrects all image-point observations
with their camera model so that the ideal collinearity equations of
:mod:`photogram.init.rays` hold. The input of the approximation chain
(:mod:`photogram.init.chain`).
"""

from __future__ import annotations

import numpy as np

from photogram.errors import InputError

__all__ = ["camera_setup", "to_ideal"]


def _model_of(camera, model):
    from photogram.geometry import camera_model
    if model is None:
        return camera_model(camera.model)
    if isinstance(model, str):
        return camera_model(model)
    return model


def _principal_distance(model, io) -> float:
    names = list(model.parameter_names)
    for key in ("c", "fx", "f"):
        if key in names:
            return float(io[names.index(key)])
    return 1.0


def camera_setup(project, model=None, camera_values=None) -> dict:
    """Camera model, interior orientation and principal distance of every
    camera of ``project``.

    Parameters
    ----------
    project : Project
    model : None, str or camera model
        None: each camera's own model; otherwise used for all cameras (its
        parameters must match the cameras' parameter count).
    camera_values : dict, optional
        Camera name -> interior orientation array overriding
        ``Camera.values()``.

    Returns
    -------
    dict
        Camera name -> ``(model, io, c)``.

    Raises
    ------
    InputError
        Unknown model, parameter count mismatch, non-positive principal
        distance.
    """
    out = {}
    for name, cam in project.cameras.items():        # loop over cameras
        m = _model_of(cam, model)
        io = np.asarray(camera_values[name] if camera_values and name in camera_values
                        else cam.values(), dtype=float)
        if io.shape != (len(m.parameter_names),):
            raise InputError(
                f"camera {name}: {io.size} interior-orientation values, model "
                f"{m.name!r} needs {len(m.parameter_names)}",
                hint="parameters in order: " + ", ".join(m.parameter_names))
        c = _principal_distance(m, io)
        if not (np.isfinite(c) and c > 0):
            raise InputError(f"camera {name}: principal distance must be positive, got {c:g}")
        out[name] = (m, io, c)
    return out


def to_ideal(project, camera_values=None, model=None) -> tuple[np.ndarray, np.ndarray]:
    """Ideal image coordinates of all image-point observations.

    Measured coordinates are corrected with the camera model
    (``model.correct(xy, io)`` for "brown": distortion, affinity removed,
    reduced to the principal point, y down) so that the ideal collinearity
    equations ``x̄ = -c Xc_x/Xc_z``, ``ȳ = c Xc_y/Xc_z`` hold; models
    without ``correct`` use ``c * model.image_to_ray(xy, io)``.

    Parameters
    ----------
    project : Project
    camera_values : dict, optional
        Camera name -> interior orientation (default ``Camera.values()``).
    model : None, str or camera model
        See :func:`camera_setup`.

    Returns
    -------
    xy_ideal : ndarray (n_obs, 2)
        Reduced to the principal point.
    c : ndarray (n_obs,)
        Principal distance of each observation's camera.
    """
    setup = camera_setup(project, model, camera_values)
    obs = project.image_points
    st_cam = np.array(project.stations.camera, dtype=object)
    xy = np.full((len(obs), 2), np.nan)
    c = np.full(len(obs), np.nan)
    cam_of_obs = st_cam[obs.station] if len(obs) else np.zeros(0, dtype=object)
    for name, (m, io, cc) in setup.items():          # loop over cameras
        rows = np.nonzero(cam_of_obs == name)[0]
        if not len(rows):
            continue
        if hasattr(m, "correct"):
            xy[rows] = m.correct(obs.xy[rows], io)
        else:
            xy[rows] = cc * m.image_to_ray(obs.xy[rows], io)
        c[rows] = cc
    return xy, c
