"""The simulated giant-slalom runs for motion capture (SIMULATED data; docs/mocap.md).

| module | concern |
|---|---|
| ``simulate``, ``skier`` | the runs, the skier's body, the pan-tilt-zoom cameras, truth |
| ``simproject`` | a simulated run written as a motion-capture project folder |
| ``harsh``, ``harsh_detector`` | the harsh setting (issue 22): terrain with a kicker, lagging cameras, a poor detector, bystanders, tracking losses |
| ``harsh_project``, ``harsh_eval`` | the harsh session as project folders; which person's detections a run used |
| ``scene``, ``texture``, ``backdrop``, ``render`` | rendered camera images of a run |
| ``simimages`` | rotation differences measured on the rendered images |

Above :mod:`photogram.mocap` in the layers (docs/index.md): it uses the
motion-capture library (skeleton, cameras, lens, homographies, project
tables); nothing in :mod:`photogram.mocap` imports it. Imports nothing from
commands, report, montecarlo. Empty on purpose: importing the package
loads no module.
"""
