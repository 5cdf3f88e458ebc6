"""Image sequences for the image detectors: a folder of image files (in
name order) or a video file, read with OpenCV as RGB arrays."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from photogram.errors import InputError
from photogram.project.limits import check_frame_size, check_image

__all__ = ["ImageSequence", "IMAGE_SUFFIXES", "check_frame_rates"]

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")


class ImageSequence:
    """Frames of a folder of images or of a video; iterable more than once."""

    #: frames per second of a video (0: unknown, or a folder of images)
    fps = 0.0

    def __init__(self, path: Path):
        self.path = Path(path)
        if self.path.is_dir():
            self.files = sorted(p for p in self.path.iterdir()
                                if p.suffix.lower() in IMAGE_SUFFIXES)
            if not self.files:
                raise InputError("no image files in the folder", file=self.path,
                                 hint="expected " + ", ".join(IMAGE_SUFFIXES))
            self._n = len(self.files)
        elif self.path.is_file():
            import cv2
            cap = cv2.VideoCapture(str(self.path))
            if not cap.isOpened():
                raise InputError("cannot open the video", file=self.path)
            self._n = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
            self.fps = float(cap.get(cv2.CAP_PROP_FPS) or 0.0)
            cap.release()
            self.files = None
        else:
            raise InputError("image folder or video not found", file=self.path)

    def __len__(self) -> int:
        return self._n

    def __iter__(self):
        import cv2
        if self.files is not None:
            for f in self.files:
                check_image(f)     # before decoding: a header may claim gigapixels
                try:
                    img = cv2.imread(str(f), cv2.IMREAD_COLOR)
                except cv2.error:
                    img = None
                if img is None:
                    raise InputError("cannot read the image", file=f)
                yield cv2.cvtColor(img, cv2.COLOR_BGR2RGB)
            return
        cap = cv2.VideoCapture(str(self.path))
        try:
            check_frame_size(cap.get(cv2.CAP_PROP_FRAME_WIDTH),
                             cap.get(cv2.CAP_PROP_FRAME_HEIGHT), self.path, "video frame")
            while True:
                ok, img = cap.read()
                if not ok:
                    break
                yield cv2.cvtColor(img, cv2.COLOR_BGR2RGB)
        finally:
            cap.release()


def as_uint8_rgb(image) -> np.ndarray:
    img = np.asarray(image)
    if img.ndim == 2:
        img = np.repeat(img[..., None], 3, axis=2)
    return img.astype(np.uint8, copy=False)


def check_frame_rates(images: dict, fps: float, error) -> None:
    """Every video runs at the project's frame rate (``[mocap] fps``): the
    frames of the cameras are the same instants. ``error(keypath, what,
    hint)`` makes the one-line InputError (the setting's)."""
    for camera, seq in images.items():
        if seq.fps > 0 and abs(seq.fps - fps) > 1e-3 * fps:
            raise error(("source", "cameras"),
                        f"camera {camera}: its video {seq.path.name} runs at {seq.fps:g} "
                        f"frames/s, the project at fps = {fps:g}",
                        hint="convert the videos to one frame rate (e.g. ffmpeg -r), or set "
                             "[mocap] fps if it is wrong")
