"""Rendered test videos of the simulated ski jump, with known truth
(issue 19, item 6): the input of the video tracker (:mod:`photogram.track`).

What is simulated
-----------------
The jump of :func:`photogram.simulation.jump.jump_truth` (24 exposures at
30 fps, hill coordinates in **dm**: X down the hill, Y to the left looking
down the hill, Z up) filmed by the three field cameras S1, S2, S3 of
:func:`photogram.simulation.ski_lines.field_cameras` (the TRUE orientations
and interior orientations, brown model with its distortion; 640 x 480 px,
grey), one video per camera:

* static scene, rendered once per camera (:mod:`.scene`): the 35 degree
  landing slope (plane of ``slope_height``) ray-traced with 2 x 2 samples per
  pixel: prepared snow for |Y| <= 150 dm (grey ~212, low-contrast grain,
  grooming ridges, faint distance lines across it every 5 m), rough snow
  beyond, snowy forest (mid grey) beyond |Y| = 600 dm; rays that miss the
  slope see a hazy distant landscape and overcast sky (S1 sees the jumper
  against it). The control and tie points of ``field_design`` are dark balls
  (radius ``target_radius``; truth in ``truth_targets``), P1-P6 on poles,
  F1-F2 on masts. Every static object near the jumper's images is on the far
  side of the slope (behind the jumper): none hides a marker;
* the jumper (:mod:`.actors`): a dark suit of capsules between joints derived
  from P1..P4 (trunk P2 to the shoulders, thighs and shanks to ankles above
  the bindings, boots, arms along the body), a grey helmet ball at P1, two
  skis as boxes 1.0 dm wide and 0.3 dm thick centred on the true ski axes
  tail..tip, and four **reflective markers**: bright uniform discs (grey 245)
  of the balls of radius ``marker_radius`` centred exactly at P1..P4, drawn
  over the body (the body never hides them; only ``occlusions`` do). The
  jumper is only there in the 24 exposure frames; the ``lead_in`` and
  ``lead_out`` frames show the empty arena;
* optional bystanders walking slowly on the far side of the slope (seen by
  all three cameras, near the images of the flight path in S2 and S3), dark
  with a bright reflective patch on the jacket (a false marker);
* per frame: shapes painted far to near on a 4 x 4 supersampled canvas of
  the moving objects' bounding box, markers as area-sampled discs (16 x 16
  samples per pixel), averaged to pixels; motion blur = the mean of
  ``subframes`` such renders spread over the ``shutter`` around the frame
  time; then a per-frame brightness factor (``gain_jitter``, harsh only),
  defocus blur, Gaussian noise and 8-bit rounding
  (:func:`photogram.measure.render.degrade`) and JPEG at ``jpeg_quality``.
  The AVI files written by :func:`write_jump_videos` hold these JPEGs
  unchanged: OpenCV's MJPEG reader decodes exactly the rendered frames,
  FFmpeg's (OpenCV's default backend) within 1 grey level.

Pixel convention
----------------
The image coordinates are those of :meth:`ViewCamera.project
<photogram.lines.views.ViewCamera.project>` in the project's convention
(docs/measure.md; the frame of the project's image points, of the lab
renderer :mod:`photogram.measure.scenes` and of ``photogram measure``): x to
the right, y down, **the top-left corner of the image at (0, 0)**, the centre
of pixel (column i, row j) at (i + 0.5, j + 0.5). A frame array
``frames[st][k]`` is indexed ``[row, column]`` = ``[y, x]``; the raster
position (OpenCV's, pixel centres at integers) of an image point is its
coordinates minus 0.5 (:func:`render.drawing_camera` paints with the
principal point moved by -0.5 px).

Timing
------
Exposure ``e`` (0-based; named ``f"{e + 1:03d}"``) is at time ``e / 30`` s;
in a video with offset 0 it is frame ``lead_in + e``. A camera with
``offsets[st] = d`` starts ``d`` frames late: exposure ``e`` is its frame
``lead_in + e - d`` (``JumpVideos.exposure_frames[st]``); all videos have
``lead_in + 24 + lead_out`` frames. ``frames.csv`` gives the offset-0
frame numbers; the true offsets are in ``truth/offsets.csv`` only.

Truth
-----
``truth_markers`` (station, frame, exposure, marker, x, y, visible): x, y is
``ViewCamera.project`` of the marker ball's centre (P1..P4 of
``jump_truth``) at the middle of the shutter, which is the exposure time;
``visible`` is False when the marker is occluded (``occlusions``) or its
centre lies outside the image (x outside [0, 640] or y outside
[0, 480]; a marker near the border may still be cut). The area
coverage of a rendered marker disc matches the exact area-sampled disc
within 0.005 (tests/test_jump_video.py); its centroid, before blur, noise
and compression, is the truth within 0.03 px on a uniform background (the
pixel locking of area sampling a ~2.7 px disc; motion blur reduces it to
~0.01 px). On the body the centroid of (frame - frame without the
marker) / (245 - frame without the marker) is within 0.04 px (S1) to
0.14 px (S2, S3) of the truth without blur, up to 0.29 px with the harsh
1/200 s blur: edges of suit, boots and skis of different grey pass under
the disc. P3 and P4
are 2.4 dm apart across the jumper and image 1-3 px apart, so their discs
overlap in most frames. ``truth_skis`` (station, frame, exposure, ski,
x_tail, y_tail, x_tip, y_tip): images of the ends of the ski axis (ski L1 =
right = index 0, L2 = left = index 1, as ``projects/jumps``). ``seeds``
(station, frame, marker, x, y): one simulated click per marker and station,
as a user would give them: all in one frame number of the three videos (the
first in which every station shows all four markers visible; with a sync
lag that frame shows a later exposure in the late camera, and the click is
where the marker is in that frame), the truth plus N(0, ``click_sigma`` =
0.7 px) per axis.

Settings
--------
:class:`VideoSettings` (defaults: the normal set) and :func:`harsh_settings`
(the harsher set the trackers were not tuned on: more noise, JPEG 60, a
longer shutter, brightness flicker, bystanders, marker occlusions, a
one-frame sync lag of S3).
Everything is a pure function of the settings (seeded).
"""

from photogram.simulation.jump_video.render import JumpVideos, render_jump_videos
from photogram.simulation.jump_video.settings import (
    IMAGE_SIZE, MARKERS, SKIS, STATIONS, VideoSettings, harsh_settings)
from photogram.simulation.jump_video.write import read_video, write_jump_videos

__all__ = ["VideoSettings", "harsh_settings", "JumpVideos", "render_jump_videos",
           "write_jump_videos", "read_video", "IMAGE_SIZE", "MARKERS", "SKIS", "STATIONS"]
