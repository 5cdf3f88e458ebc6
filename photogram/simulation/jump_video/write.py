"""Writing the rendered videos and their truth to a folder, atomically."""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

from photogram.simulation.jump_video.settings import STATIONS

__all__ = ["write_jump_videos", "read_video", "FOURCC"]

FOURCC = "MJPG"


def _write_avi(path: Path, frames: np.ndarray, fps: float) -> None:
    """Grey frames as an MJPG AVI (OpenCV's own MJPEG writer, BGR: its
    grey-scale mode does not read back correctly)."""
    import cv2
    h, w = frames.shape[1:]
    writer = cv2.VideoWriter(str(path), cv2.CAP_OPENCV_MJPEG, cv2.VideoWriter_fourcc(*FOURCC),
                             float(fps), (w, h), True)
    if not writer.isOpened():
        raise RuntimeError(f"cannot open an MJPG writer for {path}")
    for f in frames:
        writer.write(cv2.cvtColor(f, cv2.COLOR_GRAY2BGR))
    writer.release()


def read_video(path) -> np.ndarray:
    """All frames of a video file as a (F, h, w) uint8 grey array."""
    import cv2
    cap = cv2.VideoCapture(str(path))
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

    Files: ``S1.avi``, ``S2.avi``, ``S3.avi`` (MJPG, ``fps``), ``seeds.csv``
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
                _write_avi(tmp / f"{st}.avi", videos.frames[st], videos.fps)
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
