"""The cross-table checks of a whole project (:func:`validate_project`).

Every problem a user can cause becomes one :class:`~photogram.errors.InputError`
naming the file, the line and how to fix it. The observation checks are also
used per file by the reader of DBAT-style projects
(:mod:`photogram.project.reader_dbat`).

The input-checking tools this module used to hold live in
:mod:`photogram.project.text_input` (text files, hints) and
:mod:`photogram.project.toml_source` (TOML with line numbers); they are
re-exported here.
"""

from __future__ import annotations

import numpy as np

from photogram.errors import InputError
from photogram.project.text_input import suggest
from photogram.project.toml_source import TomlSource

# The input-checking tools moved to text_input and toml_source; they stay
# importable from here.
from photogram.project.text_input import DOCS, decode_utf8, read_text  # noqa: F401,E402
from photogram.project.toml_source import MISSING, Section, type_name  # noqa: F401,E402

__all__ = ["read_text", "suggest", "TomlSource", "Section", "validate_project"]


def _records(obs, rows: np.ndarray) -> np.ndarray:
    return obs.record[rows] if len(obs.record) == len(obs) else np.zeros(len(rows), int)


def _line(record) -> int | None:
    return int(record) if record and record > 0 else None


def validate_project(project, source: TomlSource | None = None) -> list[str]:
    """Check a whole project for consistency across its tables.

    Parameters
    ----------
    project : Project
        A project as built by :func:`read_project` (or by hand).
    source : TomlSource, optional
        The .prj, to point at ``[adjustment]`` keys.

    Returns
    -------
    list of str
        Warnings (the project is usable but something looks odd).

    Raises
    ------
    InputError
        Duplicate observations, a tie or check point with a single ray, an
        unknown point in ``inner_constraints``.
    """
    warnings: list[str] = []
    _check_magnitudes(project)
    _check_duplicate_observations(project)
    _check_rays(project, warnings)
    _check_settings(project, source, warnings)
    _check_usage(project, warnings)
    _check_image_format(project, warnings)
    return warnings


#: largest accepted coordinate (any length unit) and angle (radians): far
#: beyond any real value (the Earth's radius in mm is 6.4e9), and small
#: enough that squares and products of coordinates stay finite (1e308 would
#: overflow and fail with a numerical error instead of naming the value)
MAX_COORDINATE = 1e100
MAX_ANGLE = 1e4


def _check_magnitudes(project) -> None:
    """Refuse absurd approximate or reference values (e.g. 1e308) with their
    file and line, before any arithmetic overflows."""
    st, pts = project.stations, project.points
    checks = (("stations", "station", st.names, np.asarray(st.position, float), MAX_COORDINATE,
               "X0 Y0 Z0", st.record),
              ("stations", "station", st.names, np.asarray(st.angles, float), MAX_ANGLE,
               "omega phi kappa", st.record),
              ("points", "point", pts.ids, np.asarray(pts.xyz, float), MAX_COORDINATE,
               "X Y Z", pts.record))
    for source, what, names, values, limit, columns, records in checks:
        if not values.size:
            continue
        bad = np.flatnonzero(np.any(np.abs(values.reshape(len(names), -1)) > limit, axis=1))
        if len(bad):
            i = int(bad[0])
            rec = records[i] if len(records) == len(names) else 0
            value = values.reshape(len(names), -1)[i]
            big = value[np.argmax(np.abs(np.nan_to_num(value)))]
            raise InputError(f"{what} {names[i]}: {columns} hold {big:.6g}, beyond "
                             f"{limit:g} ({'radians' if limit == MAX_ANGLE else 'length units'})",
                             file=project.sources.get(source), line=_line(rec),
                             hint="check the value and the units in [project]")


def repeated_observation(station, point, n_points: int) -> tuple[int, int] | None:
    """``(row, first_row)`` of the first observation that repeats the
    (station, point) of an earlier one, or None."""
    key = station.astype(np.int64) * (n_points + 1) + point
    _, counts = np.unique(key, return_counts=True)
    if np.all(counts == 1):
        return None
    seen: dict = {}
    for row, k in enumerate(key):
        if k in seen:
            return row, seen[k]
        seen[k] = row
    return None


def _check_duplicate_observations(project) -> None:
    obs = project.image_points
    if not len(obs):
        return
    found = repeated_observation(obs.station, obs.point, len(project.points))
    if found is None:
        return
    row = found[0]
    rec = _records(obs, np.array([row]))[0]
    station = project.stations.names[obs.station[row]]
    point = project.points.ids[obs.point[row]]
    raise InputError(f"point {point} is measured twice in station {station}",
                     file=project.sources.get("image_points"), line=_line(rec),
                     hint="keep one measurement per point and image")


def observation_rays(point, station, n_points: int) -> np.ndarray:
    """Number of distinct stations observing each of ``n_points`` points."""
    pairs = np.unique(np.stack([point, station], axis=1), axis=0) \
        if len(point) else np.zeros((0, 2), int)
    return np.bincount(pairs[:, 0], minlength=n_points) if len(pairs) \
        else np.zeros(n_points, int)


def rays_per_point(project) -> np.ndarray:
    """Number of distinct stations observing each point."""
    obs = project.image_points
    return observation_rays(obs.point, obs.station, len(project.points))


def check_single_rays(project, point, station, rays, where) -> None:
    """Raise for the first tie or check point seen from one station only.

    ``point``, ``station``: the observations' indices; ``rays`` from
    :func:`observation_rays`; ``where(row)`` gives the ``(file, line)`` of an
    observation row for the message.
    """
    for i in np.flatnonzero(rays == 1):
        kind = project.points.kind[i]
        if kind in ("tie", "check"):
            row = int(np.flatnonzero(point == i)[0])
            file, line = where(row)
            raise InputError(
                f"point {project.points.ids[i]} is seen in 1 image (station "
                f"{project.stations.names[station[row]]}); a {kind} point "
                f"needs at least 2 rays", file=file, line=line,
                hint="measure it in another image or remove it")


def _check_rays(project, warnings: list[str]) -> None:
    rays = rays_per_point(project)
    obs = project.image_points
    check_single_rays(project, obs.point, obs.station, rays,
                      lambda row: (project.sources.get("image_points"),
                                   _line(_records(obs, np.array([row]))[0])))
    unused = [pid for pid, r in zip(project.points.ids, rays) if r == 0]
    if unused:
        warnings.append(f"{len(unused)} point(s) are not measured in any image "
                        f"and are not used: {', '.join(unused[:10])}"
                        + (" ..." if len(unused) > 10 else ""))


def _check_settings(project, source: TomlSource | None, warnings: list[str]) -> None:
    adj = project.adjustment
    file = project.sources.get("project")
    where = (lambda key: source.line_of(("adjustment", key))) if source else (lambda key: None)
    known = set(project.points.ids)
    for pid in adj.inner_constraints or []:
        if pid not in known:
            raise InputError(f"inner_constraints names point {pid}, which is not in the "
                             f"points table", file=file, line=where("inner_constraints"),
                             hint=suggest(pid, project.points.ids, noun="points"))
    kinds = np.asarray(project.points.kind, dtype=object)
    if adj.datum == "control" and not np.any(kinds == "control") and len(project.points):
        warnings.append("datum = control but the points table has no control points: "
                        "the datum must come from the stations")
    if adj.datum == "free" and adj.inner_constraints == []:
        raise InputError("inner_constraints is empty", file=file,
                         line=where("inner_constraints"),
                         hint="list the points of the free datum or remove the key (all points)")
    if adj.datum != "dependent" and (getattr(adj, "dependent_station", None) is not None
                                     or getattr(adj, "dependent_coordinate", "longest")
                                     != "longest"):
        warnings.append(f'dependent_station and dependent_coordinate are used only with '
                        f'datum = "dependent" (datum is "{adj.datum}")')


def _check_usage(project, warnings: list[str]) -> None:
    used = set(project.image_points.station.tolist()) | set(project.image_lines.station.tolist())
    idle = [n for i, n in enumerate(project.stations.names) if i not in used]
    if idle:
        warnings.append(f"{len(idle)} station(s) have no observations: {', '.join(idle[:10])}")
    cams = set(project.stations.camera)
    idle_cams = [c for c in project.cameras if c not in cams]
    if idle_cams:
        warnings.append(f"camera(s) without stations: {', '.join(idle_cams)}")


#: a camera whose image points all lie within this fraction of its format
#: from the top-left corner (at least MIN_FORMAT_POINTS of them) has them in
#: the wrong unit (mm read as px: ~1/100 of the format): refused
CORNER_FRACTION = 0.05
MIN_FORMAT_POINTS = 4


def _format_size(camera, image_unit: str, principal_point: bool = False):
    """The image format (width, height) in ``image_unit``; with
    ``principal_point`` twice the principal point when the size is not
    given (brown x0 y0, opencv cx cy)."""
    if camera.image_size is None:
        if not principal_point:
            return None
        for a, b in (("x0", "y0"), ("cx", "cy")):
            p = camera.parameters
            if a in p and b in p and p[a].value > 0 and p[b].value > 0:
                return 2.0 * p[a].value, 2.0 * p[b].value
        return None
    w, h = camera.image_size
    if image_unit == "px":
        return float(w), float(h)
    if camera.pixel_size is None:
        return None
    return w * camera.pixel_size[0], h * camera.pixel_size[1]


def _check_image_format(project, warnings: list[str]) -> None:
    """Image points against the image format, per camera: all of them in a
    tiny corner (mm read as px) or most of them outside (px read as mm) is
    refused; a few outside is a warning."""
    obs = project.image_points
    if not len(obs):
        return
    unit = project.units.image
    station_cam = np.asarray(project.stations.camera, dtype=object)
    obs_cam = station_cam[obs.station]
    file = project.sources.get("image_points")
    outside_all = []
    for name, cam in project.cameras.items():
        rows = np.flatnonzero(obs_cam == name)
        if not len(rows):
            continue
        xy = obs.xy[rows]
        fmt = _format_size(cam, unit, principal_point=True)
        if fmt is None:
            continue
        w, h = fmt
        if len(rows) >= MIN_FORMAT_POINTS and np.all(np.abs(xy) <= [CORNER_FRACTION * w,
                                                                     CORNER_FRACTION * h]):
            rec = _line(_records(obs, rows[:1])[0])
            other = "mm" if unit == "px" else "px"
            raise InputError(
                f"all {len(rows)} image points of camera {name} lie within "
                f"{np.abs(xy[:, 0]).max():.3g} x {np.abs(xy[:, 1]).max():.3g} {unit} of the "
                f"top-left corner of its {w:.4g} x {h:.4g} {unit} format: they look like "
                f"{other}, not {unit}", file=file, line=rec,
                hint=f"give them in {unit}, or say [observations] unit = \"{other}\" "
                     f"(with pixel_size in the camera)")
        if cam.image_size is None:
            continue                        # the principal point does not bound the format
        out = rows[np.any((xy < 0) | (xy > [w, h]), axis=1)]
        if len(rows) >= MIN_FORMAT_POINTS and 2 * len(out) > len(rows):
            rec = _line(_records(obs, out[:1])[0])
            raise InputError(
                f"{len(out)} of the {len(rows)} image points of camera {name} lie outside its "
                f"{w:.4g} x {h:.4g} {unit} format (largest x {xy[:, 0].max():.4g}, y "
                f"{xy[:, 1].max():.4g}): wrong unit or image_size?", file=file, line=rec,
                hint=f"check image_unit = \"{unit}\" in [project], [observations] unit and "
                     f"image_size / pixel_size of camera {name}")
        outside_all.append(out)
    outside = np.sort(np.concatenate(outside_all)) if outside_all else np.zeros(0, int)
    if len(outside):
        rec = _line(_records(obs, outside[:1])[0])
        first = f" (first: line {rec})" if rec else ""
        warnings.append(f"{len(outside)} image point(s) lie outside the image format{first}")
