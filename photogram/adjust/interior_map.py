"""Shared interior-orientation parameters: which unknown each interior
parameter of each observation is (Ceres' parameter blocks shared by
residual blocks; DBAT's image-variant calibration).

A camera's parameter is, by the sharing of its ``[cameras.NAME]`` section
(:mod:`photogram.project.reader_sharing`, docs/project-files.md "Parameter
sharing"):

* one value for all stations of the camera (the default);
* one value per station (``per_station``);
* one value for several cameras (``shared``: the cameras that name one
  group);
* equal to another parameter of the camera (``tie``, e.g. ``fy = fx``).

The engine keeps one interior *block* ("io instance", a parameter vector
in the camera model's order) per camera, or per station for a camera with
per-station parameters. Each instance's parameters map to columns of the
unknown vector (:class:`~photogram.adjust.state.Layout` ``camera_columns``):
instances that share a parameter name the same column. An observation
gathers its io vector from its instance, and the Jacobian columns of
shared parameters add up in the normal equations (every scatter there is a
``bincount``): with ``x = p`` and ``y = p`` (a tie) the column of ``p`` is
``dF/dx + dF/dy``, the chain rule.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["InteriorMap", "interior_map"]


@dataclass
class InteriorMap:
    """The interior unknowns of a project with shared parameters.

    Attributes
    ----------
    camera : (n_inst,) int
        Camera (index into the project's cameras) of each instance.
    station_instance : (n_s,) int
        Instance of each station.
    columns : list of (p,) int
        Column (0 .. n_io - 1) of each parameter of each instance.
    free, values : (n_io,)
        State and start value of each interior unknown.
    owners : list of dict
        Per unknown: ``cameras`` (names), ``parameter``, ``equal`` (the
        parameters tied to it), ``station`` (per-station unknowns, else
        None), ``group`` (shared across cameras, else None).
    priors : list of (column, value, sigma)
        Weighted unknowns (a-priori sigma).
    instance_station : (n_inst,) int
        Station of a per-station instance, -1 for a camera's one instance.
    station_names : list of str
    """

    camera: np.ndarray
    station_instance: np.ndarray
    columns: list
    free: np.ndarray
    values: np.ndarray
    owners: list = field(default_factory=list)
    priors: list = field(default_factory=list)
    instance_station: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    station_names: list = field(default_factory=list)

    @property
    def n_io(self) -> int:
        return len(self.values)

    @property
    def labels(self) -> list[str]:
        """One label per unknown: ``K1.c``, ``K1.x0@S3`` (per station),
        ``K1+K2.c`` (shared by cameras K1 and K2)."""
        return [f"{'+'.join(o['cameras'])}.{o['parameter']}"
                + (f"@{o['station']}" if o["station"] is not None else "") for o in self.owners]

    def instance_values(self) -> list[np.ndarray]:
        """Start io vector of each instance (tied parameters equal)."""
        return [self.values[c].copy() for c in self.columns]

    def instances_of(self, k: int) -> np.ndarray:
        """Instances of camera ``k``."""
        return np.flatnonzero(self.camera == k)

    def per_station(self, k: int, camera, p: str) -> bool:
        """Whether parameter ``p`` of camera ``k`` (Camera ``camera``) is one
        value per station here (its instances are per station)."""
        first = self.instances_of(k)[0]
        return camera.ties.get(p, p) in camera.per_station and self.instance_station[first] >= 0

    def station_of(self, instance: int) -> str:
        """Name of the station of a per-station instance."""
        return self.station_names[self.instance_station[instance]]

    def prior_rows(self):
        """``(instance, position, value, sigma)`` arrays of the priors, for
        :class:`~photogram.adjust.residual_blocks.InteriorPriorBlock`."""
        rows = []
        for col, value, sigma in self.priors:
            for i, cols in enumerate(self.columns):
                hit = np.flatnonzero(cols == col)
                if len(hit):
                    rows.append((i, int(hit[0]), value, sigma))
                    break
        return rows


def _key(camera, k, p, station):
    """The unknown that parameter ``p`` of camera ``k`` (at ``station``) is."""
    p = camera.ties.get(p, p)
    if p in camera.per_station and station is not None:
        return ("station", k, p, station)
    if p in camera.shared:
        return ("group", camera.shared[p], p)
    return ("camera", k, p)


def interior_map(cameras, camera_names, station_names, station_camera) -> InteriorMap | None:
    """The :class:`InteriorMap` of a project's cameras, or None when no
    camera shares a parameter (the engine then numbers every camera's
    parameters in turn, as always).

    Parameters
    ----------
    cameras : list of Camera
        In the order of ``camera_names``.
    station_names : list of str
    station_camera : (n_s,) int
        Camera index of each station.
    """
    if not any(c.shares() for c in cameras):
        return None
    station_camera = np.asarray(station_camera, dtype=int)
    column: dict = {}
    owners, values, free, priors = [], [], [], []
    inst_camera, inst_columns, inst_station = [], [], []
    station_instance = np.zeros(len(station_camera), dtype=int)
    for k, cam in enumerate(cameras):
        stations = np.flatnonzero(station_camera == k)
        per = bool(cam.per_station) and len(stations) > 0
        for s in stations if per else [None]:
            cols = []
            for p in cam.parameters:
                key = _key(cam, k, p, None if s is None else station_names[s])
                if key not in column:
                    column[key] = len(values)
                    par = cam.parameters[key[-2] if key[0] == "station" else key[-1]]
                    values.append(par.value)
                    free.append(par.free)
                    if par.free and par.sigma is not None and np.isfinite(par.sigma) \
                            and par.sigma > 0:
                        priors.append((column[key], par.value, par.sigma))
                    owners.append(_owner(key, cam, camera_names, cameras))
                cols.append(column[key])
            if s is None:
                station_instance[stations] = len(inst_columns)
            else:
                station_instance[s] = len(inst_columns)
            inst_camera.append(k)
            inst_columns.append(np.array(cols, dtype=int))
            inst_station.append(-1 if s is None else int(s))
    return InteriorMap(np.array(inst_camera, dtype=int), station_instance, inst_columns,
                       np.array(free, dtype=bool), np.array(values, dtype=float), owners,
                       priors, np.array(inst_station, dtype=int), list(station_names))


def _owner(key, cam, camera_names, cameras) -> dict:
    kind, p = key[0], key[-2] if key[0] == "station" else key[-1]
    if kind == "group":
        members = [n for n, c in zip(camera_names, cameras) if c.shared.get(p) == key[1]]
    else:
        members = [camera_names[key[1]]]
    equal = sorted(q for q, t in cam.ties.items() if t == p)
    return {"cameras": members, "parameter": p, "equal": equal,
            "station": key[3] if kind == "station" else None,
            "group": key[1] if kind == "group" else None}
