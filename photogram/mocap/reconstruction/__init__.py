"""3D joints from 2D detections: the cameras of a run (``cameras``: rotations
and interior orientation per frame), DCT trajectories and windows
(``dct``), the energy of eqs. (7)-(10) (``energy``) and its solvers
(``solvers``), the reconstruction with known rotations (``reconstruct``,
sections 4.3-4.4), and with unknown rotations (section 4.5): the start
(``bootstrap``, ``bearings``), the joint energy and its solver (``joint``,
``joint_solver``) and the whole estimate (``estimate``); ``blas``: the
solvers run with one BLAS thread.

May import :mod:`photogram.mocap.body` and :mod:`photogram.mocap.motion`
(the rotation model); never the sources, the tracking, the evaluation or
the project glue (``files``, ``outputs``, ``pipeline``). Empty on purpose:
importing the package loads no module.
"""
