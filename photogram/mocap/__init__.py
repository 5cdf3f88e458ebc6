"""Markerless multi-camera motion capture (alpine skiing; docs/mocap.md).

After Bachmann et al., "Motion Capture from Pan-Tilt Cameras with Unknown
Orientation" (part 1: known camera rotations; part 2: unknown rotations).
Subpackages by concern and three modules of project glue; each part
imports only the parts its row names (docs/mocap.md, "Package layout",
checked by tests/test_mocap_layout.py):

| part | concern | may import (of mocap) |
|---|---|---|
| ``pipeline`` | the run of ``photogram mocap``: project -> results | all below |
| ``outputs`` | the results folder | ``files``, subpackages |
| ``files`` | the project's tables: cameras, camera_frames, limbs, joints | subpackages |
| ``evaluation`` | metrics (appendix C), checks of a run | ``body`` |
| ``reconstruction`` | cameras per frame, DCT, energy, solvers; known and | ``body``, ``motion`` |
| | unknown rotations (bootstrap, joint optimisation) | |
| ``sources`` | observation sources: JSON, CSV, mediapipe, plugin | ``tracking``, ``body`` |
| ``tracking`` | a camera's candidate detections, athlete tracking (4.1) | ``body`` |
| ``motion`` | camera rotations: differences from images, filter, files, E_rot | -- |
| ``body`` | skeletons and their mappings, segment masses (de Leva) | -- |

The simulated giant-slalom runs and their rendered images are
:mod:`photogram.simulation.ski` (above this package: it may import
photogram.mocap, never the reverse). Nothing here imports
photogram.simulation, commands, report, montecarlo, jump or measure.
"""
