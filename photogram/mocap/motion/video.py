"""Reading camera images: a video file or a folder of images.

A *video* is any file OpenCV's ``cv2.VideoCapture`` opens (the FFmpeg
backend of opencv-python: .mp4, .avi, .mov, .mkv, ...); a *folder* holds one
image per frame (.png .jpg .jpeg .bmp .tif .tiff), in name order with
numbers compared as numbers (``img2`` before ``img10``). Frames are yielded
as BGR uint8 arrays, one at a time (a long video is never held in memory).
Bad input (a missing path, a file OpenCV cannot read, a folder without
images, an unreadable image) raises :class:`~photogram.errors.InputError`
naming the file, never a traceback.
"""

from __future__ import annotations

import re
from pathlib import Path

import cv2
import numpy as np

from photogram.errors import InputError
from photogram.project.limits import check_frame_size, check_image

__all__ = ["IMAGE_EXTENSIONS", "image_files", "read_frames", "count_frames"]

IMAGE_EXTENSIONS = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")


def _natural(name: str):
    return [int(part) if part.isdigit() else part.lower()
            for part in re.split(r"(\d+)", name)]


def image_files(folder) -> list[Path]:
    """The images of a folder in name order (numbers as numbers).

    Raises
    ------
    InputError
        The folder holds no image.
    """
    folder = Path(folder)
    files = sorted((p for p in folder.iterdir()
                    if p.is_file() and p.suffix.lower() in IMAGE_EXTENSIONS),
                   key=lambda p: _natural(p.name))
    if not files:
        raise InputError("the folder holds no images", file=folder,
                         hint="expected " + " ".join(IMAGE_EXTENSIONS) + " files, one per frame")
    return files


def _exists(path) -> Path:
    path = Path(path)
    if not path.exists():
        raise InputError("no such video file or image folder", file=path,
                         hint="give a video (e.g. .mp4, .avi) or a folder of images")
    return path


def _open(path: Path):
    cap = cv2.VideoCapture(str(path))
    if not cap.isOpened():
        cap.release()
        raise InputError("OpenCV cannot read this video", file=path,
                         hint="check the file (codec, truncation) or convert it, e.g. to "
                              "H.264 .mp4 or MJPG .avi")
    try:
        check_frame_size(cap.get(cv2.CAP_PROP_FRAME_WIDTH), cap.get(cv2.CAP_PROP_FRAME_HEIGHT),
                         path, what="video frame")
    except InputError:
        cap.release()
        raise
    return cap


def count_frames(path) -> int:
    """Number of frames of a video file or image folder.

    For a video the container's frame count; if the container does not
    know it, the frames are counted by reading them.
    """
    path = _exists(path)
    if path.is_dir():
        return len(image_files(path))
    cap = _open(path)
    try:
        n = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
        if n > 0:
            return n
        n = 0
        while cap.grab():
            n += 1
    finally:
        cap.release()
    if n == 0:
        raise InputError("the video has no frames", file=path)
    return n


def _wanted(frames):
    if frames is None:
        return None
    wanted = sorted({int(f) for f in frames})
    if wanted and wanted[0] < 0:
        raise InputError(f"negative frame number {wanted[0]}")
    return wanted


def read_frames(path, frames=None):
    """Yield the frames (BGR uint8 (H, W, 3)) of a video file or image folder.

    Parameters
    ----------
    path : str or Path
        A video file or a folder of images.
    frames : iterable of int, optional
        0-based frame numbers to read (in increasing order, each once);
        all frames if None.

    Raises
    ------
    InputError
        Missing path, unreadable video or image, folder without images, or
        a requested frame beyond the end.
    """
    path = _exists(path)
    wanted = _wanted(frames)
    if path.is_dir():
        files = image_files(path)
        index = range(len(files)) if wanted is None else wanted
        for i in index:
            if i >= len(files):
                raise InputError(f"frame {i} requested, the folder has {len(files)} images",
                                 file=path)
            yield _read_image(files[i])
        return
    yield from _read_video(path, wanted)


def _read_image(file: Path) -> np.ndarray:
    check_image(file)              # before decoding: a header may claim gigapixels
    try:
        img = cv2.imread(str(file), cv2.IMREAD_COLOR)
    except cv2.error:
        img = None
    if img is None:
        raise InputError("OpenCV cannot read this image", file=file,
                         hint="check that it is a valid image file")
    return img


def _read_video(path: Path, wanted):
    """Sequential decoding (grab() skips the conversion of unwanted frames;
    no seeking, which is not frame-accurate with every codec)."""
    cap = _open(path)
    try:
        if wanted is None:
            k = 0
            while True:
                ok, img = cap.read()
                if not ok:
                    if k == 0:
                        raise InputError("the video has no readable frames", file=path)
                    return
                yield img
                k += 1
        k = 0
        for target in wanted:
            while k < target:
                if not cap.grab():
                    raise InputError(f"frame {target} requested, the video has {k} frames",
                                     file=path)
                k += 1
            ok, img = cap.read()
            if not ok:
                raise InputError(f"frame {target} requested, the video has {k} frames",
                                 file=path)
            yield img
            k += 1
    finally:
        cap.release()
