"""The cameras' motion: frame-to-frame rotations of pan-tilt-zoom cameras
measured from their images (``homography``: eqs. (12)-(13); ``lens``:
exact radial undistortion; ``video``: video files and image folders),
their filter, check and files (``rotation_series``), the project glue of
``rotation = "estimate"`` (``unknown_rotations``), and the model of a
rotation trajectory with its prior E_rot (``camera_motion``: eq. (14)).

Imports no other part of :mod:`photogram.mocap` (nor the simulation, whose
renderer uses ``lens``). Empty on purpose: importing the package loads no
module (OpenCV is imported by the modules that need it).
"""
