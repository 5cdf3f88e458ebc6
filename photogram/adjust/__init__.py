"""The adjustment engine: parameter blocks, residual blocks, datum and the
Gauss-Newton / Levenberg-Marquardt solver with Schur elimination of points.

A problem is a :class:`~photogram.adjust.state.State` (parameter blocks:
cameras, stations, points) with a :class:`~photogram.adjust.state.Layout`
(which parameters are free, which points are eliminated) plus a list of
residual blocks (image points, control, priors, distances, verticality).
"""
