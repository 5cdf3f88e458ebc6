"""Render the photographs of the lab frame and its target-field description.

The lab project (../lab) is simulated (projects/generate.py); this script photographs
its true frame with its true cameras and stations (photogram's brown model):
retro-reflective dots (16 mm) on black plates, and ArUco markers (70 mm,
DICT_4X4_50) on nine points spread over the base plate and the post tops,
so that `photogram measure projects/lab/frame.toml` can number the frame
from the markers and measure it. The field description gives the markers
and the uncoded targets with the project's approximate coordinates
(../lab/lab_points.csv, truth + ~1 cm), never the truth. (It lives beside
projects/lab, not in it: the files of projects/lab are all written by
projects/generate.py and checked by tests/test_designs.py.)

Run (writes images/*.jpg, JPEG quality 92, and frame.toml beside this script):

    .venv/bin/python projects/lab-photos/render_images.py
"""

from pathlib import Path

import cv2
import numpy as np

from photogram.measure.scenes import (_rows, choose_markers, field_description, read_truth,
                                      render_project)

HERE = Path(__file__).resolve().parent
LAB = HERE.parent / "lab"


def main():
    truth = read_truth(LAB / "truth")
    markers = choose_markers(truth["points"])
    images = render_project(truth, markers, seed=20250101)
    (HERE / "images").mkdir(exist_ok=True)
    for name, img in images.items():
        cv2.imwrite(str(HERE / "images" / f"{name}.jpg"), img,
                    [cv2.IMWRITE_JPEG_QUALITY, 92])
    approx = {r["id"]: np.array([float(r["X"]), float(r["Y"]), float(r["Z"])])
              for r in _rows(LAB / "lab_points.csv")}
    (HERE / "frame.toml").write_text(field_description(
        markers, approx, points_file="../lab/lab_points.csv", images="images"))
    print(f"{len(images)} images and frame.toml written; coded points: {', '.join(markers)}")


if __name__ == "__main__":
    main()
