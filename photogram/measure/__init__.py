"""Automatic measurement of targets in photographs (``photogram measure``).

From a folder of images and a target-field description to the observation
table of a project (``image_points.csv`` with a sigma per observation):

* :mod:`~photogram.measure.detect` — circular targets (dark on light, bright
  on dark), blob tests, rejections counted by reason
* :mod:`~photogram.measure.centre` — subpixel centres: ellipse fit to
  subpixel edge points (kept) and the grey-value weighted centroid
* :mod:`~photogram.measure.ellipse` — direct least-squares ellipse fit, conics
* :mod:`~photogram.measure.codes` — ring-coded targets (PhotoModeler sheet)
* :mod:`~photogram.measure.aruco` — ArUco markers (centre from re-measured corners)
* :mod:`~photogram.measure.field` — the target-field description (TOML)
* :mod:`~photogram.measure.label` — numbering a plane from its codes (homography)
* :mod:`~photogram.measure.space` — numbering a 3D field from its codes (DLT)
* :mod:`~photogram.measure.network` — 3D fields: numbering again from the
  network over all images (resection / intersection)
* :mod:`~photogram.measure.guided` — guided measurement of missed targets (plane)
* :mod:`~photogram.measure.bundle_guided` — guided measurement from a bundle
  adjustment (adjusted cameras with lens distortion), iterated
* :mod:`~photogram.measure.eccentricity` — eccentricity of projected circle
  centres and its Jacobian
* :mod:`~photogram.measure.sphere` — balls: outline of a sphere, its eccentricity
* :mod:`~photogram.measure.pipeline` — images -> observations
* :mod:`~photogram.measure.report` — drawings and report.pdf of a measurement
* :mod:`~photogram.measure.render`, :mod:`~photogram.measure.render3d`,
  :mod:`~photogram.measure.scenes` — rendered images with known truth
  (planes, 3D target plates, a simulated project's frame)

See docs/measure.md.
"""
