"""Parameter sharing of a ``[cameras.NAME]`` section: which interior
parameters are one value per station, equal to another parameter of the
camera, or one value for several cameras (docs/project-files.md,
"Parameter sharing").

Three keys, beside the parameters::

    per_station = ["x0", "y0"]        # one principal point per station (image-variant)
    tie = { fy = "fx" }               # fy is fx (one focal length, aspect fixed at 1)
    shared = { c = "lens" }           # c is one value for every camera naming group "lens"

Every mistake is one :class:`~photogram.errors.InputError` with the line
and a hint. The engine side is :mod:`photogram.adjust.interior_map`.
"""

from __future__ import annotations

from photogram.project.model import Camera, Parameter
from photogram.project.text_input import suggest
from photogram.project.toml_source import Section
from photogram.project.toml_writer import Inline

__all__ = ["SHARING_KEYS", "read_sharing", "apply_sharing", "check_groups", "sharing_to_toml"]

SHARING_KEYS = ("per_station", "tie", "shared")


def _known(sec: Section, key: str, p: str, names, model: str) -> None:
    if p not in names:
        raise sec.error(key, f"unknown parameter '{p}' in {key} of {sec.label} "
                             f"(model {model})",
                        hint=suggest(p, names, noun="parameters"))


def _table(sec: Section, key: str, example: str) -> dict[str, str]:
    """An inline table of parameter -> text (``tie``, ``shared``)."""
    if key not in sec.data:
        return {}
    value = sec.data[key]
    if not isinstance(value, dict):
        raise sec.error(key, f"{key} of {sec.label} must be an inline table",
                        hint=f"e.g. {key} = {example}")
    sub = sec.table(key)
    return {p: sub.ident(p) for p in sub.data}


def read_sharing(sec: Section, model: str, names, dims) -> tuple:
    """The sharing keys of a camera section, checked against the model.

    Parameters
    ----------
    sec : Section
        ``[cameras.NAME]``.
    model : str
    names : sequence of str
        The model's parameter names.
    dims : sequence of int or None
        Power of the image unit of each parameter (a tie needs equal powers).

    Returns
    -------
    per_station : tuple of str
    ties : dict of str to str
        Parameter -> the parameter it equals.
    shared : dict of str to str
        Parameter -> group name.
    """
    per_station = tuple(sec.ids("per_station", []))
    ties = _table(sec, "tie", '{ fy = "fx" }')
    shared = _table(sec, "shared", '{ c = "lens" }')
    for p in per_station:
        _known(sec, "per_station", p, names, model)
    if len(set(per_station)) != len(per_station):
        raise sec.error("per_station", f"per_station of {sec.label} names a parameter twice",
                        hint="name each parameter once")
    dim = dict(zip(names, dims)) if dims is not None else {}
    for p, q in ties.items():
        _known(sec, "tie", p, names, model)
        _known(sec, "tie", q, names, model)
        if p == q:
            raise sec.error("tie", f"{p} is tied to itself in {sec.label}",
                            hint=f'tie a parameter to another one, e.g. tie = {{ fy = "fx" }}')
        if q in ties:
            raise sec.error("tie", f"{p} is tied to {q}, which is itself tied to {ties[q]}, "
                                   f"in {sec.label}",
                            hint=f'tie both to the same parameter: {p} = "{ties[q]}"')
        if dim.get(p) != dim.get(q):
            raise sec.error("tie", f"{p} and {q} of {sec.label} have different units "
                                   f"(image unit to the power {dim.get(p)} and {dim.get(q)})",
                            hint="tie only parameters that mean the same quantity "
                                 "(e.g. fy to fx)")
        for other, what in ((per_station, "per_station"), (shared, "shared")):
            if p in other:
                raise sec.error("tie", f"{p} of {sec.label} is tied to {q} and also in {what}",
                                hint=f"a tied parameter follows {q}: give {what} for {q}")
    for p, group in shared.items():
        _known(sec, "shared", p, names, model)
        if p in per_station:
            raise sec.error("shared", f"{p} of {sec.label} is both per_station and shared "
                                      f"(group {group})",
                            hint="a parameter is one value per station or one value for "
                                 "several cameras, not both")
    groups = list(shared.values())
    for group in groups:
        if groups.count(group) > 1:
            twice = [p for p, g in shared.items() if g == group]
            raise sec.error("shared", f"group '{group}' names {' and '.join(twice)} of "
                                      f"{sec.label}",
                            hint="one parameter per group and camera; tie parameters of "
                                 "one camera with tie = { ... }")
    return per_station, ties, shared


def _same(a: Parameter, b: Parameter) -> bool:
    return a.value == b.value and a.free == b.free and a.sigma == b.sigma


def apply_sharing(sec: Section, camera: Camera, given) -> Camera:
    """Check the sharing of ``camera`` against its parameter states and give
    each tied parameter the value, state and prior of the one it equals.

    ``given`` are the parameter keys written in the section: a tied
    parameter may be written only with the same value and state as its
    target (it is then redundant, not contradictory).
    """
    params = camera.parameters
    for p in camera.per_station:
        if not params[p].free:
            raise sec.error("per_station", f"{p} of {sec.label} is per station but fixed",
                            hint=f"give {p} = {{ value = ..., free = true }} (one value per "
                                 f"station is estimated), or remove it from per_station")
    for p, q in camera.ties.items():
        if p in given and not _same(params[p], params[q]):
            raise sec.error(p, f"{p} of {sec.label} is tied to {q} but given "
                               f"differently ({p} = {params[p].value!r}, {q} = "
                               f"{params[q].value!r})",
                            hint=f"remove {p}: it takes the value and state of {q}")
        t = params[q]
        params[p] = Parameter(t.value, t.free, t.sigma, t.sigma_estimated)
    return camera


def check_groups(sec: Section, cameras: dict[str, Camera]) -> None:
    """Cameras that name the same group share one parameter: it must have
    the same name and unit in their models, and the same value, state and
    prior in their sections."""
    first: dict[str, tuple[str, str]] = {}
    for name, cam in cameras.items():
        for p, group in cam.shared.items():
            if group not in first:
                first[group] = (name, p)
                continue
            other, q = first[group]
            ref = cameras[other]
            here = sec.table(name)
            if p != q:
                raise here.error("shared", f"group '{group}' ties {q} of camera {other} to {p} "
                                           f"of camera {name}",
                                 hint="a group holds the same parameter of every camera "
                                      "(cameras of different models share a parameter only "
                                      "where its name is the same)")
            if not _same(cam.parameters[p], ref.parameters[q]):
                a, b = ref.parameters[q], cam.parameters[p]
                raise here.error(p, f"{p} of camera {name} (value {b.value!r}, free {b.free}) "
                                    f"differs from {q} of camera {other} (value {a.value!r}, "
                                    f"free {a.free}) in group '{group}'",
                                 hint="give the parameters of one group the same value, "
                                      "free and sigma")
            if _dims(ref, q) != _dims(cam, p):
                raise here.error("shared", f"{p} has other units in model {cam.model} than "
                                           f"in {ref.model} (group '{group}')",
                                 hint="share parameters only between models where they mean "
                                      "the same quantity")


def _dims(camera: Camera, p: str):
    """Power of the image length unit of parameter ``p`` (None: unknown),
    from the camera model's registry (photogram.geometry; imported here so
    that camera_schema, which imports this module, is not imported back)."""
    from photogram.geometry import CAMERA_MODELS
    model = CAMERA_MODELS.get(camera.model)
    dims = getattr(model, "parameter_dims", None)
    return None if dims is None else dict(zip(camera.parameters, dims)).get(p)


def sharing_to_toml(camera: Camera, table: dict) -> dict:
    """Add the sharing keys of ``camera`` to its TOML table (nothing when it
    shares nothing, so that the files of other cameras stay as before)."""
    if camera.per_station:
        table["per_station"] = list(camera.per_station)
    if camera.ties:
        table["tie"] = Inline(camera.ties)
    if camera.shared:
        table["shared"] = Inline(camera.shared)
    return table
