"""Write the normal and the harsh jump video sets into a folder:

    python -m photogram.simulation.jump_video FOLDER [--overwrite]

gives ``FOLDER/normal`` and ``FOLDER/harsh`` (layout of
:func:`photogram.simulation.jump_video.write_jump_videos`).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from photogram.simulation.jump_video import (
    VideoSettings, harsh_settings, render_jump_videos, write_jump_videos)


def main(argv=None) -> int:
    """Render and write both sets; print the time each took."""
    ap = argparse.ArgumentParser(prog="python -m photogram.simulation.jump_video",
                                 description=__doc__.splitlines()[0])
    ap.add_argument("folder", type=Path)
    ap.add_argument("--overwrite", action="store_true", help="replace existing sets")
    args = ap.parse_args(argv)
    if not args.overwrite:
        existing = [str(args.folder / n) for n in ("normal", "harsh")
                    if (args.folder / n).exists()]
        if existing:
            ap.error(f"{', '.join(existing)} exist (--overwrite replaces them)")
    for name, settings in (("normal", VideoSettings()), ("harsh", harsh_settings())):
        t0 = time.perf_counter()
        videos = render_jump_videos(settings)
        out = write_jump_videos(videos, args.folder / name, overwrite=args.overwrite)
        print(f"{out}: {videos.n_frames} frames x 3 cameras in "
              f"{time.perf_counter() - t0:.1f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
