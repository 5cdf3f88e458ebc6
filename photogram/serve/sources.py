"""The views of ``photogram measure --serve``: which image shows which
station (and exposure), read once, kept in memory, and sent as PNG.

Photographs: the image of a station is the file of the images folder whose
stem is the station name (as ``photogram measure`` names its stations,
docs/measure.md); the folder is ``--images DIR``, else the ``images`` of
``--field``, else ``images/`` beside the project file. Videos (a ``[track]``
project): the frame of each exposure of the station's video
(:mod:`photogram.track.video`).

A view is addressed by its id (``K1a``, or ``001/S1`` for exposure 001 of
station S1) from the server's own list; a file name from a request is never
used as a path. An image that cannot be read makes its view ``ok = false``
with the one-line reason (shown on the page), not a failure of the server.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from photogram.errors import InputError, PhotogramError
from photogram.io.targets import IMAGE_SUFFIXES

__all__ = ["View", "ImageStore", "still_views", "read_colour", "read_frame"]

_FRAME_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp", ".pgm")

_CHANNEL = {"blue": 0, "green": 1, "red": 2}

#: bytes of decoded images (and, separately, of PNG data) kept in memory
CACHE_BYTES = 512 * 2 ** 20


@dataclass
class View:
    """One image of the page."""

    id: str
    station: str
    exposure: str | None = None
    path: Path | None = None          # photographs: the image file
    frame: int | None = None          # videos: the frame number
    video: Path | None = None
    width: int = 0
    height: int = 0
    error: str | None = None

    @property
    def ok(self) -> bool:
        return self.error is None

    def json(self) -> dict:
        return {"id": self.id, "station": self.station, "exposure": self.exposure,
                "width": int(self.width), "height": int(self.height), "ok": self.ok,
                "error": self.error}


def read_colour(path: Path) -> np.ndarray:
    """An image file as 8-bit BGR (h, w, 3), with the checks of
    :func:`photogram.measure.pipeline.read_image` (a one-line
    :class:`InputError` for an unreadable, damaged or truncated file)."""
    import cv2
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise InputError(f"cannot read image {path}: {exc.strerror}",
                         hint="check the file and its permissions") from None
    if path.suffix.lower() in (".jpg", ".jpeg") and not data.rstrip(b"\0").endswith(b"\xff\xd9"):
        raise InputError(f"cannot read image {path}: truncated JPEG (no end-of-image marker)",
                         hint="copy the image again")
    img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR) if data else None
    if img is None:
        raise InputError(f"cannot read image {path}: damaged or not an image",
                         hint="replace the file")
    return img


def read_frame(path, frame: int) -> np.ndarray:
    """Frame ``frame`` (0-based) of a video file or an image folder as BGR
    uint8 (h, w, 3); a one-line :class:`InputError` if it cannot be read."""
    import cv2
    path = Path(path)
    if path.is_dir():
        files = sorted(p for p in path.iterdir() if p.suffix.lower() in _FRAME_SUFFIXES)
        if not 0 <= frame < len(files):
            raise InputError(f"cannot read frame {frame} of {path}: the folder has "
                             f"{len(files)} frames")
        return read_colour(files[frame])
    cap = cv2.VideoCapture(str(path))
    try:
        if not cap.isOpened():
            raise InputError(f"cannot read video {path}: OpenCV cannot open it",
                             hint="convert it to AVI/MJPG or to a folder of PNG frames")
        n = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
        if frame < 0 or (n > 0 and frame >= n):
            raise InputError(f"cannot read frame {frame} of video {path} ({n} frames)")
        cap.set(cv2.CAP_PROP_POS_FRAMES, frame)
        ok, img = cap.read()
    finally:
        cap.release()
    if not ok or img is None:
        raise InputError(f"cannot read frame {frame} of video {path}")
    return img


def still_views(stations, folder: Path, sizes: dict | None = None) -> list[View]:
    """A view per station whose image is in ``folder`` (by stem), in the
    stations' order; stations without an image get a view with the error.

    ``sizes``: station -> (width, height) from the cameras, used when the
    image cannot be read.
    """
    folder = Path(folder)
    files = {}
    if folder.is_dir():
        for p in sorted(folder.iterdir()):
            if p.suffix.lower() in IMAGE_SUFFIXES:
                files.setdefault(p.stem, p)
    views = []
    for st in stations:
        v = View(id=st, station=st, path=files.get(st))
        if v.path is None:
            v.error = (f"no image for station {st} in {folder} (expected {st}.jpg or another "
                       f"image ending)")
        w, h = (sizes or {}).get(st) or (0, 0)
        v.width, v.height = int(w), int(h)
        views.append(v)
    return views


class _Recent:
    """The most recently used entries up to ``budget`` bytes (at least one)."""

    def __init__(self, budget: int):
        self.budget = budget
        self.items: OrderedDict = OrderedDict()

    def get(self, key):
        value = self.items.get(key)
        if value is not None:
            self.items.move_to_end(key)
        return value

    def put(self, key, value) -> None:
        self.items[key] = value
        self.items.move_to_end(key)
        while len(self.items) > 1 and sum(v.nbytes if hasattr(v, "nbytes") else len(v)
                                          for v in self.items.values()) > self.budget:
            self.items.popitem(last=False)


class ImageStore:
    """Decoded images and their PNG bytes, per view id, read on first use
    and kept while they fit in :data:`CACHE_BYTES` each (the most recently
    used; thread-safe: the server has one thread per request)."""

    def __init__(self, views: list[View]):
        self.views = {v.id: v for v in views}
        self._bgr = _Recent(CACHE_BYTES)
        self._png = _Recent(CACHE_BYTES)
        self._lock = threading.Lock()

    def check_all(self) -> None:
        """Read every image once: sizes and errors of the views (of a video
        only the first view, so that a recording that cannot be opened is
        said at once; the other frames are read when shown)."""
        seen = set()
        for v in self.views.values():
            if v.video is not None:
                if v.video in seen:
                    continue
                seen.add(v.video)
            if v.ok:
                try:
                    self.bgr(v.id)
                except PhotogramError as exc:
                    v.error = exc.one_line()

    def bgr(self, view_id: str) -> np.ndarray:
        """The image of a view as BGR uint8 (h, w, 3)."""
        with self._lock:
            img = self._bgr.get(view_id)
        if img is not None:
            return img
        v = self.views[view_id]
        if v.error is not None:
            raise InputError(v.error)
        if v.video is not None:
            img = read_frame(v.video, v.frame)
        else:
            img = read_colour(v.path)
        v.height, v.width = img.shape[:2]
        with self._lock:
            self._bgr.put(view_id, img)
        return img

    def gray(self, view_id: str, channel: str = "green") -> np.ndarray:
        """One channel (the target field's, default green) as uint8 (h, w)."""
        img = self.bgr(view_id)
        if channel == "gray":
            import cv2
            return cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
        return np.ascontiguousarray(img[:, :, _CHANNEL.get(channel, 1)])

    def png(self, view_id: str) -> bytes:
        """PNG bytes of the full-resolution image (colour kept)."""
        with self._lock:
            data = self._png.get(view_id)
        if data is not None:
            return data
        import cv2
        ok, buf = cv2.imencode(".png", self.bgr(view_id), [cv2.IMWRITE_PNG_COMPRESSION, 1])
        if not ok:
            raise InputError(f"cannot encode the image of view {view_id} as PNG")
        data = buf.tobytes()
        with self._lock:
            self._png.put(view_id, data)
        return data
