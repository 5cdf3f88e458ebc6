"""Writing the rendered videos and their truth to a folder, atomically;
reading the videos back."""

from __future__ import annotations

import os
import shutil
import struct
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

from photogram.simulation.jump_video.settings import STATIONS

__all__ = ["write_jump_videos", "read_video", "mjpg_avi", "FOURCC"]

FOURCC = "MJPG"


def _chunk(fourcc: bytes, data: bytes) -> bytes:
    return fourcc + struct.pack("<I", len(data)) + data + (b"\0" if len(data) % 2 else b"")


def _list(kind: bytes, body: bytes) -> bytes:
    return b"LIST" + struct.pack("<I", len(body) + 4) + kind + body


def mjpg_avi(jpegs, size, fps: float) -> bytes:
    """An AVI file (RIFF, one MJPG video stream, idx1 index, every frame a
    key frame) holding the given JPEG images unchanged.

    The frames are the renderer's own JPEGs (one grey component): decoding
    the file gives exactly the rendered frames with OpenCV's MJPEG reader
    (``cv2.CAP_OPENCV_MJPEG``) and within 1 grey level with FFmpeg's
    (OpenCV's default): no second compression. (OpenCV's ``VideoWriter``
    re-encodes at a fixed quality and its grey-scale mode does not read
    back correctly.)
    """
    w, h = size
    n, big = len(jpegs), max(len(j) for j in jpegs)
    avih = struct.pack("<14I", int(round(1e6 / fps)), int(big * fps), 0, 0x10, n, 0, 1, big,
                       w, h, 0, 0, 0, 0)
    strh = (b"vids" + FOURCC.encode() + struct.pack("<IHHIIIIIIII", 0, 0, 0, 0, 1000,
                                                    int(round(fps * 1000)), 0, n, big,
                                                    0xFFFFFFFF, 0)
            + struct.pack("<4h", 0, 0, w, h))
    strf = struct.pack("<IiiHH4sIiiII", 40, w, h, 1, 24, FOURCC.encode(), w * h * 3, 0, 0, 0, 0)
    hdrl = _list(b"hdrl", _chunk(b"avih", avih)
                 + _list(b"strl", _chunk(b"strh", strh) + _chunk(b"strf", strf)))
    movi, index, offset = [], [], 4
    for j in jpegs:
        c = _chunk(b"00dc", j)
        index.append(b"00dc" + struct.pack("<III", 0x10, offset, len(j)))
        offset += len(c)
        movi.append(c)
    body = (b"AVI " + hdrl + _list(b"movi", b"".join(movi)) + _chunk(b"idx1", b"".join(index)))
    return b"RIFF" + struct.pack("<I", len(body)) + body


def _write_avi(path: Path, frames: np.ndarray, jpegs, fps: float) -> None:
    """The frames as an MJPG AVI: their JPEG bytes where the renderer kept
    them, else encoded at quality 100."""
    from photogram.simulation.jump_video.render import compress
    data = [j if j is not None else compress(f, 0)[1]
            for f, j in zip(frames, jpegs or [None] * len(frames))]
    path.write_bytes(mjpg_avi(data, (frames.shape[2], frames.shape[1]), fps))


def read_video(path, api=None) -> np.ndarray:
    """All frames of a video file as a (F, h, w) uint8 grey array.

    ``api``: an OpenCV capture backend; default OpenCV's own MJPEG reader
    for ``.avi`` (bit-exact for the files written here), else any.
    """
    import cv2
    if api is None:
        api = cv2.CAP_OPENCV_MJPEG if str(path).lower().endswith(".avi") else cv2.CAP_ANY
    cap = cv2.VideoCapture(str(path), api)
    if not cap.isOpened():
        raise RuntimeError(f"cannot read {path}")
    out = []
    while True:
        ok, img = cap.read()
        if not ok:
            break
        out.append(img[..., 1] if img.ndim == 3 else img)
    cap.release()
    return np.stack(out) if out else np.zeros((0, 0, 0), np.uint8)


def _csv(df: pd.DataFrame, path: Path) -> None:
    df.to_csv(path, index=False, float_format="%.4f")


def write_jump_videos(videos, folder, *, overwrite: bool = False) -> Path:
    """Write ``videos`` (a :class:`JumpVideos`) into ``folder``.

    Files: ``S1.avi``, ``S2.avi``, ``S3.avi`` (MJPG, ``fps``: the rendered
    frames' own JPEGs, :func:`mjpg_avi`), ``seeds.csv``
    (station, frame, marker, x, y), ``frames.csv`` (exposure "001".., frame
    for offset 0), ``truth/markers.csv``, ``truth/skis.csv``,
    ``truth/targets.csv`` (images of the static ball targets),
    ``truth/offsets.csv`` (station, offset) and ``truth/settings.txt``.
    The folder is built beside ``folder`` under a temporary name and renamed
    at the end: it appears whole or not at all.

    Raises
    ------
    FileExistsError
        If ``folder`` exists and ``overwrite`` is False (with ``overwrite``
        the old folder is replaced only after the new one is complete).
    """
    folder = Path(folder)
    if folder.exists() and not overwrite:
        raise FileExistsError(f"{folder} exists (pass overwrite=True to replace it)")
    folder.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{folder.name}.", dir=folder.parent))
    try:
        (tmp / "truth").mkdir()
        for st in STATIONS:
            if st in videos.frames:
                _write_avi(tmp / f"{st}.avi", videos.frames[st], videos.encoded.get(st),
                           videos.fps)
        s = videos.settings
        n = len(videos.exposure_frames[STATIONS[0]])
        _csv(pd.DataFrame({"exposure": [f"{e + 1:03d}" for e in range(n)],
                           "frame": s.lead_in + np.arange(n)}), tmp / "frames.csv")
        _csv(videos.seeds, tmp / "seeds.csv")
        _csv(videos.truth_markers, tmp / "truth" / "markers.csv")
        _csv(videos.truth_skis, tmp / "truth" / "skis.csv")
        _csv(videos.truth_targets, tmp / "truth" / "targets.csv")
        _csv(pd.DataFrame({"station": list(videos.offsets),
                           "offset": list(videos.offsets.values())}),
             tmp / "truth" / "offsets.csv")
        (tmp / "truth" / "settings.txt").write_text(repr(s) + "\n")
        os.chmod(tmp, 0o755)
        if folder.exists():
            old = folder.with_name(f".{folder.name}.old")
            if old.exists():
                shutil.rmtree(old)
            folder.rename(old)
            tmp.rename(folder)
            shutil.rmtree(old)
        else:
            tmp.rename(folder)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return folder
