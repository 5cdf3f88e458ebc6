"""Automatic measurement of targets in photographs (``photogram measure``).

From a folder of images and a target-field description to the observation
table of a project (``image_points.csv`` with a sigma per observation):

* :mod:`~photogram.measure.detect` — circular targets (dark on light, bright
  on dark), blob tests, rejections counted by reason
* :mod:`~photogram.measure.centre` — subpixel centres: ellipse fit to
  subpixel edge points (kept) and the grey-value weighted centroid
* :mod:`~photogram.measure.ellipse` — direct least-squares ellipse fit, conics
* :mod:`~photogram.measure.codes` — ring-coded targets (PhotoModeler sheet)
* :mod:`~photogram.measure.field` — the target-field description (TOML)
* :mod:`~photogram.measure.label` — numbering from the codes by homography
* :mod:`~photogram.measure.eccentricity` — eccentricity of projected circle
  centres and its Jacobian
* :mod:`~photogram.measure.pipeline` — images -> observations
* :mod:`~photogram.measure.render` — rendered target fields with known truth

See docs/measure.md.
"""
