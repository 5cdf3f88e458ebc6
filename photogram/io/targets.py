"""Camera calibration from images of a planar target: chessboard, ChArUco
board or circle grid, detected with OpenCV, turned into a project for
``photogram calibrate``.

Target descriptions (``parse_target``; sizes in the project's length unit,
metres by default)::

    chessboard:COLSxROWS:SQUARE                  inner corners, e.g. chessboard:9x6:0.025
    charuco:SQUARESXxSQUARESY:SQUARE:MARKER[:DICT]   e.g. charuco:7x5:0.04:0.03:DICT_5X5_100
    circles:COLSxROWS:SPACING                    symmetric circle grid
    acircles:COLSxROWS:SPACING                   asymmetric grid (OpenCV's layout)

Detection: ``cv2.findChessboardCorners`` + ``cv2.cornerSubPix`` (window 11
x 11, stopped at 1e-4 px / 100 iterations; a corner that cornerSubPix
returns unchanged, because its iterate left the window, is left out with a
warning), ``cv2.aruco.CharucoDetector``
(its corners are refined by OpenCV), ``cv2.findCirclesGrid`` (blob centres).

The project: one camera (``opencv``: fx fy cx cy k1 k2 p1 p2 k3 free, or
``brown``: c x0 y0 K1 K2 K3 P1 P2 B1 free), one station per image in which
the target was found (named by the file stem), the target's points as
**fixed control** (the target is the datum: ``datum = "control"``, sigma
0), the detections as image points (sigma ``sigma_image``, 0.1 px by
default; it scales sigma0, not the estimates or the a-posteriori sigmas).
Approximate values: OpenCV's closed-form start (``cv2.initCameraMatrix2D``,
Zhang's homography method) for the focal length and ``cv2.solvePnP`` for the
stations, so the adjustment starts near the solution.

The target's points have ids ``0 .. n-1`` in OpenCV's order (row by row;
ChArUco: the board's corner ids) and coordinates ``(x, y, 0)``: the board
plane is Z = 0.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from photogram.errors import InputError
from photogram.project.limits import check_image

__all__ = ["Target", "parse_target", "detect", "detect_folder", "images_project",
           "IMAGE_SUFFIXES", "image_files"]

log = logging.getLogger("photogram")

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp", ".pgm", ".ppm")
KINDS = ("chessboard", "charuco", "circles", "acircles")


@dataclass(frozen=True)
class Target:
    """A planar calibration target (see the module doc)."""

    kind: str
    cols: int
    rows: int
    size: float
    marker: float = 0.0
    dictionary: str = "DICT_5X5_100"

    def object_points(self) -> np.ndarray:
        """(n, 3) coordinates of the target's points, in id order."""
        if self.kind == "chessboard" or self.kind == "circles":
            r, c = np.mgrid[0:self.rows, 0:self.cols]
            xy = np.column_stack([c.ravel(), r.ravel()]) * self.size
        elif self.kind == "acircles":
            r, c = np.mgrid[0:self.rows, 0:self.cols]
            xy = np.column_stack([(2 * c + r % 2).ravel(), r.ravel()]) * self.size
        else:
            xy = np.asarray(self.board().getChessboardCorners(), float)[:, :2]
        return np.column_stack([xy, np.zeros(len(xy))])

    def board(self):
        """The cv2.aruco.CharucoBoard of a ChArUco target."""
        import cv2
        dic = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, self.dictionary))
        return cv2.aruco.CharucoBoard((self.cols, self.rows), self.size, self.marker, dic)


def parse_target(spec: str) -> Target:
    """A :class:`Target` from its description (module doc).

    Raises
    ------
    InputError
        Unknown kind, malformed size, non-positive dimensions, unknown
        ArUco dictionary.
    """
    import cv2
    hint = ("e.g. chessboard:9x6:0.025, charuco:7x5:0.04:0.03:DICT_5X5_100, "
            "circles:4x11:0.02, acircles:4x11:0.02")
    parts = [p.strip() for p in str(spec).split(":")]
    if parts[0] not in KINDS:
        raise InputError(f"unknown target kind {parts[0]!r} in {spec!r}",
                         hint=f"one of {', '.join(KINDS)}; {hint}")
    need = 4 if parts[0] == "charuco" else 3
    if len(parts) < need or len(parts) > need + (1 if parts[0] == "charuco" else 0):
        raise InputError(f"target {spec!r} needs {need} fields", hint=hint)
    try:
        cols, rows = (int(v) for v in parts[1].lower().split("x"))
        size = float(parts[2])
        marker = float(parts[3]) if parts[0] == "charuco" else 0.0
    except ValueError:
        raise InputError(f"cannot read the target {spec!r}", hint=hint) from None
    if cols < 2 or rows < 2 or not size > 0 or parts[0] == "charuco" and not 0 < marker < size:
        raise InputError(f"target {spec!r}: at least 2 x 2, positive sizes (marker smaller than "
                         f"the square)", hint=hint)
    dictionary = parts[4] if len(parts) > 4 else "DICT_5X5_100"
    if parts[0] == "charuco" and not hasattr(cv2.aruco, dictionary):
        raise InputError(f"unknown ArUco dictionary {dictionary!r}",
                         hint="e.g. DICT_4X4_50, DICT_5X5_100, DICT_6X6_250")
    return Target(parts[0], cols, rows, size, marker, dictionary)


def _gray(image):
    import cv2
    image = np.asarray(image)
    if image.ndim == 3:
        image = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    if image.dtype != np.uint8:
        image = cv2.normalize(image, None, 0, 255, cv2.NORM_MINMAX).astype(np.uint8)
    return image


def detect(image, target: Target) -> tuple[np.ndarray, np.ndarray] | None:
    """Detected target points in one image: ``(ids (k,), xy (k, 2))`` in
    pixels (OpenCV's frame: pixel centres at integers), or None."""
    import cv2
    gray = _gray(image)
    if target.kind == "chessboard":
        ok, corners = cv2.findChessboardCorners(
            gray, (target.cols, target.rows),
            cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE)
        if not ok:
            return None
        crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 100, 1e-4)
        start = corners.reshape(-1, 2).astype(float)
        corners = cv2.cornerSubPix(gray, corners.copy(), (11, 11), (-1, -1), crit)
        xy = corners.reshape(-1, 2).astype(float)
        # cornerSubPix returns the start unchanged when its iterate leaves the
        # window: the corner was not refined (and the start may be pixels off)
        keep = np.any(xy != start, axis=1)
        if not keep.all():
            log.warning("%d chessboard corner(s) not refined by cornerSubPix (ids %s): "
                        "left out", int((~keep).sum()),
                        ", ".join(str(i) for i in np.flatnonzero(~keep)))
        return np.flatnonzero(keep), xy[keep]
    if target.kind in ("circles", "acircles"):
        flag = cv2.CALIB_CB_SYMMETRIC_GRID if target.kind == "circles" else \
            cv2.CALIB_CB_ASYMMETRIC_GRID
        ok, centres = cv2.findCirclesGrid(gray, (target.cols, target.rows), flags=flag)
        if not ok:
            return None
        return np.arange(len(centres)), centres.reshape(-1, 2).astype(float)
    detector = cv2.aruco.CharucoDetector(target.board())
    corners, ids, _, _ = detector.detectBoard(gray)
    if ids is None or len(ids) < 6:
        return None
    return ids.ravel().astype(int), corners.reshape(-1, 2).astype(float)


def image_files(folder) -> list[Path]:
    """The image files of a folder (by their ending, IMAGE_SUFFIXES), sorted
    by name.

    Raises
    ------
    InputError
        Not a folder, or no image in it.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise InputError("not a folder of images", file=folder,
                         hint="give the folder holding the photographs")
    files = sorted(p for p in folder.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)
    if not files:
        raise InputError("no images in the folder", file=folder,
                         hint=f"image files end with {', '.join(IMAGE_SUFFIXES)}")
    return files


def detect_folder(folder, target: Target):
    """Detect the target in every image of ``folder``.

    Returns
    -------
    names : list of str          image stems with a detection
    detections : list of (ids, xy)
    image_size : (w, h)
    missed : list of str          images without a detection
    """
    import cv2
    folder = Path(folder)
    names, found, missed, size = [], [], [], None
    for path in image_files(folder):
        check_image(path)          # before decoding: a header may claim gigapixels
        try:
            image = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
        except cv2.error:
            image = None
        if image is None:
            raise InputError("cannot read this image", file=path,
                             hint="a damaged or unsupported image file")
        s = (image.shape[1], image.shape[0])
        if size is None:
            size = s
        elif s != size:
            raise InputError(f"image size {s[0]} x {s[1]} differs from the first image's "
                             f"{size[0]} x {size[1]}", file=path,
                             hint="one camera, one image size: calibrate each camera apart")
        hit = detect(image, target)
        if hit is None:
            missed.append(path.stem)
            continue
        names.append(path.stem)
        found.append(hit)
    if missed:
        log.warning("target not found in %d image(s): %s", len(missed), ", ".join(missed))
    if len(names) < 3:
        raise InputError(f"the target was found in {len(names)} image(s); a calibration "
                         f"needs at least 3", file=folder,
                         hint="check the target description (inner corners for a chessboard)")
    return names, found, size, missed


def _start(obj, detections, size):
    """OpenCV's closed-form start: K from homographies, poses by PnP."""
    import cv2
    objs = [obj[ids].astype(np.float32) for ids, _ in detections]
    imgs = [xy.astype(np.float32).reshape(-1, 1, 2) for _, xy in detections]
    K = cv2.initCameraMatrix2D(objs, imgs, size)
    poses = []
    for o, x in zip(objs, imgs):
        ok, rvec, tvec = cv2.solvePnP(o, x, K, None)
        if not ok:
            raise InputError("cannot find a start for a station (solvePnP failed)")
        poses.append((rvec.ravel(), tvec.ravel()))
    return K, poses


def images_project(folder, target, *, model: str = "opencv", name: str | None = None,
                   sigma_image: float = 0.1, length_unit: str = "m"):
    """A calibration project from a folder of target images (module doc).

    Returns
    -------
    Project
        To be written with :func:`photogram.io.exchange.save_project` and
        adjusted with ``photogram calibrate``.
    """
    from photogram.geometry import opencv_to_brown, rodrigues_to_matrix
    from photogram.io.exchange import build_project, cv_to_station, opencv_camera
    folder = Path(folder)
    if isinstance(target, str):
        target = parse_target(target)
    if model not in ("opencv", "brown"):
        raise InputError(f"unknown camera model {model!r}", hint="opencv or brown")
    names, dets, size, _ = detect_folder(folder, target)
    obj = target.object_points()
    K, poses = _start(obj, dets, size)
    camera = opencv_camera("camera", K, None, size, source=str(folder), free=True)
    if model == "brown":
        from photogram.project.model import Parameter
        values = opencv_to_brown(camera.values())
        camera.model = "brown"
        camera.parameters = {n: Parameter(value=float(v), free=n != "B2") for n, v in
                             zip(("c", "x0", "y0", "K1", "K2", "K3", "P1", "P2", "B1", "B2"),
                                 values)}
    stations = [cv_to_station(rodrigues_to_matrix(r), t) for r, t in poses]
    obs_st, obs_pt, obs_xy = [], [], []
    for n, (ids, xy) in zip(names, dets):
        obs_st += [n] * len(ids)
        obs_pt += [str(i) for i in ids]
        obs_xy.append(xy)
    used = sorted({int(p) for p in obs_pt})
    return build_project(name or f"{folder.name}_calibration", {"camera": camera},
                         stations=names, station_camera=["camera"] * len(names),
                         angles=np.array([s[0] for s in stations]),
                         X0=np.array([s[1] for s in stations]),
                         point_ids=[str(i) for i in used], kinds=["control"] * len(used),
                         xyz=obj[used], point_sigma=np.zeros((len(used), 3)),
                         obs_station=obs_st, obs_point=obs_pt, obs_xy=np.vstack(obs_xy),
                         length_unit=length_unit, datum="control", sigma_image=sigma_image)
