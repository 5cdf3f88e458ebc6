"""The registry of foreign formats: what ``photogram import`` and
``photogram export`` can read and write (docs/interoperability.md).

``import_project(format, source, to, **options) -> Path`` writes a new
project folder (never replacing a file) and returns its .prj;
``export_results(format, source, to, force=False) -> list[Path]`` writes
the files of one format from a results folder (or a project).
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from photogram.errors import InputError, PhotogramError

__all__ = ["IMPORT_FORMATS", "EXPORT_FORMATS", "import_project", "export_results"]

log = logging.getLogger("photogram")

#: format -> what it reads (for the help text)
IMPORT_FORMATS = {
    "dbat": "DBAT XML script (camcaldemo.xml, sxb.xml) with its tables",
    "pmexport": "PhotoModeler text export (the layout DBAT's loadpm reads)",
    "pose2sim": "Pose2Sim / anipose calibration TOML (Calib_*.toml)",
    "opencv": "OpenCV FileStorage calibration (YAML/XML/JSON)",
    "colmap": "COLMAP model, binary or text (folder with cameras, images, points3D .bin or "
              ".txt; rigs and frames read)",
    "bal": "Bundle Adjustment in the Large problem (.txt, .bz2; read by photogram.io.bal)",
    "images": "folder of planar-target images (--target) -> a calibration project",
}
EXPORT_FORMATS = {
    "pose2sim": "Pose2Sim / anipose calibration TOML",
    "opencv": "OpenCV FileStorage (one file per station; a folder for several)",
    "colmap": "COLMAP text model (a folder)",
    "colmap-bin": "COLMAP binary model, COLMAP's default (a folder)",
    "ply": "object points with their sigmas (ASCII PLY)",
    "trc": "trajectories for OpenSim (.trc, metres, Y up)",
    "c3d": "trajectories as C3D (mm, Z up, residual and camera mask)",
    "mot": "stick-model angles for OpenSim (.mot, degrees)",
    "csv": "trajectories as one CSV row per exposure (metres, Z up)",
}
ALIASES = {"anipose": "pose2sim", "photomodeler": "pmexport", "yaml": "opencv",
           "targets": "images"}


def _format(name: str, table: dict) -> str:
    key = ALIASES.get(str(name).lower(), str(name).lower())
    if key not in table:
        from photogram.project.text_input import suggest
        raise InputError(f"unknown format {name!r}", hint=suggest(key, list(table), noun="formats"))
    return key


def import_project(fmt: str, source, to, *, name: str | None = None, target: str | None = None,
                   model: str = "opencv", control=None, free=None,
                   image_size=None) -> Path:
    """Read ``source`` in format ``fmt`` and write a new project into the
    folder ``to``; returns the .prj written.

    ``control`` (a DBAT control table), ``free`` ("all" or camera parameter
    names) and ``image_size`` ((w, h) px) are options of ``pmexport``
    (:func:`photogram.io.pmexport.pmexport_project`).

    Raises
    ------
    InputError
        Unknown format, malformed source (file and line), existing files.
    """
    from photogram.io import exchange
    key = _format(fmt, IMPORT_FORMATS)
    source = Path(source)
    if key != "images" and target is not None:
        raise InputError("--target is only used with the images format")
    if key != "pmexport" and (control is not None or free is not None or image_size is not None):
        raise InputError("--control, --free and --image-size are only used with the pmexport "
                         "format")
    if key == "dbat":
        from photogram.io.dbat_script import dbat_script_project
        return exchange.save_project(dbat_script_project(source, name), to, name)
    if key == "pmexport":
        from photogram.io.pmexport import pmexport_project
        return exchange.save_project(pmexport_project(source, name, image_size, control=control,
                                                      free=free), to, name)
    if key == "pose2sim":
        from photogram.io.pose2sim import pose2sim_project
        return exchange.save_calibration(pose2sim_project(source, name), to, name)
    if key == "opencv":
        from photogram.io.opencv_fs import opencv_project
        return exchange.save_calibration(opencv_project(source, name), to, name)
    if key == "colmap":
        from photogram.io.colmap import colmap_project
        return exchange.save_project(colmap_project(source, name), to, name)
    if key == "images":
        if not target:
            raise InputError("the images format needs --target",
                             hint="e.g. --target chessboard:9x6:0.025 (inner corners, square "
                                  "size in m)")
        from photogram.io.targets import images_project
        return exchange.save_project(images_project(source, target, model=model, name=name),
                                     to, name)
    return _import_bal(source, to, name)


def _import_bal(source: Path, to, name):
    try:
        from photogram.io.bal import read_bal  # noqa: F401  (the engine's reader)
    except ImportError:
        raise InputError("BAL import is not available yet (photogram.io.bal is not built)",
                         file=source) from None
    from photogram.io.bal_import import bal_project
    from photogram.io.exchange import save_project
    return save_project(bal_project(source, name), to, name)


def export_results(fmt: str, source, to, *, force: bool = False) -> list[Path]:
    """Write the results in ``source`` (a results folder, or a project) in
    format ``fmt`` to ``to``; returns the files written.

    Raises
    ------
    InputError
        Unknown format, incomplete source (e.g. stations without an
        orientation), existing files (unless ``force``).
    """
    key = _format(fmt, EXPORT_FORMATS)
    to = Path(to)
    _refuse_inputs(key, source, to)
    if key in ("trc", "c3d", "mot", "csv"):
        from photogram.io import trajectories as tr
        traj = tr.load_trajectories(source)
        writer = {"trc": tr.write_trc_export, "c3d": tr.write_c3d, "mot": tr.write_mot,
                  "csv": tr.write_trajectory_csv}[key]
        written = [writer(to, traj, force=force)]
        return written + ([tr.csv_sidecar(to)] if key == "csv" else [])
    from photogram.io.export_source import load_source, views_of
    src = load_source(source)
    project = src.project
    if key == "ply":
        from photogram.io.ply import write_ply
        return [write_ply(to, project.points.ids, project.points.xyz, src.point_sigma,
                          project.points.kind, unit=project.units.length, force=force,
                          comment=f"from {src.folder}")]
    _refuse_moving_cameras(src, key, source)
    if key in ("colmap", "colmap-bin"):
        from photogram.io.colmap import colmap_views
        views = colmap_views(project)
    else:
        views = views_of(project)
    if not views:
        raise InputError("no stations to export", file=source)
    if key == "pose2sim":
        import dataclasses

        from photogram.io.pose2sim import write_pose2sim
        # Pose2Sim's (and anipose's) world is in metres: convert the translations
        views = [dataclasses.replace(v, t_cv=np.asarray(v.t_cv, float) * src.metres)
                 for v in views]
        for v in views:
            if np.any(np.asarray(v.dist, float)[5:] != 0):
                raise InputError(f"camera {v.camera} has rational, thin-prism or tilt "
                                 f"distortion (opencv_full), which Pose2Sim's [k1, k2, p1, "
                                 f"p2, k3] cannot hold", file=source,
                                 hint="export opencv (FileStorage keeps all 14 terms)")
        if project.units.length != "m":
            log.info("Pose2Sim export: translations converted from %s to m",
                     project.units.length)
        return [write_pose2sim(to, views, force=force,
                               error=float(src.summary.get("sigma0_image") or 0.0))]
    if key == "opencv":
        from photogram.io.opencv_fs import write_opencv
        return write_opencv(to, views, force=force)
    from photogram.io.colmap import write_colmap
    obs, error = _observations(src)
    _check_tracks(src, obs)
    folder = write_colmap(to, views, project.points.ids, project.points.xyz, obs, error,
                          force=force, binary_files=key == "colmap-bin", project=project)
    ext = ".bin" if key == "colmap-bin" else ".txt"
    return _targets(key, folder) + ([folder / ("rigs" + ext), folder / ("frames" + ext)]
                                    if project.rigs else [])


#: files of a results folder (or calibration folder) that the exporters read
READ_FILES = ("summary.json", "cameras.toml", "stations.csv", "points.csv", "residuals.csv",
              "covariance.npz", "points3d.csv", "exposures.csv", "joints3d.csv", "metrics.csv",
              "joints3d.trc")


def export_inputs(source) -> list[Path]:
    """Every file an export of ``source`` may read: the source itself, the
    files of a results folder, and the project (.prj and its tables) that
    the folder's summary.json names or the folder holds."""
    import json
    source = Path(source)
    out = [source] if source.is_file() else []
    folder = source if source.is_dir() else source.parent
    prjs = [source] if source.suffix == ".prj" else []
    if source.is_dir():
        out += [folder / f for f in READ_FILES if (folder / f).is_file()]
        prjs += sorted(folder.glob("*.prj"))
        try:
            info = json.loads((folder / "summary.json").read_text(encoding="utf-8"))
            info = info.get("project") if isinstance(info, dict) else None
            if isinstance(info, dict) and info.get("path"):
                prjs.append(Path(info["path"]))
        except (OSError, ValueError):
            pass
    from photogram.project import read_project
    from photogram.project.output_policy import project_inputs
    for prj in prjs:
        if not Path(prj).is_file():
            continue
        out.append(Path(prj))
        try:
            out += project_inputs(read_project(prj))
        except PhotogramError:
            pass                              # the export itself names the problem
    return out


def _targets(key: str, to: Path) -> list[Path]:
    if key in ("colmap", "colmap-bin"):
        ext = ".bin" if key == "colmap-bin" else ".txt"
        return [to / (f + ext) for f in ("cameras", "images", "points3D")]
    if key == "csv":
        from photogram.io.trajectories import csv_sidecar
        return [to, csv_sidecar(to)]
    return [to]


def _refuse_inputs(key: str, source, to: Path) -> None:
    """Never write over a file the export reads (not even with --force)."""
    import os
    inputs = [p for p in export_inputs(source) if p.exists()]
    for target in _targets(key, to):
        for p in inputs:
            same = target.exists() and os.path.samefile(target, p)
            if same or target.resolve() == p.resolve():
                raise InputError(f"is an input of this export ({p}); photogram export "
                                 f"never writes over the files it reads, not even with --force",
                                 file=target, hint="choose another --to path")


def _refuse_moving_cameras(src, key: str, source) -> None:
    """Pose2Sim, OpenCV and COLMAP hold one fixed orientation per camera: a
    project whose cameras pan, tilt or zoom (``[mocap]`` with
    ``camera_frames``, estimated rotations or images) has one per frame,
    and its stations table gives frame 0 only."""
    ms = getattr(src.project, "mocap", None)
    if ms is None:
        return
    moving = (ms.camera_frames is not None or ms.rotation == "estimate"
              or ms.rotation_differences is not None or bool(ms.images))
    if moving:
        raise InputError(
            f"the cameras of this project pan, tilt or zoom (one orientation per frame); "
            f"{key} holds one fixed orientation per camera, and exporting the stations table "
            f"(frame 0) would be wrong for every other frame", file=src.project.path,
            hint="export the 3D joints of its mocap results instead (photogram export "
                 "trc|c3d|csv|mot RESULTS)")


def _check_tracks(src, obs) -> None:
    """COLMAP keeps only 3D points with a track: refuse a model whose points
    all lack image observations, and say how many are left out."""
    xyz = src.project.points.xyz
    known = np.all(np.isfinite(xyz), axis=1)
    seen = np.zeros(len(known), bool)
    seen[[p for _, p, _, _ in obs]] = True
    lost = int(np.sum(known & ~seen))
    if lost and not np.any(known & seen):
        raise InputError(f"none of the {lost} points has an image observation, and COLMAP "
                         f"keeps only points with a track", file=src.folder,
                         hint="rerun the command that wrote the results (its residuals.csv "
                              "lists the observations), or export ply for the points alone")
    if lost:
        log.warning("COLMAP export: %d point(s) without image observations are left out", lost)


def _observations(src):
    """(view index, point index, x, y) of every image point, and the mean
    image residual per point (0 where unknown), in px."""
    project = src.project
    sidx = project.stations.index()
    pidx = project.points.index()
    n = len(project.points)
    err_sum, err_n = np.zeros(n), np.zeros(n)
    if src.results is not None:
        res = src.results.residuals
        obs = []
        if len(res) and {"station", "point", "x", "y"} <= set(res.columns):
            vx = res["vx"].to_numpy(float) if "vx" in res.columns else np.zeros(len(res))
            vy = res["vy"].to_numpy(float) if "vy" in res.columns else np.zeros(len(res))
            for s, p, x, y, a, b in zip(res["station"], res["point"], res["x"], res["y"],
                                        vx, vy):
                if str(s) in sidx and str(p) in pidx:
                    i = pidx[str(p)]
                    obs.append((sidx[str(s)], i, float(x), float(y)))
                    err_sum[i] += np.hypot(a, b)
                    err_n[i] += 1
        if not obs:
            obs = _project_observations(src)
        if src.project.units.image != "px":
            raise InputError("COLMAP export needs image coordinates in px",
                             file=src.folder, hint="use image_unit = \"px\"")
    else:
        ip = project.image_points
        if project.units.image != "px":
            raise InputError("COLMAP export needs image coordinates in px", file=project.path)
        obs = [(int(s), int(p), float(x), float(y)) for s, p, (x, y) in
               zip(ip.station, ip.point, ip.xy)]
    error = np.where(err_n > 0, err_sum / np.maximum(err_n, 1), 0.0)
    return obs, error


def _project_observations(src) -> list:
    """The image points of the project a results folder came from (its
    ``summary.json`` names it), for results folders whose residuals.csv
    lists no observations (photogram intersect before issue 16)."""
    path = src.project.path
    if not path or not Path(path).is_file():
        return []
    from photogram.project import read_project
    try:
        source = read_project(path)
    except PhotogramError as exc:
        log.warning("COLMAP export: cannot read the observations of %s (%s)", path, exc)
        return []
    sidx = src.project.stations.index()
    pidx = src.project.points.index()
    names, ids = source.stations.names, source.points.ids
    ip = source.image_points
    return [(sidx[names[s]], pidx[ids[p]], float(x), float(y))
            for s, p, (x, y) in zip(ip.station, ip.point, ip.xy)
            if names[s] in sidx and ids[p] in pidx]
