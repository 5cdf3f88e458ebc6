"""From a folder of images and a target field to image observations.

Per image: read (bad or truncated files are an :class:`InputError` naming
the file), take the field's channel, detect and measure the circular
targets (:mod:`photogram.measure.detect`), decode the ring codes
(:mod:`photogram.measure.codes`), number the uncoded targets from the codes
(:mod:`photogram.measure.label`), measure the targets the layout predicts
but the detector missed (:mod:`photogram.measure.guided`; for a 3D field,
after all images, from the network: :mod:`photogram.measure.network`),
optionally
correct the eccentricity of
the projected circle centre (:mod:`photogram.measure.eccentricity`, with
the image's plane homography and the field's target diameter).

**Pixel convention of the output.** The detectors work in OpenCV's frame
(pixel centres at integers). The observations are written in the
*corner* convention of photogram's image frame, DBAT and PhotoModeler: the
top-left corner of the image is (0, 0) and the first pixel's centre is
(0.5, 0.5), so that ``x_mm = x_px * pixel_size`` from the corner of the
format holds (docs/camera-models.md). That is ``+0.5 px`` on both axes.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from photogram.errors import InputError
from photogram.io.targets import IMAGE_SUFFIXES, image_files   # one list of image endings
from photogram.measure.aruco import detect_markers, inside_quads
from photogram.measure.codes import decode_rings, ring_profiles
from photogram.measure.detect import Detections, detect_targets
from photogram.measure.eccentricity import eccentricity
from photogram.measure.field import TargetField
from photogram.measure.guided import guided_measure
from photogram.measure.label import Numbering, number_plane
from photogram.measure.network import refine_space
from photogram.measure.space import number_space

__all__ = ["ImageResult", "Measurement", "read_image", "measure_image", "measure_images",
           "IMAGE_SUFFIXES", "PIXEL_OFFSET"]

log = logging.getLogger("photogram")

PIXEL_OFFSET = 0.5          # OpenCV frame -> corner convention
_CHANNEL = {"blue": 0, "green": 1, "red": 2}


@dataclass
class ImageResult:
    """Everything measured in one image."""

    name: str
    detections: Detections
    code_label: np.ndarray          # per detection: code id, "" plain, None rejected ring
    numbering: Numbering
    xy: np.ndarray                  # corrected centres, corner convention (n, 2)
    sigma: np.ndarray               # centre sigma per detection (px)
    seconds: float = 0.0

    def counts(self) -> dict:
        """Detections, numbered, codes decoded and rejected, blobs rejected per reason."""
        lab = self.numbering.labels
        c = self.detections.counts()
        c["numbered"] = int(sum(1 for v in lab if v))
        c["codes"] = int(sum(1 for v in self.code_label if v))
        c["code_rejected"] = int(sum(1 for v in self.code_label if v is None))
        c["unnumbered"] = c["accepted"] - c["numbered"] - c["code_rejected"]
        return c


@dataclass
class Measurement:
    """The result of :func:`measure_images`."""

    field: TargetField
    images: list[ImageResult] = field(default_factory=list)

    def table(self) -> list[tuple[str, str, float, float, float]]:
        """Observations ``(station, point, x, y, sigma)``: numbered targets only."""
        rows = []
        for im in self.images:
            for i, lab in enumerate(im.numbering.labels):
                if lab:
                    rows.append((im.name, str(lab), float(im.xy[i, 0]), float(im.xy[i, 1]),
                                 float(im.sigma[i])))
        return rows

    def problems(self) -> list[str]:
        return [p for im in self.images for p in im.numbering.problems]


def read_image(path: Path, channel: str = "green") -> np.ndarray:
    """One channel of an image as uint8 (h, w).

    Raises
    ------
    InputError
        The file cannot be read, is not an image, or a JPEG is truncated
        (no end-of-image marker).
    """
    import cv2
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise InputError(f"cannot read this image: {exc.strerror}", file=path,
                         hint="check the file and its permissions") from None
    if path.suffix.lower() in (".jpg", ".jpeg") and not data.rstrip(b"\0").endswith(b"\xff\xd9"):
        raise InputError("truncated JPEG (no end-of-image marker)", file=path,
                         hint="copy the image again or remove it from the folder")
    buf = np.frombuffer(data, np.uint8)
    flag = cv2.IMREAD_GRAYSCALE if channel == "gray" else cv2.IMREAD_COLOR
    img = cv2.imdecode(buf, flag) if len(buf) else None
    if img is None:
        raise InputError("cannot decode this image (damaged or not an image)", file=path,
                         hint="remove it from the folder or replace it")
    if img.ndim == 3:
        img = np.ascontiguousarray(img[:, :, _CHANNEL[channel]])
    return img


def measure_image(gray: np.ndarray, fld: TargetField, name: str = "",
                  eccentricity_correction: bool = True, guided: bool = True) -> ImageResult:
    """Detect, decode, number and correct one image (module doc)."""
    t0 = time.perf_counter()
    t = (255.0 - gray.astype(np.float32)) if fld.polarity == "dark" else gray.astype(np.float32)
    # of uint8 grey levels, t is detect_targets' own image (exact integers)
    det = detect_targets(gray, fld.polarity, min_diameter=fld.min_diameter,
                         max_diameter=fld.max_diameter, min_contrast=fld.min_contrast,
                         bright=t if np.asarray(gray).dtype == np.uint8 else None)
    marker_problems = []
    if fld.aruco_dictionary:
        det, m_xy, m_quads, m_points, marker_problems = _markers(gray, det, fld, name)
    if len(det) and fld.codes:
        ring, inside, valid = ring_profiles(t, det.xy, det.axes, det.angle,
                                            det.extra["background"], det.contrast,
                                            radii=fld.code_radii)
        code_label, _ = decode_rings(ring, inside, valid, fld.codes)
    else:
        code_label = np.full(len(det), "", dtype=object)
    if fld.aruco_dictionary and len(m_points):
        det = _append_markers(det, m_xy, m_quads, fld.aruco_sigma)
        code_label = np.concatenate([code_label, np.array(m_points, object)])
    if fld.spatial:
        ids, cXYZ = fld.coded3()
        num = number_space(det.xy, code_label, ids, cXYZ, fld.target_ids, fld.target_xyz,
                           (gray.shape[1], gray.shape[0]), image=name)
        guided = eccentricity_correction = False   # 3D: after the network (measure_images)
    else:
        ids, cXY = fld.coded()
        num = number_plane(det.xy, code_label, ids, cXY, fld.grid_ids, fld.grid_xy,
                           fld.spacing, image=name)
    num.problems[:0] = marker_problems
    if guided and num.homography is not None and not num.conflicts and fld.diameter > 0:
        det, num.labels, code_label, num.homography = guided_measure(
            t, det, num.labels, code_label, num.homography, fld)
    xy = det.xy.copy()
    is_marker = det.extra.get("marker", np.zeros(len(det), bool))
    if len(is_marker) < len(det):
        is_marker = np.concatenate([is_marker, np.zeros(len(det) - len(is_marker), bool)])
    if eccentricity_correction and fld.diameter > 0 and num.homography is not None:
        ids_all, XY_all = fld.layout()
        pos = {k: i for i, k in enumerate(ids_all)}
        lab = num.labels
        sel = np.array([bool(v) and v in pos for v in lab], bool)
        if sel.any():
            XY = XY_all[[pos[v] for v in lab[sel]]]
            H = _refit(XY, det.xy[sel], num.homography)
            circ = sel & ~is_marker
            xy[circ] -= eccentricity(H, XY_all[[pos[v] for v in lab[circ]]], fld.diameter / 2)
    sigma = np.sqrt(det.sigma ** 2 + fld.sigma_floor ** 2)
    return ImageResult(name, det, code_label, num, xy + PIXEL_OFFSET, sigma,
                       time.perf_counter() - t0)


def _markers(gray, det, fld, name):
    """ArUco markers of the field in an image; circle detections on them rejected."""
    m_ids, quads, centres = detect_markers(gray, fld.aruco_dictionary)
    problems = []
    keep = []
    for k, mid in enumerate(m_ids):
        if mid not in fld.markers:
            continue
        if np.sum(m_ids == mid) > 1:
            problems.append(f"{name}: ArUco marker {mid} seen {int(np.sum(m_ids == mid))} "
                            f"times; none of them used")
            continue
        keep.append(k)
    on = inside_quads(det.xy, quads) if len(quads) else np.zeros(len(det), bool)
    if on.any():
        d = det.subset(~on)
        d.rejected_xy = np.vstack([det.rejected_xy.reshape(-1, 2), det.xy[on]])
        d.rejected_reason = np.concatenate([det.rejected_reason,
                                            np.full(int(on.sum()), "marker")])
        d.extra["background"] = det.extra["background"][~on]
        det = d
    keep = np.array(keep, int)
    return (det, centres[keep], quads[keep], [fld.markers[int(m)] for m in m_ids[keep]],
            problems)


def _append_markers(det, xy, quads, sigma):
    cat = np.concatenate
    n = len(xy)
    side = np.linalg.norm(quads - np.roll(quads, 1, axis=1), axis=2).mean(axis=1)
    extra = dict(det.extra)
    extra["background"] = cat([det.extra["background"], np.full(n, np.nan)])
    extra["marker"] = cat([det.extra.get("marker", np.zeros(len(det), bool)), np.ones(n, bool)])
    if "guided" in extra:
        extra["guided"] = cat([extra["guided"], np.zeros(n, bool)])
    return Detections(cat([det.xy, xy]), cat([det.xy_centroid, np.full((n, 2), np.nan)]),
                      cat([det.axes, np.column_stack([side / 2, side / 2])]),
                      cat([det.angle, np.zeros(n)]), cat([det.contrast, np.full(n, np.nan)]),
                      cat([det.residual, np.zeros(n)]), cat([det.sigma, np.full(n, sigma)]),
                      cat([det.n_edge, np.full(n, 4)]), det.rejected_xy, det.rejected_reason,
                      det.image_size, extra)


def _match_uncoded(images: list[ImageResult], fld: TargetField) -> None:
    """A 3D field without a table of targets: the plain detections of the
    images oriented by their codes are matched across views
    (:func:`photogram.measure.epipolar.match_tracks`) and numbered U0001...;
    then the tracks serve as the field's table for the network step
    (:func:`photogram.measure.network.refine_space`), which orients the
    images with too few codes (PnP) and numbers what the matching missed."""
    from photogram.measure.epipolar import match_tracks
    idx, pts, Ps = [], [], []
    for res in images:
        plain = np.array([i for i in range(len(res.detections))
                          if res.code_label[i] == "" and not res.numbering.labels[i]], int)
        idx.append(plain)
        pts.append(res.detections.xy[plain] if len(plain) else np.zeros((0, 2)))
        P = res.numbering.homography
        Ps.append(P if P is not None and P.shape == (3, 4) else None)
    labels, xyz = match_tracks(pts, Ps)
    for res, plain, lab in zip(images, idx, labels):
        for i, v in zip(plain, lab):
            if v:
                res.numbering.labels[i] = v
    if xyz:
        import copy
        tracks = copy.copy(fld)
        tracks.target_ids = list(xyz)
        tracks.target_xyz = np.array(list(xyz.values()))
        tracks.target_normal = None
        refine_space(images, tracks)


def _eccentricity_3d(res: ImageResult, fld: TargetField) -> None:
    """Eccentricity correction of the numbered circles of a 3D field: each
    target's plane (its point and normal) is mapped to the image by the
    homography ``H = [P (e1, 0), P (e2, 0), P (X, 1)]`` of the image's DLT
    projection matrix P (from the numbered targets), and the eccentricity of
    its circle is subtracted (:func:`photogram.measure.eccentricity.eccentricity`)."""
    from photogram.errors import GeometryError
    from photogram.init.dlt import dlt
    pos = {k: i for i, k in enumerate(fld.target_ids)}
    lab = res.numbering.labels
    sel = np.array([i for i, v in enumerate(lab) if v in pos], int)
    if len(sel) < 6:
        return
    X = fld.target_xyz[[pos[lab[i]] for i in sel]]
    try:
        P = dlt(X, res.detections.xy[sel])
    except GeometryError:
        return
    if fld.shape == "ball":
        res.xy[sel] -= _ball_eccentricity(P, X, fld.diameter / 2)
        return
    for i, Xi in zip(sel, X):
        n = fld.target_normal[pos[lab[i]]]
        up = np.array([0.0, 0.0, 1.0]) if abs(n[2]) < 0.9 else np.array([0.0, 1.0, 0.0])
        e1 = np.cross(up, n)
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(n, e1)
        H = np.column_stack([P[:, :3] @ e1, P[:, :3] @ e2, P[:, :3] @ Xi + P[:, 3]])
        res.xy[i] -= eccentricity(H, np.zeros((1, 2)), fld.diameter / 2)[0]


def _ball_eccentricity(P: np.ndarray, X: np.ndarray, radius: float) -> np.ndarray:
    """Outline centre minus image of the centre of balls at X (n, 3) for the
    projection matrix P (decomposed into K [R | -R C];
    :func:`photogram.measure.sphere.ball_eccentricity`)."""
    import cv2
    from photogram.measure.sphere import ball_eccentricity
    P = P / np.linalg.norm(P[2, :3])
    if np.median(X @ P[2, :3] + P[2, 3]) < 0:        # points in front: positive depth
        P = -P
    K, R, C = cv2.decomposeProjectionMatrix(P)[:3]
    D = np.diag(np.where(np.diag(K) < 0, -1.0, 1.0))      # K with a positive diagonal
    K, R = K @ D, D @ R
    C = C[:3, 0] / C[3, 0]
    K = K / K[2, 2]
    return np.array([ball_eccentricity(K, R @ (Xi - C), radius) for Xi in X])


def _refit(XY, xy, H0):
    import cv2
    if len(XY) >= 4:
        H, _ = cv2.findHomography(XY.astype(np.float64), xy.astype(np.float64), 0)
        if H is not None:
            return H
    return H0


def measure_images(fld: TargetField, folder=None, *, eccentricity_correction: bool = True,
                   progress=None) -> Measurement:
    """Measure every image of ``folder`` (default: the field's ``images``).

    ``progress(result, gray)`` is called after each image (e.g. to draw it).

    Raises
    ------
    InputError
        No folder given, empty folder, an unreadable image, codes that
        disagree with the layout in an image, or a field that numbers
        nothing in any image.
    """
    folder = folder if folder is not None else fld.images
    if folder is None:
        raise InputError("which images?", file=fld.path,
                         hint="give images = \"folder\" in [field] or --images FOLDER")
    files = image_files(folder)
    out = Measurement(fld)
    size = None
    for path in files:
        gray = read_image(path, fld.channel)
        s = gray.shape
        if size is None:
            size = s
        elif s != size:
            log.warning("%s: image size %d x %d differs from the first image's", path.name,
                        s[1], s[0])
        res = measure_image(gray, fld, path.stem, eccentricity_correction)
        if res.numbering.conflicts:
            raise InputError(res.numbering.conflicts[0], file=path,
                             hint="check the code bits and coordinates of the target-field "
                                  "description against the sheet")
        out.images.append(res)
        if progress:
            progress(res, gray)
    if fld.spatial and fld.target_ids:
        refine_space(out.images, fld)
        if eccentricity_correction and fld.diameter > 0 and (
                fld.target_normal is not None or fld.shape == "ball"):
            for res in out.images:
                _eccentricity_3d(res, fld)
    elif fld.spatial:
        _match_uncoded(out.images, fld)
    if not out.table():
        raise InputError(f"the target field numbers no target in any of the {len(files)} "
                         f"image(s)", file=fld.path,
                         hint="check polarity, the diameter range in px and the code bits "
                              "against one image (docs/measure.md)")
    return out
