"""COLMAP's camera models and photogram's: the exact mapping both ways.

Every COLMAP model of this table is one of photogram's forward models with
some parameters tied or zero (COLMAP's ``src/colmap/sensor/models.h``: the
same normalised coordinates ``u = X/Z``, ``v = Y/Z`` and the same distortion
formulas as OpenCV; docs/camera-models.md, section 5.5):

==================  ==  ==============================  ==================
COLMAP              id  parameters                      photogram
==================  ==  ==============================  ==================
SIMPLE_PINHOLE       0  f cx cy                         opencv (fx = fy = f)
PINHOLE              1  fx fy cx cy                     opencv
SIMPLE_RADIAL        2  f cx cy k                       opencv (k1 = k)
RADIAL               3  f cx cy k1 k2                   opencv
OPENCV               4  fx fy cx cy k1 k2 p1 p2         opencv
OPENCV_FISHEYE       5  fx fy cx cy k1 k2 k3 k4         opencv_fisheye
FULL_OPENCV          6  fx fy cx cy k1 k2 p1 p2 k3..k6  opencv, or opencv_full
                                                        when k4..k6 != 0
SIMPLE_RADIAL_FI.    8  f cx cy k                       opencv_fisheye
RADIAL_FISHEYE       9  f cx cy k1 k2                   opencv_fisheye
==================  ==  ==============================  ==================

Export picks the first model of this order (fewest parameters) that holds
the camera exactly (every tie an equality, every missing parameter zero).
COLMAP's principal point is in its pixel frame (centre of the top-left
pixel at (0.5, 0.5)); photogram's, OpenCV's, at (0, 0): ``shift`` is
subtracted from cx, cy on import and added on export.
"""

from __future__ import annotations

import numpy as np

from photogram.errors import InputError

__all__ = ["COLMAP_CAMERAS", "COLMAP_IDS", "n_params", "colmap_to_model", "model_to_colmap",
           "view_intrinsics", "intrinsics_model", "model_camera", "camera_intrinsics"]

_F = ("fx", "fy")
#: COLMAP model -> (model id, photogram family, photogram names of each parameter);
#: a tuple of names is a tie (one COLMAP value for all of them). Export order.
COLMAP_CAMERAS: dict[str, tuple[int, str, tuple]] = {
    "SIMPLE_PINHOLE": (0, "opencv", (_F, "cx", "cy")),
    "PINHOLE": (1, "opencv", ("fx", "fy", "cx", "cy")),
    "SIMPLE_RADIAL": (2, "opencv", (_F, "cx", "cy", "k1")),
    "RADIAL": (3, "opencv", (_F, "cx", "cy", "k1", "k2")),
    "OPENCV": (4, "opencv", ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2")),
    "FULL_OPENCV": (6, "opencv", ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3", "k4",
                                  "k5", "k6")),
    "SIMPLE_RADIAL_FISHEYE": (8, "opencv_fisheye", (_F, "cx", "cy", "k1")),
    "RADIAL_FISHEYE": (9, "opencv_fisheye", (_F, "cx", "cy", "k1", "k2")),
    "OPENCV_FISHEYE": (5, "opencv_fisheye", ("fx", "fy", "cx", "cy", "k1", "k2", "k3", "k4")),
}
COLMAP_IDS = {v[0]: k for k, v in COLMAP_CAMERAS.items()}
_FAMILY = {"opencv": "opencv", "opencv_full": "opencv", "opencv_fisheye": "opencv_fisheye"}


def _names(model: str) -> tuple[str, ...]:
    from photogram.geometry import camera_model
    return camera_model(model).parameter_names


def n_params(colmap: str) -> int:
    """Number of parameters of a COLMAP camera model."""
    return len(COLMAP_CAMERAS[colmap][2])


def colmap_to_model(colmap: str, params, shift: float) -> tuple[str, np.ndarray]:
    """photogram's ``(model, values)`` of a COLMAP camera (values in px,
    OpenCV's pixel frame: cx, cy minus ``shift``). FULL_OPENCV with k4 = k5
    = k6 = 0 is the ``opencv`` model, else ``opencv_full``."""
    _, family, groups = COLMAP_CAMERAS[colmap]
    p = np.asarray(params, float)
    model = family
    if colmap == "FULL_OPENCV" and np.any(p[9:12] != 0):
        model = "opencv_full"
    names = _names(model)
    values = np.zeros(len(names))
    for group, v in zip(groups, p):
        for name in (group if isinstance(group, tuple) else (group,)):
            if name not in names:              # k4..k6 of FULL_OPENCV, zero here
                continue
            values[names.index(name)] = v - shift if name in ("cx", "cy") else v
    return model, values


def _holds(colmap: str, model: str, values) -> np.ndarray | None:
    """COLMAP's parameters of the photogram camera if ``colmap`` holds it
    exactly, else None."""
    _, family, groups = COLMAP_CAMERAS[colmap]
    if _FAMILY.get(model) != family:
        return None
    named = dict(zip(_names(model), np.asarray(values, float)))
    used, out = set(), []
    for group in groups:
        group = group if isinstance(group, tuple) else (group,)
        first = named.get(group[0], 0.0)
        if any(named.get(g, 0.0) != first for g in group):
            return None
        used.update(group)
        out.append(first)
    if any(v != 0 for k, v in named.items() if k not in used):
        return None
    return np.array(out)


def model_to_colmap(model: str, values, shift: float, *, name: str = "",
                    only: str | None = None) -> tuple[str, np.ndarray]:
    """The smallest COLMAP model that holds photogram's camera exactly, and
    its parameters (cx, cy plus ``shift``).

    Raises
    ------
    InputError
        When none does (``opencv_full`` with thin-prism or tilt terms).
    """
    for colmap in ([only] if only else COLMAP_CAMERAS):
        p = _holds(colmap, model, values)
        if p is not None:
            groups = COLMAP_CAMERAS[colmap][2]
            for i, g in enumerate(groups):
                if g in ("cx", "cy"):
                    p[i] += shift
            return colmap, p
    raise InputError(f"camera {name}: no COLMAP camera model holds this {model} camera "
                     f"exactly (thin-prism s1..s4 or tilt tauX, tauY are not zero)",
                     hint="COLMAP has no such model: refit the camera without these terms "
                          "(fix them at 0), or export opencv (FileStorage keeps all 14)")


# --------------------------------------------------------------------------
# View (K, OpenCV distortion vector, fisheye flag) <-> (model, values)
# --------------------------------------------------------------------------

def intrinsics_model(K, dist, fisheye: bool = False) -> tuple[str, np.ndarray]:
    """``(model, values)`` of OpenCV intrinsics: the distortion vector is in
    OpenCV's order (k1 k2 p1 p2 k3 k4 k5 k6 s1 s2 s3 s4 tauX tauY), which is
    the order of ``opencv`` / ``opencv_full`` after fx fy cx cy; fisheye:
    k1..k4 of ``opencv_fisheye``."""
    K = np.asarray(K, float)
    d = np.asarray(dist, float).ravel()
    head = [K[0, 0], K[1, 1], K[0, 2], K[1, 2]]
    if fisheye:
        v = np.zeros(8)
        v[:4], v[4:4 + min(4, d.size)] = head, d[:4]
        return "opencv_fisheye", v
    model = "opencv_full" if d.size > 5 and np.any(d[5:] != 0) else "opencv"
    v = np.zeros(len(_names(model)))
    v[:4] = head
    v[4:4 + min(d.size, v.size - 4)] = d[:v.size - 4]
    return model, v


def view_intrinsics(model: str, values) -> tuple[np.ndarray, np.ndarray, bool]:
    """``(K, dist, fisheye)`` of a camera of model opencv, opencv_full or
    opencv_fisheye (inverse of :func:`intrinsics_model`)."""
    v = np.asarray(values, float)
    K = np.array([[v[0], 0.0, v[2]], [0.0, v[1], v[3]], [0.0, 0.0, 1.0]])
    return K, v[4:].copy(), model == "opencv_fisheye"


def colmap_ties(colmap: str) -> dict[str, str]:
    """The equality ties of a COLMAP camera model as photogram's ``tie``
    (docs/project-files.md, "Parameter sharing"): one focal length f is
    ``fy = fx`` (SIMPLE_PINHOLE, SIMPLE_RADIAL, RADIAL and their fisheyes)."""
    ties = {}
    for group in COLMAP_CAMERAS[colmap][2]:
        if isinstance(group, tuple):
            ties.update({g: group[0] for g in group[1:]})
    return ties


def model_camera(name: str, model: str, values, image_size=None, *, source=None,
                 free: bool = False, ties: dict | None = None):
    """A project camera of ``model`` with ``values`` (px) and the equality
    ``ties`` (e.g. :func:`colmap_ties`)."""
    from photogram.project.model import Camera, Parameter
    size = None if image_size is None else (int(image_size[0]), int(image_size[1]))
    params = {n: Parameter(value=float(v), free=free)
              for n, v in zip(_names(model), np.asarray(values, float))}
    return Camera(name=name, model=model, parameters=params, image_size=size, source=source,
                  ties=dict(ties or {}))


def camera_intrinsics(camera, image_unit: str = "px", tolerance: float = 0.01):
    """``(K, dist, fisheye, misfit_px)`` of a project camera for COLMAP:
    opencv, opencv_full and opencv_fisheye exactly, brown and bal through
    :func:`photogram.io.exchange.opencv_intrinsics` (brown fitted)."""
    from photogram.geometry import rescale_parameters
    from photogram.io.exchange import opencv_intrinsics
    if camera.model not in _FAMILY:
        K, dist, misfit = opencv_intrinsics(camera, image_unit, tolerance)
        return K, dist, False, misfit
    values = camera.values()
    if image_unit == "mm":
        if camera.pixel_size is None or camera.pixel_size[0] != camera.pixel_size[1]:
            raise InputError(f"camera {camera.name} is in mm and needs a square pixel_size "
                             f"to be exported in pixels")
        values = rescale_parameters(camera.model, values, 1.0 / camera.pixel_size[0])
    K, dist, fisheye = view_intrinsics(camera.model, values)
    return K, dist, fisheye, 0.0
