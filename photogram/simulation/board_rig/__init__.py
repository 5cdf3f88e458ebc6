"""Rendered test data for multi-camera calibration from a ChArUco board
(issue 20, item 1): a board waved through a capture volume seen by 4-6
cameras, with known truth.

What is simulated
-----------------
* **Cameras** (:func:`rig_cameras`): around a capture volume of 3 x 3 x 2 m
  (floor at Z = 0, world Z up, centre ``VOLUME_CENTRE`` = (0, 0, 1) m), at
  2-6 m from the centre, 1-3 m high, each looking at a point within 0.3 m of
  the centre (roll within 3 deg). OpenCV model: fx 900-1400 px for a 1280 px
  wide image (scaled with the width), fy = fx within 0.5 %, principal point
  within 3 % of the image centre, k1 -0.2..0.1, k2 -0.05..0.1, p1 p2 within
  1e-3, k3 within 0.02, drawn again until the radial distortion is
  invertible out to 1.5 times the image corner's radius. Extrinsics in
  OpenCV's convention: ``x_cam = R X + t``.
* **Board poses** (:func:`board_poses`): ``X_world = R_bw X_board + t_bw``.
  **Pose 0 lies flat on the floor**, printed face up: ``R_bw = Rz diag(1,
  -1, -1)`` with Rz a turn of 0 or 90 deg about Z (the board's z axis
  points into the printed face, OpenCV's convention, so it points down),
  centred on the point of a 0.25 m grid over the floor that the most
  cameras see well (:func:`_floor_pose`). ``photogram.rig``'s floor frame
  (:func:`floor_frame`: the board's axes of pose 0 made Z-up, x, -y, -z) is
  therefore the world turned about Z (0 or 90 deg) and shifted by
  ``t_bw[0]``. Every
  other pose k is shown to the cameras k and k + 1 (ordered by azimuth):
  centre uniform in the half of the volume nearer them (x, y in [-1.4, 1.4]
  m, z in [0.25, 1.75] m), printed face towards their midpoint, tilted by
  up to 30 deg about a random axis and rolled by up to 45 deg in its plane
  (with the cameras' elevations the board leans from the vertical by a
  median 30-40 deg, at most 60-80 deg, seeds 0 and 1), drawn again (``tries``) until two cameras see it whole with
  squares of 16 px or more. Each pose has a linear (0.2-1 m/s) and
  angular (0-1.5 rad/s) velocity for the motion blur; the pose is the one
  at mid-exposure.
* **Images** (:func:`render_view`): every output pixel is split into
  ``supersample`` x ``supersample`` samples at OpenCV pixel positions (pixel
  centres at integers, the convention of :func:`photogram.io.targets.detect`
  and ``cv2.projectPoints``); each sample's ray is the inverse of the
  distortion (``cv2.undistortPoints`` iterated to 1e-9 px at the pixel
  centres, interpolated within the pixel: < 1e-3 px), intersected with the
  board plane (only within the board's box, found on a 4 px grid); the board texture (``board.generateImage`` with 224 px per
  square and a white paper margin, area-downsampled by powers of 2 to about
  the sample spacing, a mip level per view) is sampled bilinearly
  (``cv2.remap``); the samples are averaged per pixel (area anti-aliasing)
  and composited over a static textured grey background by their coverage.
  The back of the board is plain grey. Motion blur: the mean of
  ``subframes`` renders at sub-poses spread over the ``shutter``, centred on
  the pose. Then a Gaussian lens blur, Gaussian noise, 8-bit rounding and
  JPEG (as :func:`photogram.measure.render.degrade`), and in some views an
  occluding dark bar (an arm) across the board, drawn before the blur.

Texture <-> board coordinates: texel centre ``(u, v)`` of mip level L is the
board point ``x = (u + 0.5) * texel * 2**L - margin`` (same for y), where
``object_points()`` are ``((c + 1) * size, (r + 1) * size)``: the board's
origin is the outer corner of its top-left square (tested).
"""

from photogram.simulation.board_rig.geometry import (RigCamera, BoardPoses, RigRenderSettings,
                                                     normal_settings, harsh_settings,
                                                     rig_cameras, board_poses, true_corners,
                                                     floor_frame, VOLUME_CENTRE, TARGET_SPEC,
                                                     USABLE_DISTANCE)
from photogram.simulation.board_rig.render import (render_view, render_rig)
from photogram.simulation.board_rig.files import (write_rig_set, cameras_toml, detect_rig,
                                                  detect_rendered)

__all__ = ["RigCamera", "BoardPoses", "RigRenderSettings", "normal_settings",
           "harsh_settings", "rig_cameras", "board_poses", "render_view", "render_rig",
           "true_corners", "write_rig_set", "floor_frame", "cameras_toml", "VOLUME_CENTRE",
           "TARGET_SPEC", "detect_rig", "detect_rendered",
           "USABLE_DISTANCE"]
