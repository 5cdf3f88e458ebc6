"""Jumper markers and ski lines tracked in synchronized videos of a jump
(issue 19: from pixels to observations, part 2).

From one video per camera, the field orientation and one seed click per
marker to the ``jumper_points.csv`` and ``ski_lines.csv`` that
``photogram intersect`` reads. See docs/track.md.
"""
