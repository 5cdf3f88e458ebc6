"""Markerless multi-camera motion capture (alpine skiing; docs/mocap.md).

After Bachmann et al., "Motion Capture from Pan-Tilt Cameras with Unknown
Orientation" (part 1: known camera rotations; part 2: unknown rotations):

| module | concern |
|---|---|
| ``skeleton`` | the 24-joint ski skeleton, detector skeletons, mappings |
| ``anthropometry`` | de Leva (1996) segment masses and centres of mass |
| ``sources`` | observation sources: OpenPose/Pose2Sim JSON, CSV, mediapipe, plugin |
| ``tracking`` | athlete tracking and crops (section 4.1), main-person selection |
| ``cameras`` | fixed and pan-tilt-zoom cameras (rotations per frame) |
| ``dct`` | DCT trajectories and windows (eq. (1)) |
| ``energy`` | robust reprojection energy and limb prior (eqs. (7)-(10)) |
| ``solvers`` | Gauss-Newton/IRLS with PCG (default) and L-BFGS |
| ``reconstruct`` | the reconstruction of a sequence (sections 4.3-4.4) |
| ``metrics`` | PCK, MPJPE, CoM, speed, joint angles, lean, fore/aft (appendix C) |
| ``camera_motion`` | camera rotations as Euler-angle DCTs, E_rot (eq. (14)) |
| ``joint``, ``joint_solver`` | the joint pose and rotation energy, dense per-window LM |
| ``bootstrap``, ``bearings`` | the start with unknown rotations (paper's rounds, the athlete's path) |
| ``estimate``, ``unknown_rotations`` | poses and rotations together; project glue |
| ``homography``, ``rotation_series`` | rotation differences from images (eqs. (12)-(13)), filter, files |
| ``video`` | video files and image folders (OpenCV) |
| ``render``, ``scene``, ``texture``, ``lens``, ``backdrop``, ``simimages`` | rendered camera images of the simulator |
| ``simulate``, ``skier``, ``simproject`` | the simulated giant-slalom runs |
| ``files``, ``pipeline``, ``outputs`` | project tables, the pipeline, the results folder |
"""
