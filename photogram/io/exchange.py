"""What the converters share: OpenCV-style views, project folders, results.

Every foreign camera format of the computer-vision world (Pose2Sim/anipose,
OpenCV FileStorage, COLMAP, BAL) describes a camera station as intrinsics
``K``, distortion coefficients and an OpenCV pose ``x_cv = R_cv X + t_cv``
(camera looking along +z, y down). :class:`View` holds exactly that; the
conversion to photogram's photogrammetric pose is
(docs/camera-models.md, section 1)::

    R = diag(1,-1,-1) R_cv        X0 = -R_cv^T t_cv

and a camera of model ``opencv`` (fx fy cx cy k1 k2 p1 p2 k3) is OpenCV's
own model, so intrinsics convert without loss. A ``brown`` camera is fitted
(:func:`photogram.geometry.fit_distortion`) on export and the misfit is
reported.

Import side: :func:`build_project` and :func:`save_project` (a new project
folder; existing files are never replaced; every file written atomically),
kept in :mod:`photogram.io.project_folder` and re-exported here.
Export side: :func:`load_source` reads a results folder (or a .prj) back into
a :class:`~photogram.project.model.Project` with the a-posteriori sigmas, and
:func:`views_of` turns its stations into :class:`View` objects.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from photogram.errors import InputError
from photogram.io.project_folder import (build_project, check_new_file,  # noqa: F401
                                         save_calibration, save_project, write_new_bytes,
                                         write_new_text)
from photogram.project.model import Camera, Parameter

__all__ = ["View", "LineText", "opencv_camera", "fisheye_camera", "opencv_distortion_vector",
           "cv_to_station", "station_to_cv", "build_project", "save_project", "save_calibration",
           "opencv_intrinsics", "write_new_text", "write_new_bytes", "check_new_file"]

log = logging.getLogger("photogram")

OPENCV_NAMES = ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3")
FLIP = np.diag([1.0, -1.0, -1.0])


@dataclass
class View:
    """One camera station in OpenCV terms.

    ``K`` (3, 3), ``dist`` OpenCV's coefficient vector (k1, k2, p1, p2[, k3]),
    ``R_cv``/``t_cv`` the world-to-camera pose of the OpenCV camera frame;
    ``image_size`` (width, height) in px or None.
    """

    name: str
    camera: str
    K: np.ndarray
    dist: np.ndarray
    R_cv: np.ndarray
    t_cv: np.ndarray
    image_size: tuple[int, int] | None = None
    extra: dict = field(default_factory=dict)

    def project(self, X) -> np.ndarray:
        """Pixel coordinates of world points (n, 3) by cv2.projectPoints."""
        import cv2
        from photogram.geometry import matrix_to_rodrigues
        X = np.asarray(X, dtype=float).reshape(-1, 1, 3)
        xy, _ = cv2.projectPoints(X, matrix_to_rodrigues(self.R_cv), self.t_cv.reshape(3, 1),
                                  self.K, self.dist)
        return xy.reshape(-1, 2)


class LineText:
    """The lines of a text file with 1-based numbers, for readers that must
    name the line of every error."""

    def __init__(self, path, what: str, fallback: str | None = None):
        """``fallback``: an encoding for files that are not UTF-8 (e.g.
        ``"latin-1"`` for PhotoModeler's exports); ``self.encoding`` says
        which one was used."""
        self.path = Path(path)
        self.what = what
        self.encoding = "utf-8"
        try:
            data = self.path.read_bytes()
        except OSError as exc:
            raise InputError(f"cannot read {what}: {exc.strerror or exc}", file=self.path) \
                from None
        try:
            text = data.decode("utf-8-sig")
        except UnicodeDecodeError as exc:
            if fallback:
                self.encoding = fallback
                self.lines = data.decode(fallback).splitlines()
                return
            line = data[:exc.start].count(b"\n") + 1
            raise InputError(f"{what} is not UTF-8 text: byte 0x{data[exc.start]:02X} cannot be "
                             f"decoded", file=self.path, line=line,
                             hint="save it as UTF-8 (or plain ASCII)") from None
        self.lines = text.splitlines()

    def error(self, line: int | None, what: str, hint: str | None = None) -> InputError:
        return InputError(what, file=self.path, line=line, hint=hint)

    def numbers(self, line: int, fields, count: int | None = None, what: str = "values",
                minimum: int | None = None, allow_nan: bool = False) -> list[float]:
        """Parse ``fields`` (strings) as floats; wrong count or text is an error."""
        if count is not None and len(fields) != count:
            raise self.error(line, f"expected {count} {what}, found {len(fields)}",
                             hint="the file is truncated or not in the expected layout")
        if minimum is not None and len(fields) < minimum:
            raise self.error(line, f"expected at least {minimum} {what}, found {len(fields)}",
                             hint="the file is truncated or not in the expected layout")
        out = []
        for f in fields:
            try:
                v = float(f)
            except ValueError:
                raise self.error(line, f"{f!r} is not a number ({what})") from None
            if not np.isfinite(v) and not (allow_nan and np.isnan(v)):
                raise self.error(line, f"{f!r} is not a finite number ({what})")
            out.append(v)
        return out


# --------------------------------------------------------------------------
# cameras and poses
# --------------------------------------------------------------------------

def opencv_camera(name: str, K, dist, image_size=None, *, source: str | None = None,
                  file=None, line=None, free: bool = False) -> Camera:
    """A camera of model ``opencv`` from a camera matrix and OpenCV's
    distortion vector, or ``opencv_full`` when the vector has non-zero
    rational, thin-prism or tilt terms (k4 ... tauY; same order, exact).

    ``dist`` may have 0, 4, 5, 8, 12 or 14 coefficients. A skewed ``K``
    (``K[0, 1] != 0``) is refused.
    """
    K = np.asarray(K, dtype=float)
    if K.shape != (3, 3):
        raise InputError(f"camera {name}: the camera matrix must be 3 x 3, got {K.shape}",
                         file=file, line=line)
    if not np.all(np.isfinite(K)):
        raise InputError(f"camera {name}: the camera matrix holds NaN or infinity",
                         file=file, line=line)
    if abs(K[0, 1]) > 1e-12 * abs(K[0, 0]) or np.any(K[1:, 0] != 0) or K[2, 1] != 0 \
            or K[2, 2] != 1:
        raise InputError(f"camera {name}: the camera matrix is not [[fx, 0, cx], [0, fy, cy], "
                         f"[0, 0, 1]] (skew or scaling)", file=file, line=line,
                         hint="photogram's opencv model has no skew; normalise K[2, 2] to 1")
    d = np.zeros(5)
    dist = np.asarray(dist if dist is not None else [], dtype=float).ravel()
    if dist.size not in (0, 4, 5, 8, 12, 14):
        raise InputError(f"camera {name}: {dist.size} distortion coefficients; OpenCV uses "
                         f"4, 5, 8, 12 or 14", file=file, line=line)
    model, names = "opencv", OPENCV_NAMES
    if dist.size > 5 and np.any(dist[5:] != 0):
        from photogram.geometry import camera_model
        model, names = "opencv_full", camera_model("opencv_full").parameter_names
        d = np.zeros(14)
    d[:min(d.size, dist.size)] = dist[:d.size]
    values = [K[0, 0], K[1, 1], K[0, 2], K[1, 2], *d]
    size = None if image_size is None else (int(round(image_size[0])), int(round(image_size[1])))
    params = {n: Parameter(value=float(v), free=free) for n, v in zip(names, values)}
    return Camera(name=name, model=model, parameters=params, image_size=size, source=source)


def fisheye_camera(name: str, K, dist, image_size=None, *, source: str | None = None,
                   file=None, line=None, free: bool = False) -> Camera:
    """A camera of model ``opencv_fisheye`` from a camera matrix and
    OpenCV's fisheye distortion vector ``[k1, k2, k3, k4]`` (``K`` checked
    as :func:`opencv_camera` does)."""
    dist = np.asarray(dist if dist is not None else np.zeros(4), dtype=float).ravel()
    if dist.size != 4 or not np.all(np.isfinite(dist)):
        raise InputError(f"camera {name}: a fisheye camera has 4 distortion coefficients "
                         f"[k1, k2, k3, k4], got {dist.size}", file=file, line=line)
    base = opencv_camera(name, K, None, image_size, source=source, file=file, line=line)
    values = [base.parameters[n].value for n in OPENCV_NAMES[:4]] + list(dist)
    from photogram.geometry import camera_model
    names = camera_model("opencv_fisheye").parameter_names
    params = {n: Parameter(value=float(v), free=free) for n, v in zip(names, values)}
    return Camera(name=name, model="opencv_fisheye", parameters=params,
                  image_size=base.image_size, source=source)


def cv_to_station(R_cv, t_cv) -> tuple[np.ndarray, np.ndarray]:
    """OpenCV pose -> (omega-phi-kappa radians of the world-to-camera R, X0)."""
    from photogram.geometry import matrix_to_opk, photogrammetric_pose
    R, X0 = photogrammetric_pose(np.asarray(R_cv, float), np.asarray(t_cv, float).ravel())
    return matrix_to_opk(R), np.asarray(X0, float).ravel()


def station_to_cv(angles, X0) -> tuple[np.ndarray, np.ndarray]:
    """(angles, X0) of a station -> OpenCV (R_cv, t_cv)."""
    from photogram.geometry import opencv_pose, opk_to_matrix
    R_cv, t_cv = opencv_pose(opk_to_matrix(np.asarray(angles, float)), np.asarray(X0, float))
    return np.asarray(R_cv, float), np.asarray(t_cv, float).ravel()


def opencv_intrinsics(camera: Camera, image_unit: str = "px",
                      tolerance: float = 0.01) -> tuple[np.ndarray, np.ndarray, float]:
    """``(K, dist, misfit_px)`` of a camera in OpenCV terms.

    ``opencv`` cameras convert exactly (misfit 0, dist of 5), ``opencv_full``
    too (dist of 5, 8, 12 or 14: the shortest that holds its non-zero
    terms). ``brown`` cameras are converted by the exact pinhole part plus a least-squares fit of k1, k2,
    p1, p2, k3 over the format (:func:`photogram.geometry.fit_distortion`);
    ``aicon`` cameras exactly where possible, else by a fit of all nine;
    the RMS misfit in px is returned and logged when above ``tolerance``.
    Cameras in mm are converted to px with their pixel size.
    """
    from photogram.geometry import (brown_to_opencv, camera_model, fit_distortion,
                                    rescale_parameters)
    values = camera.values()
    if image_unit == "mm":
        if camera.pixel_size is None or camera.pixel_size[0] != camera.pixel_size[1]:
            raise InputError(f"camera {camera.name} is in mm and needs a square pixel_size "
                             f"to be exported in pixels")
        values = rescale_parameters(camera.model, values, 1.0 / camera.pixel_size[0])
    misfit = 0.0
    if camera.model == "opencv_full":
        K = np.array([[values[0], 0.0, values[2]], [0.0, values[1], values[3]], [0.0, 0.0, 1.0]])
        return K, opencv_distortion_vector(values[4:]), 0.0
    if camera.model == "opencv":
        p = values
    elif camera.model == "brown":
        pin = brown_to_opencv(values, strict=False)
        if np.any(values[3:8] != 0) or values[9] != 0:
            if camera.image_size is None:
                raise InputError(f"camera {camera.name} (brown) needs image_size to fit "
                                 f"OpenCV's distortion over the format")
            p, misfit = fit_distortion("brown", values, "opencv", camera.image_size,
                                       target_params=pin)
            p = np.asarray(p, float)
        else:
            p = pin
        if misfit > tolerance:
            log.warning("camera %s: brown -> opencv distortion fit leaves %.3g px RMS",
                        camera.name, misfit)
    elif camera.model == "aicon":
        p, misfit = _aicon_to_opencv(camera, values)
        if misfit > tolerance:
            log.warning("camera %s: aicon -> opencv fit leaves %.3g px RMS", camera.name,
                        misfit)
    elif camera.model == "bal":
        # xy = f (1 + k1 r2 + k2 r2^2) t about the image centre: OpenCV with cx = cy = 0
        p = np.array([values[0], values[0], 0.0, 0.0, values[1], values[2], 0.0, 0.0, 0.0])
    else:
        camera_model(camera.model)
        raise InputError(f"camera {camera.name}: model {camera.model} cannot be exported")
    K = np.array([[p[0], 0.0, p[2]], [0.0, p[1], p[3]], [0.0, 0.0, 1.0]])
    return K, np.array(p[4:9], float), float(misfit)


def _aicon_to_opencv(camera: Camera, values) -> tuple[np.ndarray, float]:
    """OpenCV parameters (px) of an aicon camera and the RMS misfit: exact
    where the conversion is (docs/camera-models.md, section 5.3), else a
    least-squares fit of all nine OpenCV parameters over the format."""
    from photogram.geometry import aicon_to_opencv, fit_distortion
    try:
        return aicon_to_opencv(values), 0.0
    except InputError:
        pass
    if camera.image_size is None:
        raise InputError(f"camera {camera.name} (aicon) needs image_size to fit OpenCV's "
                         f"distortion over the format")
    p, misfit = fit_distortion("aicon", values, "opencv", camera.image_size,
                               target_params=aicon_to_opencv(values, strict=False),
                               free=("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3"))
    return np.asarray(p, float), misfit


def opencv_distortion_vector(d) -> np.ndarray:
    """OpenCV's distortion vector (k1 k2 p1 p2 k3 k4 k5 k6 s1 s2 s3 s4 tauX
    tauY) cut to the shortest length OpenCV takes (5, 8, 12 or 14) that
    keeps every non-zero term."""
    d = np.asarray(d, float).ravel()
    nonzero = np.flatnonzero(d)
    last = int(nonzero[-1]) + 1 if nonzero.size else 0
    n = next(k for k in (5, 8, 12, 14) if k >= min(last, 14))
    out = np.zeros(n)
    out[:min(n, d.size)] = d[:n]
    return out
