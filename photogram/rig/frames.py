"""Board detections of every camera from videos or image folders, and the
frames worth calibrating from.

* **Frames.** A video is read one frame every ``step`` seconds (frames in
  between are grabbed, not decoded); an image folder takes every image.
  A frame's id is its number in the video (as text) or the image's stem,
  and means the same instant in every camera.
* **Sharpness.** The variance of the Laplacian over the board's bounding
  box (Pech-Pacheco et al. 2000), relative to the camera's median over its
  detections: a detection below ``min_sharpness`` of the median (motion
  blur) is left out, as Pose2Sim and caliscope leave out blurred board
  views.
* **Coverage.** With more frames than ``max_frames``, frames are chosen
  greedily: each time the frame whose corners fall in the most cells of
  an 8 x 6 grid over each camera's image not yet covered (ties: seen by
  more cameras, then more corners), so that the corners spread over every
  image (the principal point and the distortion need the image's edges).
"""

from __future__ import annotations

import collections
import logging
from pathlib import Path

import numpy as np

from photogram.errors import InputError

log = logging.getLogger("photogram")

__all__ = ["board_sharpness", "read_camera", "select_frames", "read_rig"]

GRID = (8, 6)


def board_sharpness(gray: np.ndarray, xy: np.ndarray) -> float:
    """Variance of the Laplacian of ``gray`` over the bounding box of the
    corners ``xy`` (n, 2)."""
    import cv2
    h, w = gray.shape[:2]
    x0, y0 = np.clip(np.floor(xy.min(0)).astype(int) - 2, 0, [w - 1, h - 1])
    x1, y1 = np.clip(np.ceil(xy.max(0)).astype(int) + 3, 1, [w, h])
    box = gray[y0:y1, x0:x1]
    if box.size < 9:
        return 0.0
    return float(cv2.Laplacian(box, cv2.CV_64F).var())


def _video_frames(path: Path, step: float):
    """(id, gray image) every ``step`` seconds of a video, and its fps and
    frame count."""
    import cv2
    cap = cv2.VideoCapture(str(path))
    if not cap.isOpened():
        raise InputError("cannot open this video", file=path,
                         hint="a damaged file or a codec OpenCV cannot read; or give a folder "
                              "of images")
    fps = float(cap.get(cv2.CAP_PROP_FPS) or 0.0)
    n = int(cap.get(cv2.CAP_PROP_FRAME_COUNT) or 0)
    every = max(1, int(round(step * fps))) if fps > 0 else 1

    def frames():
        i = 0
        try:
            while True:
                if i % every == 0:
                    ok, img = cap.read()
                    if not ok:
                        break
                    yield str(i), cv2.cvtColor(img, cv2.COLOR_BGR2GRAY) if img.ndim == 3 \
                        else img
                elif not cap.grab():
                    break
                i += 1
        finally:
            cap.release()
    return frames(), fps, n


def _found(gray: np.ndarray, target) -> tuple:
    """(image size (w, h), the board's detection or None, its sharpness or
    None) of one frame."""
    from photogram.io.targets import detect
    hit = detect(gray, target)
    return ((gray.shape[1], gray.shape[0]), hit,
            None if hit is None else board_sharpness(gray, hit[1]))


#: :func:`_found` of the image files read in this process, by (path, size,
#: modification time (ns), inode, target): a board project calibrated again
#: (another floor frame, scene points) does not decode and detect its
#: images again; the detection is deterministic. The last ``_FILES_SIZE``.
_FILES: collections.OrderedDict = collections.OrderedDict()
_FILES_SIZE = 4096


def _folder_found(path: Path, target):
    """(id, :func:`_found`) of every image of a folder (:data:`_FILES`)."""
    import cv2

    from photogram.io.targets import image_files
    from photogram.project.limits import check_image
    for f in image_files(path):
        st = f.stat()
        key = (str(f.resolve()), st.st_size, st.st_mtime_ns, st.st_ino, target)
        if key in _FILES:
            _FILES.move_to_end(key)
        else:
            check_image(f)
            img = cv2.imread(str(f), cv2.IMREAD_GRAYSCALE)
            if img is None:
                raise InputError("cannot read this image", file=f,
                                 hint="a damaged or unsupported image file")
            _FILES[key] = _found(img, target)
            while len(_FILES) > _FILES_SIZE:
                _FILES.popitem(last=False)
        size, hit, sharp = _FILES[key]
        yield f.stem, (size, None if hit is None else (hit[0].copy(), hit[1].copy()), sharp)


def read_camera(name: str, path: Path, target, *, step: float = 0.2,
                min_sharpness: float = 0.3) -> dict:
    """Detect the board in one camera's video or image folder.

    Returns
    -------
    dict with ``detections`` {frame id: (ids, xy)}, ``sharpness`` {frame
    id: value}, ``image_size`` (w, h), ``fps`` (0 for images), ``frames``
    (read), ``blurred`` (ids left out for sharpness)
    """
    path = Path(path)
    if path.is_dir():
        found, fps, n = _folder_found(path, target), 0.0, None
    else:
        frames, fps, n = _video_frames(path, step)
        found = ((fid, _found(gray, target)) for fid, gray in frames)
    dets, sharp, size, count = {}, {}, None, 0
    for fid, (s, hit, sharpness) in found:
        count += 1
        if size is None:
            size = s
        elif s != size:
            raise InputError(f"camera {name}: frame {fid} is {s[0]} x {s[1]} px, the first "
                             f"{size[0]} x {size[1]}", file=path,
                             hint="one camera, one image size")
        if hit is None:
            continue
        dets[fid] = hit
        sharp[fid] = sharpness
    if count == 0:
        raise InputError(f"camera {name}: no frame could be read", file=path,
                         hint="check the video file or the image folder")
    blurred = []
    if sharp and min_sharpness > 0:
        med = float(np.median(list(sharp.values())))
        blurred = [f for f, v in sharp.items() if v < min_sharpness * med]
        for f in blurred:
            dets.pop(f)
    return {"detections": dets, "sharpness": sharp, "image_size": size, "fps": fps,
            "frames": count, "frame_count": n, "blurred": blurred}


def select_frames(detections: dict, image_sizes: dict, max_frames: int,
                  keep=()) -> list:
    """Frame ids chosen for coverage (module doc); ``keep``: ids always
    chosen (the floor frame)."""
    ids = sorted({f for d in detections.values() for f in d})
    if len(ids) <= max_frames:
        return ids
    cells = {}
    for f in ids:
        cs = set()
        for c, d in detections.items():
            if f in d:
                w, h = image_sizes[c]
                xy = d[f][1]
                gx = np.clip((xy[:, 0] / w * GRID[0]).astype(int), 0, GRID[0] - 1)
                gy = np.clip((xy[:, 1] / h * GRID[1]).astype(int), 0, GRID[1] - 1)
                cs |= {(c, int(a), int(b)) for a, b in zip(gx, gy)}
        cells[f] = cs
    n_cam = {f: sum(f in d for d in detections.values()) for f in ids}
    n_pts = {f: sum(len(d[f][0]) for d in detections.values() if f in d) for f in ids}
    chosen = [f for f in keep if f in cells]
    covered = set().union(*(cells[f] for f in chosen)) if chosen else set()
    left = [f for f in ids if f not in chosen]
    while len(chosen) < max_frames and left:
        best = max(left, key=lambda f: (len(cells[f] - covered), n_cam[f], n_pts[f]))
        chosen.append(best)
        covered |= cells[best]
        left.remove(best)
    return sorted(chosen, key=ids.index)


def read_rig(cameras: dict, target, *, step: float = 0.2, min_sharpness: float = 0.3,
             max_frames: int = 150, keep=()) -> dict:
    """Every camera's detections (:func:`read_camera`), checked for equal
    frame rates, and the frames chosen (:func:`select_frames`).

    Returns
    -------
    dict with ``detections`` {camera: {frame: (ids, xy)}} of the chosen
    frames, ``image_sizes``, ``per_camera`` (what :func:`read_camera`
    returned, without the detections) and ``chosen`` (frame ids)
    """
    per = {}
    for name, path in cameras.items():
        per[name] = read_camera(name, path, target, step=step, min_sharpness=min_sharpness)
    rates = {n: p["fps"] for n, p in per.items() if p["fps"] > 0}
    if rates:
        ref = next(iter(rates))
        for n, r in rates.items():
            if abs(r - rates[ref]) > 1e-3 * rates[ref]:
                raise InputError(f"camera {n}: its video runs at {r:g} frames/s, camera {ref}'s "
                                 f"at {rates[ref]:g}", file=cameras[n],
                                 hint="the frames of a board project are the same instants "
                                      "in every camera: convert the videos to one frame rate")
    for n, p in per.items():
        if not p["detections"]:
            raise InputError(f"camera {n}: the board is not found in any of its {p['frames']} "
                             "frame(s) read", file=cameras[n],
                             hint="check [board] target (squares and markers, dictionary) and "
                                  "that this camera sees the board; or leave the camera out")
    dets = {n: p["detections"] for n, p in per.items()}
    sizes = {n: p["image_size"] for n, p in per.items()}
    chosen = select_frames(dets, sizes, max_frames, keep)
    keep_set = set(chosen)
    dets = {n: {f: v for f, v in d.items() if f in keep_set} for n, d in dets.items()}
    info = {n: {k: v for k, v in p.items() if k != "detections"} for n, p in per.items()}
    return {"detections": dets, "image_sizes": sizes, "per_camera": info, "chosen": chosen}
