"""The ``[mocap]`` section: a motion-capture project (docs/mocap.md).

A .prj with a ``[mocap]`` section is a motion-capture project: ``[project]``
and ``[output]`` as usual; the cameras either in ``[cameras]`` and
``[stations]`` (one station per camera, named like it or naming it in its
``camera`` column) or in a Pose2Sim calibration file (``calibration =``);
no ``[points]``, ``[observations]`` or ``[constraints]``. This module checks
types, choices and that files exist, every error with file and line; the
mocap pipeline (:mod:`photogram.mocap.pipeline`) checks what needs the
mocap package (skeleton names, the network) through
:meth:`MocapSettings.error`, which points at the key's line.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from photogram.errors import InputError
from photogram.project.camera_schema import read_camera
from photogram.project.model import Points, Project
from photogram.project.toml_source import Section, TomlSource

__all__ = ["MocapSettings", "MocapSource", "read_mocap_project", "MOCAP_KEYS", "SOURCE_KINDS"]

MOCAP_KEYS = ("fps", "skeleton", "calibration", "camera_frames", "frames", "up", "limb_lengths",
              "truth", "reference_trc", "outside_leg", "runs", "source", "tracking",
              "reconstruction", "rotation", "rotation_differences", "images", "homography",
              "truth_rotations", "filter", "offsets")
OFFSET_MODES = ("estimate", "report")
ROTATION_MODES = ("known", "estimate")
HOMOGRAPHY_KEYS = ("n_features", "ransac_px", "min_inliers", "box_margin", "median", "sigma",
                   "max_failed", "min_inlier_fraction", "lags", "max_lag_fraction")
SOURCE_KINDS = ("openpose", "csv", "mediapipe", "plugin")
SOURCE_KEYS = ("kind", "path", "cameras", "skeleton", "network", "wide")
TRACKING_KEYS = ("scale", "wide_scale", "sigma_centre", "sigma_side", "sigma_refine",
                 "crop_size", "min_confidence", "multiview", "association_px",
                 "association_confidence", "gate")
RECONSTRUCTION_KEYS = ("solver", "n_dct", "window", "overlap", "sigma2", "lambda_rep",
                       "lambda_limbs", "gnc_start", "max_iterations", "tolerance",
                       "symmetric_limbs", "min_confidence", "support_frames", "limb_unit",
                       "step_tol", "n_rotation_dct", "lambda_rot", "bootstrap_iterations",
                       "pose_basis", "rotation_basis", "rotation_prior", "cutoff_hz",
                       "inlier_sigmas", "chain_offsets", "offset_knot_frames",
                       "chain_sigma_deg")
FILTER_KEYS = ("type", "order", "cutoff_hz")
FILTER_TYPES = ("butterworth", "none")
_FORBIDDEN = ("points", "observations", "constraints", "intersect", "montecarlo",
              "adjustment", "targets")


@dataclass
class MocapSource:
    """``[mocap.source]``: where the 2D detections come from."""

    kind: str
    path: Path | None = None
    cameras: dict | None = None         # camera -> folder/file (absolute)
    skeleton: str | None = None
    network: str | None = None          # "module:function" (kind = plugin)
    wide: tuple = ()                    # cameras with the wide crop scale


@dataclass
class MocapSettings:
    """``[mocap]`` with absolute paths; ``source_file`` and ``keypath`` let
    later checks point at the right line (:meth:`error`)."""

    source: MocapSource
    fps: float = 50.0
    skeleton: str | None = None
    calibration: Path | None = None
    camera_frames: Path | None = None
    frames: tuple | None = None
    up: tuple = (0.0, 0.0, 1.0)
    limb_lengths: Path | None = None
    truth: Path | None = None
    reference_trc: Path | None = None
    outside_leg: str = "extended"
    runs: tuple = ()
    tracking: dict = field(default_factory=dict)
    reconstruction: dict = field(default_factory=dict)
    rotation: str = "known"             # or "estimate" (rotations from the images)
    rotation_differences: Path | None = None
    images: dict | None = None          # camera -> video file or image folder (absolute)
    homography: dict = field(default_factory=dict)
    truth_rotations: Path | None = None
    filter: dict = field(default_factory=dict)     # [mocap.filter] (post-filter of the joints)
    offsets: str | dict | None = None   # "estimate", "report" or camera -> frames
    toml: TomlSource | None = None

    def error(self, keypath, what: str, hint: str | None = None) -> InputError:
        """An InputError at the line of ``keypath`` (e.g. ``("source",
        "skeleton")``) under ``[mocap]``."""
        line = self.toml.line_of(("mocap",) + tuple(keypath)) if self.toml else None
        return InputError(what, file=self.toml.path if self.toml else None, line=line, hint=hint)


def _path(sec: Section, key: str, folder: Path, *, kind: str = "file") -> Path | None:
    if key not in sec:
        return None
    value = Path(sec.string(key))
    full = value if value.is_absolute() else folder / value
    ok = {"file": full.is_file(), "dir": full.is_dir(), "any": full.exists()}[kind]
    if not ok:
        what = {"file": "file", "dir": "folder", "any": "file or folder"}[kind]
        raise sec.error(key, f"{key} in {sec.label}: {what} {value} not found",
                        hint="paths are relative to the folder of the project file")
    return full


def _camera_paths(sub: Section, base: Path, hint: str) -> dict:
    """camera -> existing file or folder (absolute) of a ``{ C1 = "..." }``
    table, relative paths from ``base``."""
    out = {}
    for name in sub.data:
        value = Path(sub.string(name))
        full = value if value.is_absolute() else base / value
        if not full.exists():
            raise sub.error(name, f"camera {name} in {sub.label}: {value} not found", hint=hint)
        out[name] = full
    return out


def _read_source(sec: Section, folder: Path) -> MocapSource:
    sec.check_keys(SOURCE_KEYS, required=("kind",))
    kind = sec.string("kind", choices=SOURCE_KINDS)
    want = {"openpose": "any", "csv": "file", "mediapipe": "any", "plugin": "any"}[kind]
    path = _path(sec, "path", folder, kind=want)
    cams = None
    if "cameras" in sec:
        cams = _camera_paths(sec.table("cameras"),
                             path if path is not None and path.is_dir() else folder,
                             "relative to path of [mocap.source] (or the project folder "
                             "without path)")
    if kind == "csv" and path is None:
        raise sec.error(None, f"{sec.label} of kind csv needs path = \"detections.csv\"")
    if kind != "csv" and path is None and cams is None:
        raise sec.error(None, f"{sec.label} of kind {kind} needs path or cameras",
                        hint="path = a folder with one sub-folder per camera, or cameras = "
                             "{ cam1 = \"...\" }")
    network = None
    if kind == "plugin":
        network = sec.string("network")
        if ":" not in network:
            raise sec.error("network", f"network in {sec.label} must be \"module:function\"",
                            hint='e.g. network = "mynet:detect"')
    elif "network" in sec:
        raise sec.error("network", f"network in {sec.label} is only for kind = \"plugin\"")
    return MocapSource(kind=kind, path=path, cameras=cams, skeleton=sec.string("skeleton", None),
                       network=network, wide=tuple(sec.ids("wide", [])))


def _numbers(sec: Section, key: str, length: int, default):
    if key not in sec:
        return default
    value = sec.data[key]
    if not isinstance(value, list) or len(value) != length or any(
            isinstance(v, bool) or not isinstance(v, (int, float)) for v in value):
        raise sec.error(key, f"{key} in {sec.label} must be an array of {length} numbers")
    return tuple(float(v) for v in value)


def _lags(sub) -> tuple:
    """``lags`` of [mocap.homography]: frame distances (integers >= 2) of the
    lagged rotation differences; ``[]`` measures none."""
    value = sub.data["lags"]
    if not (isinstance(value, list) and all(isinstance(v, int) and not isinstance(v, bool)
                                            and v >= 2 for v in value)):
        raise sub.error("lags", f"lags in {sub.label} must list frame distances of at least 2",
                        hint="e.g. lags = [10, 25]; lags = [] measures no lagged pairs")
    return tuple(int(v) for v in value)


def _check_cutoffs(sec: Section, subs: dict, fps: float) -> None:
    """``cutoff_hz`` of ``[mocap.reconstruction]``: below fps/2, not with ``n_dct``."""
    rec = subs["reconstruction"]
    if "cutoff_hz" not in rec:
        return
    sub = sec.table("reconstruction")
    if "n_dct" in rec:
        raise sub.error("cutoff_hz", f"give either n_dct or cutoff_hz in {sub.label}, not both",
                        hint="cutoff_hz chooses the DCT terms by frequency, n_dct counts them")
    if rec["cutoff_hz"] >= fps / 2:
        raise sub.error("cutoff_hz", f"cutoff_hz in {sub.label} must be below fps/2 = "
                                     f"{fps / 2:g} Hz, not {rec['cutoff_hz']:g}")


def _read_filter(sub: Section | None, fps: float) -> dict:
    """``[mocap.filter]``: type, even order >= 2, cutoff_hz below fps/2."""
    if sub is None:
        return {}
    sub.check_keys(FILTER_KEYS)
    out = {}
    if "type" in sub:
        out["type"] = sub.string("type", choices=FILTER_TYPES)
    if "order" in sub:
        out["order"] = sub.integer("order", minimum=2)
        if out["order"] % 2:
            raise sub.error("order", f"order in {sub.label} must be even, not {out['order']}",
                            hint="the zero-lag filter runs a Butterworth of order/2 twice")
    if "cutoff_hz" in sub:
        out["cutoff_hz"] = sub.number("cutoff_hz", positive=True)
        if out["cutoff_hz"] >= fps / 2:
            raise sub.error("cutoff_hz", f"cutoff_hz in {sub.label} must be below fps/2 = "
                                         f"{fps / 2:g} Hz, not {out['cutoff_hz']:g}")
    return out


def _read_mocap(sec: Section, folder: Path, src: TomlSource) -> MocapSettings:
    sec.check_keys(MOCAP_KEYS, required=("source",))
    source = _read_source(sec.table("source"), folder)
    frames = None
    if "frames" in sec:
        value = sec.data["frames"]
        if not (isinstance(value, list) and len(value) == 2 and
                all(isinstance(v, int) and not isinstance(v, bool) for v in value)
                and 0 <= value[0] <= value[1]):
            raise sec.error("frames", f"frames in {sec.label} must be [first, last] (0-based, "
                                      f"inclusive)", hint="e.g. frames = [0, 99]")
        frames = (int(value[0]), int(value[1]))
    up = _numbers(sec, "up", 3, (0.0, 0.0, 1.0))
    if sum(v * v for v in up) == 0:
        raise sec.error("up", f"up in {sec.label} must not be zero")
    runs = sec.data.get("runs", [])
    if not isinstance(runs, list) or any(not isinstance(v, int) or isinstance(v, bool) or v < 1
                                         for v in runs):
        raise sec.error("runs", f"runs in {sec.label} must list the first frames (>= 1) of "
                                f"the runs after the first", hint="e.g. runs = [279, 558]")
    subs = {}
    for name, keys in (("tracking", TRACKING_KEYS), ("reconstruction", RECONSTRUCTION_KEYS),
                       ("homography", HOMOGRAPHY_KEYS)):
        sub = sec.table(name, required=False)
        values = {}
        if sub is not None:
            sub.check_keys(keys)
            for key in sub.data:
                if key == "solver":
                    values[key] = sub.string(key, choices=("gauss-newton", "lbfgs"))
                elif key in ("pose_basis", "rotation_basis"):
                    values[key] = sub.string(key, choices=("dct", "free"))
                elif key == "lags":
                    values[key] = _lags(sub)
                elif key in ("symmetric_limbs", "rotation_prior", "multiview", "chain_offsets"):
                    values[key] = sub.boolean(key)
                elif key in ("n_dct", "window", "overlap", "max_iterations", "crop_size",
                             "support_frames", "n_rotation_dct", "bootstrap_iterations",
                             "offset_knot_frames",
                             "n_features", "min_inliers", "median"):
                    values[key] = sub.integer(key, minimum=0 if key in ("overlap",
                                                                        "support_frames") else 1)
                else:
                    zero_ok = key in ("lambda_limbs", "min_confidence", "lambda_rot",
                                      "box_margin", "max_failed", "sigma",
                                      "association_confidence", "inlier_sigmas",
                                      "chain_sigma_deg")
                    values[key] = sub.number(key, nonnegative=zero_ok, positive=not zero_ok)
        subs[name] = values
    images = None
    if "images" in sec:
        images = _camera_paths(sec.table("images"), folder, "a video file or a folder of "
                               "images, relative to the project folder")
    fps = sec.number("fps", 50.0, positive=True)
    _check_cutoffs(sec, subs, fps)
    rotation = sec.string("rotation", "known", choices=ROTATION_MODES)
    rot_diff = _path(sec, "rotation_differences", folder)
    if rotation == "estimate" and rot_diff is None and images is None:
        raise sec.error("rotation", f"rotation = \"estimate\" in {sec.label} needs the "
                                    f"camera images or measured rotation differences",
                        hint='add [mocap.images] (camera = "video.mp4" or a folder) or '
                             'rotation_differences = "file.csv"')
    offsets = _read_offsets(sec)
    if rotation == "estimate" and isinstance(offsets, str):
        # the offsets are estimated from the cameras' rays, which need the
        # rotations that rotation = "estimate" has not estimated yet
        raise sec.error("offsets", f"offsets = \"{offsets}\" in {sec.label} cannot be used with "
                                   f"rotation = \"estimate\": the offsets are estimated from "
                                   f"the cameras' rays, which need known rotations",
                        hint="give them as a table, e.g. offsets = { C2 = 1 } from a run with "
                             "known rotations, or leave offsets out")
    return MocapSettings(
        offsets=offsets, rotation=rotation, rotation_differences=rot_diff,
        images=images,
        homography=subs["homography"], truth_rotations=_path(sec, "truth_rotations", folder),
        source=source, fps=fps, filter=_read_filter(sec.table("filter", required=False), fps),
        skeleton=sec.string("skeleton", None),
        calibration=_path(sec, "calibration", folder),
        camera_frames=_path(sec, "camera_frames", folder), frames=frames, up=up,
        limb_lengths=_path(sec, "limb_lengths", folder), truth=_path(sec, "truth", folder),
        reference_trc=_path(sec, "reference_trc", folder),
        outside_leg=sec.string("outside_leg", "extended", choices=("extended", "flexed")),
        runs=tuple(sorted(set(runs))), tracking=subs["tracking"],
        reconstruction=subs["reconstruction"], toml=src)


def _read_offsets(sec: Section):
    """``offsets``: "estimate" (estimate and apply), "report" (estimate only)
    or a table camera -> frames (docs/mocap.md, "Synchronisation"); the
    camera names are checked by the pipeline."""
    if "offsets" not in sec:
        return None
    value = sec.data["offsets"]
    if isinstance(value, str):
        return sec.string("offsets", choices=OFFSET_MODES)
    if not isinstance(value, dict):
        raise sec.error("offsets", f"offsets in {sec.label} must be \"estimate\", \"report\" "
                                   f"or a table of frames per camera",
                        hint='e.g. offsets = { cam_03 = 1 }')
    sub = sec.table("offsets")
    out = {}
    for name, v in value.items():
        if isinstance(v, bool) or not isinstance(v, (int, float)) or v != v or abs(v) == float(
                "inf"):
            raise sub.error(name, f"offset of camera {name} in {sub.label} must be a number of "
                                  f"frames, not {v!r}",
                            hint=f"e.g. {name} = 1 (its frame f + 1 shows frame f of the "
                                 f"others; fractional: interpolated)")
        out[name] = float(v)
    return out


def read_mocap_project(prj: Path, src: TomlSource, root: Section) -> Project:
    """Read a motion-capture project (module doc)."""
    from photogram.project.reader_sections import _read_output, _read_project_section
    from photogram.project.reader_tables import _read_stations
    for name in _FORBIDDEN:
        if name in root.data:
            raise root.error(name, f"[{name}] has no meaning in a motion-capture project",
                             hint="remove it; the detections are given in [mocap.source]")
    root.table("project")
    project = Project(path=prj, sources={"project": prj})
    _read_project_section(root.table("project"), project)
    project.output = _read_output(root.table("output", required=False))
    mocap = _read_mocap(root.table("mocap"), prj.parent, src)
    cams, stations = root.table("cameras", required=False), root.table("stations",
                                                                       required=False)
    if mocap.calibration is not None and (cams is not None or stations is not None):
        raise root.error("cameras" if cams is not None else "stations",
                         "give the cameras either in calibration or in [cameras] and "
                         "[stations], not both")
    if mocap.calibration is None:
        if cams is None or stations is None:
            raise root.error("mocap", "a motion-capture project needs its cameras: "
                                      "calibration = \"Calib.toml\" in [mocap], or [cameras] "
                                      "and [stations]")
        if not cams.data:
            raise cams.error(None, "[cameras] has no cameras")
        for name in cams.data:
            cam = read_camera(cams.table(name), name, image_unit=project.units.image,
                              folder=project.folder)
            project.cameras[name] = cam
        project.stations = _read_stations(stations, project)
        project.points = Points()
    project.mocap = mocap
    return project
