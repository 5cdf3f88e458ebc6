"""The camera part of the project schema: model parameter names, the
omega-phi-kappa rotation convention, and reading/writing ``[cameras.NAME]``.

This module is the single source of camera-model parameter names for the
project readers and writers. Names and unit dimensions come from
``photogram.geometry.CAMERA_MODELS`` when that registry exists, else from
:data:`FALLBACK_PARAMETERS` / :data:`FALLBACK_DIMS` (kept identical). The
rotation functions are those of ``photogram.geometry.rotations`` (fallback:
the same formulas, ``R = M_kappa M_phi M_omega``, world-to-camera).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from photogram.project.model import IMAGE_UNITS, Camera, Parameter
from photogram.project.reader_sharing import (SHARING_KEYS, apply_sharing, read_sharing,
                                              sharing_to_toml)
from photogram.project.text_input import DOCS, suggest
from photogram.project.toml_source import Section, TomlSource
from photogram.project.toml_writer import Inline

__all__ = ["FALLBACK_PARAMETERS", "FALLBACK_DIMS", "REQUIRED_PARAMETERS", "CONSTANT_PARAMETERS",
           "constant_parameters", "camera_models",
           "parameter_names", "parameter_dims", "opk_to_matrix", "matrix_to_opk", "invert_opk",
           "read_camera", "free_parameters", "load_cameras_file", "camera_to_toml"]

FALLBACK_PARAMETERS: dict[str, tuple[str, ...]] = {
    "brown": ("c", "x0", "y0", "K1", "K2", "K3", "P1", "P2", "B1", "B2"),
    "opencv": ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3"),
    "opencv_fisheye": ("fx", "fy", "cx", "cy", "k1", "k2", "k3", "k4"),
    "aicon": ("c", "xh", "yh", "A1", "A2", "A3", "B1", "B2", "C1", "C2", "r0"),
    # DBAT's lens models 4, 5 and -1 (photogram.geometry.dbat_models)
    "brown_affine_after": ("c", "x0", "y0", "K1", "K2", "K3", "P1", "P2", "B1", "B2"),
    "brown_aspect_first": ("c", "x0", "y0", "K1", "K2", "K3", "P1", "P2", "B1", "B2"),
    "brown_forward": ("c", "x0", "y0", "K1", "K2", "K3", "P1", "P2"),
    "opencv_full": ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6",
                    "s1", "s2", "s3", "s4", "tauX", "tauY"),
}
#: Power of the image length unit in each parameter (for px <-> mm).
FALLBACK_DIMS: dict[str, tuple[int, ...]] = {
    "brown": (1, 1, 1, -2, -4, -6, -1, -1, 0, 0),
    "opencv": (1, 1, 1, 1, 0, 0, 0, 0, 0),
    "opencv_fisheye": (1, 1, 1, 1, 0, 0, 0, 0),
    "aicon": (1, 1, 1, -2, -4, -6, -1, -1, 0, 0, 1),
    "brown_affine_after": (1, 1, 1, -2, -4, -6, -1, -1, 0, 0),
    "brown_aspect_first": (1, 1, 1, -2, -4, -6, -1, -1, 0, 0),
    "brown_forward": (1, 1, 1, -2, -4, -6, -1, -1),
    "opencv_full": (1, 1, 1, 1) + (0,) * 14,
}
#: Parameters a camera section must give. The principal point defaults to
#: the format centre (as ``default_parameters`` of photogram.geometry), all
#: other parameters to 0; defaults are fixed.
REQUIRED_PARAMETERS: dict[str, tuple[str, ...]] = {
    "brown": ("c",),
    "opencv": ("fx", "fy"),
    "opencv_fisheye": ("fx", "fy"),
    "aicon": ("c",),
    "brown_affine_after": ("c",),
    "brown_aspect_first": ("c",),
    "brown_forward": ("c",),
    "opencv_full": ("fx", "fy"),
}
PRINCIPAL_POINT: dict[str, tuple[str, str]] = {"brown": ("x0", "y0"), "opencv": ("cx", "cy"),
                                               "opencv_fisheye": ("cx", "cy"),
                                               "opencv_full": ("cx", "cy"),
                                               "aicon": ("xh", "yh")}
PRINCIPAL_POINT.update(dict.fromkeys(("brown_affine_after", "brown_aspect_first",
                                      "brown_forward"), ("x0", "y0")))
#: Parameters that are constants of the camera (never free), which must be
#: non-negative: the aicon model's balancing radius (the models'
#: ``constant_parameters`` when the registry exists).
CONSTANT_PARAMETERS: dict[str, tuple[str, ...]] = {"aicon": ("r0",)}
CAMERA_KEYS = ("model", "image_size", "pixel_size")
FROM_KEYS = ("from", "name", "free", "weighted")
PARAMETER_KEYS = ("value", "free", "sigma", "sigma_estimated")


# --------------------------------------------------------------------------
# registry
# --------------------------------------------------------------------------

def _registry() -> dict[str, tuple[tuple[str, ...], tuple[int, ...] | None]]:
    """Model name -> (parameter names, unit dimensions)."""
    fallback = {m: (names, FALLBACK_DIMS.get(m)) for m, names in FALLBACK_PARAMETERS.items()}
    try:
        from photogram import geometry
    except ImportError:
        return fallback
    models = getattr(geometry, "CAMERA_MODELS", None)
    if not models:
        return fallback
    return {name: (tuple(m.parameter_names), getattr(m, "parameter_dims", None))
            for name, m in models.items()}


def camera_models() -> tuple[str, ...]:
    """Names of the known camera models."""
    return tuple(_registry())


def parameter_names(model: str) -> tuple[str, ...] | None:
    """Parameter names of ``model`` in model order (None if unknown)."""
    entry = _registry().get(model)
    return None if entry is None else entry[0]


def parameter_dims(model: str) -> tuple[int, ...] | None:
    """Power of the image length unit in each parameter of ``model``."""
    entry = _registry().get(model)
    return None if entry is None or entry[1] is None else tuple(entry[1])


def constant_parameters(model: str) -> tuple[str, ...]:
    """Parameters of ``model`` that are constants of the camera (never
    free; e.g. the aicon model's balancing radius r0)."""
    try:
        from photogram import geometry
        return tuple(getattr(geometry.CAMERA_MODELS[model], "constant_parameters", ()))
    except (ImportError, AttributeError, KeyError):
        return CONSTANT_PARAMETERS.get(model, ())


# --------------------------------------------------------------------------
# rotations
# --------------------------------------------------------------------------

def _fallback_matrix(angles: np.ndarray) -> np.ndarray:
    """R = M_kappa M_phi M_omega (world-to-camera) for angles (..., 3)."""
    o, p, k = np.moveaxis(np.asarray(angles, dtype=float), -1, 0)
    so, co, sp, cp, sk, ck = np.sin(o), np.cos(o), np.sin(p), np.cos(p), np.sin(k), np.cos(k)
    rows = [[cp * ck, co * sk + so * sp * ck, so * sk - co * sp * ck],
            [-cp * sk, co * ck - so * sp * sk, so * ck + co * sp * sk],
            [sp, -so * cp, co * cp]]
    return np.stack([np.stack(r, axis=-1) for r in rows], axis=-2)


def _fallback_angles(R: np.ndarray) -> np.ndarray:
    R = np.asarray(R, dtype=float)
    omega = np.arctan2(-R[..., 2, 1], R[..., 2, 2])
    phi = np.arctan2(R[..., 2, 0], np.hypot(R[..., 0, 0], R[..., 1, 0]))
    kappa = np.arctan2(-R[..., 1, 0], R[..., 0, 0])
    return np.stack([omega, phi, kappa], axis=-1)


def _rotations():
    try:
        from photogram.geometry.rotations import matrix_to_opk, opk_to_matrix
    except ImportError:
        return _fallback_matrix, _fallback_angles
    return opk_to_matrix, matrix_to_opk


def opk_to_matrix(angles) -> np.ndarray:
    """World-to-camera matrices of omega-phi-kappa angles (..., 3), radians."""
    return np.asarray(_rotations()[0](np.asarray(angles, dtype=float)), dtype=float)


def matrix_to_opk(R) -> np.ndarray:
    """Omega-phi-kappa angles (radians) of rotation matrices (..., 3, 3)."""
    return np.asarray(_rotations()[1](np.asarray(R, dtype=float)), dtype=float)


def invert_opk(angles) -> np.ndarray:
    """Angles of the inverse rotation (world-to-camera <-> camera-to-world).

    Rows with a NaN stay NaN.
    """
    angles = np.atleast_2d(np.asarray(angles, dtype=float))
    out = np.full_like(angles, np.nan)
    ok = np.all(np.isfinite(angles), axis=1)
    if np.any(ok):
        R = opk_to_matrix(angles[ok])
        out[ok] = matrix_to_opk(np.swapaxes(R, -1, -2))
    return out


# --------------------------------------------------------------------------
# reading [cameras.NAME]
# --------------------------------------------------------------------------

def _parameter(sec: Section, key: str) -> Parameter:
    value = sec.data[key]
    if isinstance(value, dict):
        sub = Section(sec.source, sec.keypath + (key,), value, f"{key} of {sec.label}")
        sub.check_keys(PARAMETER_KEYS, required=("value",))
        par = Parameter(sub.number("value"), free=sub.boolean("free", False),
                        sigma=sub.number("sigma", None, positive=True),
                        sigma_estimated=sub.number("sigma_estimated", None, nonnegative=True))
        if par.sigma is not None and not par.free:
            raise sub.error("sigma", f"{key} of {sec.label} has a sigma but is fixed",
                            hint="set free = true for a weighted parameter, or remove sigma")
        return par
    return Parameter(sec.number(key))


def _centre(sec: Section, name: str, model: str, image_unit: str, size, pixel) -> dict:
    """Default principal point: the format centre in the image unit."""
    keys = PRINCIPAL_POINT.get(model, ())
    if all(k in sec.data for k in keys):
        return {}
    if size is None or image_unit == "mm" and pixel is None:
        raise sec.error(None, f"camera {name} has no {' and '.join(keys)}",
                        hint="give them, or image_size" +
                        (" and pixel_size" if image_unit == "mm" else "") +
                        " to put the principal point at the format centre")
    scale = (1.0, 1.0) if image_unit == "px" else pixel
    return {k: Parameter(size[i] * scale[i] / 2.0) for i, k in enumerate(keys)}


def _inline_camera(sec: Section, name: str, image_unit: str) -> Camera:
    model = sec.string("model", "brown")
    names = parameter_names(model)
    if names is None:
        raise sec.error("model", f"unknown camera model '{model}' in {sec.label}",
                        hint=suggest(model, camera_models(), noun="known models"))
    for key in sec.data:
        if key not in CAMERA_KEYS + SHARING_KEYS and key not in names:
            raise sec.error(key, f"unknown parameter '{key}' for camera model {model} "
                                 f"in {sec.label}",
                            hint=suggest(key, list(names) + list(CAMERA_KEYS)))
    per_station, ties, shared = read_sharing(sec, model, names, parameter_dims(model))
    for key in REQUIRED_PARAMETERS.get(model, ()):
        if key not in sec.data and key not in ties:
            raise sec.error(None, f"camera {name} has no {key}",
                            hint=f"add {key} = ...; it is required for model {model}")
    size = sec.numbers("image_size", 2, None, integer=True)
    pixel = sec.numbers("pixel_size", 2, None)
    defaults = _centre(sec, name, model, image_unit, size, pixel)
    params = {p: _parameter(sec, p) if p in sec.data else defaults.get(p, Parameter(0.0))
              for p in names}
    _check_constants(sec, model, params)
    camera = Camera(name=name, model=model, parameters=params, image_size=size,
                    pixel_size=pixel, per_station=per_station, ties=ties, shared=shared)
    return apply_sharing(sec, camera, sec.data) if camera.shares() else camera


def _check_constants(sec: Section, model: str, params: dict, free=()) -> None:
    """Constants of the camera (:data:`CONSTANT_PARAMETERS`) are fixed and
    non-negative."""
    for key in constant_parameters(model):
        par = params[key]
        if par.free or key in free:
            raise sec.error("free" if key in free else key,
                            f"{key} of {sec.label} is a constant of the {model} model and "
                            "cannot be free",
                            hint=f"give {key} as a plain value (0 = unbalanced); to change "
                                 "it, convert the camera with photogram.geometry.change_r0")
        if not par.value >= 0:
            raise sec.error(key, f"{key} of {sec.label} must be >= 0, got {par.value:g}",
                            hint="the balancing radius is a distance from the principal point")


def read_camera(sec: Section, name: str, *, image_unit: str, folder: Path,
                allow_from: bool = True) -> Camera:
    """Read one ``[cameras.NAME]`` section.

    Parameters
    ----------
    sec : Section
        The section.
    name : str
        The camera name.
    image_unit : str
        The project's image unit (a camera taken ``from`` a file must match).
    folder : Path
        Folder that ``from`` paths are relative to.
    allow_from : bool
        Whether ``from = ...`` is allowed (not inside a cameras file).

    Returns
    -------
    Camera
    """
    if "from" in sec:
        if not allow_from:
            raise sec.error("from", f"{sec.label} in a cameras file cannot use from",
                            hint="a cameras file must hold the values itself")
        return _camera_from_file(sec, name, image_unit, folder)
    return _inline_camera(sec, name, image_unit)


def _camera_from_file(sec: Section, name: str, image_unit: str, folder: Path) -> Camera:
    sec.check_keys(FROM_KEYS)
    ref = sec.string("from")
    path = folder / ref
    if not path.is_file():
        raise sec.error("from", f"cameras file '{ref}' of {sec.label} not found ({path})",
                        hint="run the earlier project first, or fix the path; "
                             "it is relative to the .prj folder")
    unit, cameras = load_cameras_file(path)
    wanted = sec.ident("name", name)
    if wanted not in cameras:
        if "name" in sec or len(cameras) != 1:
            raise sec.error("name" if "name" in sec else "from",
                            f"camera {wanted} is not in {ref}",
                            hint=suggest(wanted, cameras, noun="cameras there") +
                            "; choose one with name = \"...\"")
        wanted = next(iter(cameras))
    camera = cameras[wanted]
    if unit != image_unit:
        camera = _convert_unit(sec, camera, unit, image_unit, ref)
    return _override_free(sec, camera, name, ref)


def _convert_unit(sec: Section, camera: Camera, old: str, new: str, ref: str) -> Camera:
    """The camera with its parameters in the image unit ``new``."""
    dims = parameter_dims(camera.model)
    pixel = camera.pixel_size
    if dims is None or pixel is None or pixel[0] != pixel[1]:
        raise sec.error("from", f"camera {camera.name} in {ref} is in {old}, this project "
                                f"uses image_unit = {new}",
                        hint="converting needs a square pixel_size in that file; or use "
                             "the same image_unit in both projects")
    factor = pixel[0] if new == "mm" else 1.0 / pixel[0]

    def scale(v, d):
        return None if v is None else v * factor ** d
    params = {p: Parameter(scale(par.value, d), par.free, scale(par.sigma, d),
                           scale(par.sigma_estimated, d))
              for (p, par), d in zip(camera.parameters.items(), dims)}
    return Camera(name=camera.name, model=camera.model, parameters=params,
                  image_size=camera.image_size, pixel_size=pixel, source=camera.source)


def free_parameters(sec: Section, camera: Camera) -> list[str]:
    """The parameters ``free = [...]`` of ``sec`` names, checked against
    ``camera``'s parameters."""
    free = sec.ids("free", [])
    for p in free:
        if p not in camera.parameters:
            raise sec.error("free", f"unknown parameter '{p}' in free of {sec.label}",
                            hint=suggest(p, camera.parameters, noun="parameters"))
    return free


def _override_free(sec: Section, camera: Camera, name: str, ref: str) -> Camera:
    free = free_parameters(sec, camera)
    _check_constants(sec, camera.model, camera.parameters, free)
    weighted = sec.boolean("weighted", False)
    params = {}
    for p, par in camera.parameters.items():
        sigma = None
        if weighted and p in free:
            sigma = par.sigma_estimated
            if not sigma:
                raise sec.error("weighted", f"parameter {p} has no sigma_estimated in {ref}",
                                hint="weighted = true needs estimated sigmas; remove it "
                                     "or leave the parameter out of free")
        params[p] = Parameter(par.value, free=p in free, sigma=sigma,
                              sigma_estimated=par.sigma_estimated)
    return Camera(name=name, model=camera.model, parameters=params,
                  image_size=camera.image_size, pixel_size=camera.pixel_size, source=ref)


def load_cameras_file(path: Path) -> tuple[str, dict[str, Camera]]:
    """Read a cameras file (results/cameras.toml or hand-written).

    It has an optional ``[project]`` section (``image_unit`` matters, the
    other unit keys are informative) and ``[cameras.NAME]`` sections in the
    .prj schema, without ``from``.

    Returns
    -------
    image_unit : str
    cameras : dict of str to Camera
    """
    src = TomlSource.load(path, what="cameras file")
    root = src.root()
    root.check_keys(("project", "cameras"), required=("cameras",), noun="section")
    project = root.table("project", required=False)
    unit = "px"
    if project is not None:
        project.check_keys(("name", "length_unit", "angle_unit", "image_unit", "rotation",
                            "rotation_direction", "software_version"))
        unit = project.string("image_unit", "px", choices=IMAGE_UNITS)
    section = root.table("cameras")
    cameras = {}
    for cam in section.data:
        cameras[cam] = read_camera(section.table(cam), cam, image_unit=unit,
                                   folder=path.parent, allow_from=False)
    if not cameras:
        raise section.error(None, "the cameras file has no cameras",
                            hint=f"add [cameras.NAME] sections; see {DOCS}")
    return unit, cameras


# --------------------------------------------------------------------------
# writing
# --------------------------------------------------------------------------

def _clean(value) -> float | None:
    if value is None:
        return None
    value = float(value)
    return None if math.isnan(value) else value


def camera_to_toml(camera: Camera, sigma_estimated=None) -> dict:
    """The ``[cameras.NAME]`` table of ``camera`` for the TOML writer.

    Parameters
    ----------
    camera : Camera
    sigma_estimated : dict or sequence, optional
        A-posteriori sigmas by parameter name or in model order (NaN: not
        estimated); they replace the camera's own ``sigma_estimated``.
    """
    if sigma_estimated is not None and not isinstance(sigma_estimated, dict):
        sigma_estimated = dict(zip(camera.parameters, np.asarray(sigma_estimated, float)))
    table: dict = {"model": camera.model}
    if camera.image_size is not None:
        table["image_size"] = [int(v) for v in camera.image_size]
    if camera.pixel_size is not None:
        table["pixel_size"] = [float(v) for v in camera.pixel_size]
    for p, par in camera.parameters.items():
        est = _clean(sigma_estimated.get(p) if sigma_estimated is not None
                     else par.sigma_estimated)
        if not par.free and par.sigma is None and est is None:
            table[p] = float(par.value)
        else:
            table[p] = Inline(value=float(par.value), free=bool(par.free),
                              sigma=_clean(par.sigma), sigma_estimated=est)
    return sharing_to_toml(camera, table)
