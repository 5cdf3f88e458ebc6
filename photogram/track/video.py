"""Frames of the synchronized cameras: video files or image-sequence folders.

A station's recording is either a video file that OpenCV reads
(``cv2.VideoCapture``: AVI/MJPG, MP4, ...) or a folder of numbered images
(``000000.png``, ``000001.png``, ...; PNG, JPEG, TIFF, BMP), read in the
sorted order of their names. Colour frames are converted to grey
(``cv2.COLOR_BGR2GRAY``, ITU-R BT.601 weights), since the markers are
found by brightness alone.

The cameras of a jump run at one frame rate and were started together
(up to the integer offsets of :mod:`photogram.track.sync`), so their
recordings must have the same number of frames and the same rate:
:func:`check_videos` refuses anything else with one line naming the file.
The frame rates may differ by ``fps_tolerance`` (relative, default 0.1 %:
containers round 30000/1001 differently); an image folder has no rate
(NaN) and is not compared.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from photogram.errors import InputError

__all__ = ["read_frames", "check_videos", "read_videos", "IMAGE_SUFFIXES"]

#: image files an image-sequence folder may hold
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp", ".pgm")


def _grey(img: np.ndarray) -> np.ndarray:
    import cv2
    if img.ndim == 3:
        if img.shape[2] == 4:
            img = cv2.cvtColor(img, cv2.COLOR_BGRA2GRAY)
        else:
            img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    if img.dtype != np.uint8:
        # 16-bit images: keep the upper 8 bits (the markers are the brightest)
        img = (img >> 8).astype(np.uint8) if img.dtype == np.uint16 \
            else np.clip(np.rint(img), 0, 255).astype(np.uint8)
    return img


def _read_folder(path: Path, fps: float | None) -> tuple[np.ndarray, float]:
    import cv2
    files = sorted(p for p in path.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)
    if not files:
        raise InputError("folder holds no images", file=path,
                         hint="an image sequence is 000000.png, 000001.png, ... "
                              f"({', '.join(IMAGE_SUFFIXES)})")
    frames = []
    for f in files:
        img = cv2.imread(str(f), cv2.IMREAD_UNCHANGED)
        if img is None:
            raise InputError("not a readable image", file=f,
                             hint="re-export the frame or remove it from the folder")
        img = _grey(img)
        if frames and img.shape != frames[0].shape:
            raise InputError(f"frame is {img.shape[1]}x{img.shape[0]} px, the first "
                             f"frame of the folder {frames[0].shape[1]}x{frames[0].shape[0]}",
                             file=f, hint="all frames of a camera have one size")
        frames.append(img)
    return np.stack(frames), float("nan") if fps is None else float(fps)


def _read_video(path: Path) -> tuple[np.ndarray, float]:
    import cv2
    cap = cv2.VideoCapture(str(path))
    try:
        if not cap.isOpened():
            raise InputError("OpenCV cannot open this video", file=path,
                             hint="convert it to AVI/MJPG or to a folder of PNG frames")
        fps = float(cap.get(cv2.CAP_PROP_FPS))
        frames = []
        while True:
            ok, img = cap.read()
            if not ok:
                break
            frames.append(_grey(img))
    finally:
        cap.release()
    if not frames:
        raise InputError("the video has no readable frame", file=path,
                         hint="convert it to AVI/MJPG or to a folder of PNG frames")
    return np.stack(frames), fps if fps > 0 else float("nan")


def read_frames(path, fps: float | None = None) -> tuple[np.ndarray, float]:
    """All frames of one camera as grey images (module doc).

    Parameters
    ----------
    path : str or Path
        A video file or a folder of numbered images.
    fps : float, optional
        Frame rate of an image folder (NaN when not given); ignored for a
        video file, whose container gives it.

    Returns
    -------
    frames : (F, H, W) uint8
    fps : float
        Frames per second (NaN if unknown).

    Raises
    ------
    InputError
        The path does not exist, is not readable, or its frames differ in size.
    """
    p = Path(path)
    if not p.exists():
        raise InputError("no such video file or image folder", file=p,
                         hint="give S1.avi or a folder S1/ with 000000.png, ...")
    if p.is_dir():
        return _read_folder(p, fps)
    return _read_video(p)


def check_videos(videos: dict, files: dict | None = None,
                 fps_tolerance: float = 1e-3) -> float:
    """Check that the recordings of all stations fit together (module doc).

    Parameters
    ----------
    videos : dict station -> (frames (F, H, W), fps)
        As :func:`read_frames` returns them.
    files : dict station -> path, optional
        The files, for the messages (the station name otherwise).
    fps_tolerance : float
        Largest accepted relative difference of the frame rates.

    Returns
    -------
    float
        The common frame rate (NaN if no recording knows it).

    Raises
    ------
    InputError
        One line naming the first recording whose frame count, frame size or
        frame rate differs from the first station's, and the fix.
    """
    if not videos:
        raise InputError("no videos given", hint="one video per station: S1.avi S2.avi S3.avi")
    files = files or {}
    names = list(videos)
    ref = names[0]
    ref_frames, ref_fps = videos[ref]
    where = {s: files.get(s, s) for s in names}
    for s in names[1:]:
        fr, fps = videos[s]
        if fr.shape[1:] != ref_frames.shape[1:]:
            raise InputError(f"frames are {fr.shape[2]}x{fr.shape[1]} px, those of "
                             f"{where[ref]} {ref_frames.shape[2]}x{ref_frames.shape[1]}",
                             file=where[s], hint="all cameras of a jump record one format")
        if len(fr) != len(ref_frames):
            raise InputError(f"{len(fr)} frames, {where[ref]} has {len(ref_frames)}",
                             file=where[s],
                             hint="cut the synchronized recordings to the same frames "
                                  "(the sync offsets are estimated afterwards)")
        if np.isfinite(fps) and np.isfinite(ref_fps) \
                and abs(fps - ref_fps) > fps_tolerance * ref_fps:
            raise InputError(f"{fps:g} frames/s, {where[ref]} has {ref_fps:g}",
                             file=where[s],
                             hint="the cameras must run at one frame rate; resample "
                                  "the video or re-export it at the common rate")
    rates = [f for _, f in videos.values() if np.isfinite(f)]
    return float(rates[0]) if rates else float("nan")


def read_videos(paths: dict, fps: float | None = None,
                fps_tolerance: float = 1e-3) -> tuple[dict, float]:
    """:func:`read_frames` for every station, then :func:`check_videos`.

    Parameters
    ----------
    paths : dict station -> path
    fps : float, optional
        Frame rate of image folders.

    Returns
    -------
    frames : dict station -> (F, H, W) uint8
    fps : float
    """
    videos = {s: read_frames(p, fps) for s, p in paths.items()}
    rate = check_videos(videos, {s: str(p) for s, p in paths.items()}, fps_tolerance)
    return {s: v[0] for s, v in videos.items()}, rate
