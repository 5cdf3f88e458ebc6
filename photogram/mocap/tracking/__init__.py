"""The athlete in each camera: the candidate detections of a camera
(``detections``: the data every observation source gives) and the
tracking of section 4.1 (``athlete``: main-person selection, crop boxes,
crops for the image detectors).

May import :mod:`photogram.mocap.body`; never the sources (which call the
tracking), the reconstruction, or the modules above them. Empty on
purpose: importing the package loads no module.
"""
