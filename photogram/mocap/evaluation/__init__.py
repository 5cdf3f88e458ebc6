"""What is measured on and checked of a run: the metrics of appendix C
(``metrics``: PCK, MPJPE, bone lengths, centre of mass, speed, joint
angles, lean, fore/aft) and the checks that refuse or warn instead of a
silently wrong result (``checks``: coverage of the detections, angle unit,
fit of the cameras).

May import :mod:`photogram.mocap.body`; never the other subpackages or the
project glue (``files``, ``outputs``, ``pipeline``). Empty on purpose:
importing the package loads no module.
"""
