"""Columns of the results tables that readers below the jump layer need.

exposures.csv of ``photogram intersect`` holds the stick-model parameters
per exposure (photogram.jump computes them); exporters in photogram.io
(.mot) read that table and must know which columns are angles and which
lengths, without importing the jump package, which sits above io.
"""

#: Per-exposure parameters of the stick model, in the order of the
#: covariance matrices. ``v`` (speed of O) is added by
#: :mod:`photogram.jump.propagate` from neighbouring exposures and is always
#: last.
PARAMETERS = ("alpha", "beta", "gamma", "delta_phi", "phi", "heading", "Z0", "v")
#: the angles among them (angle_unit in the results tables)
ANGLE_PARAMETERS = ("alpha", "beta", "gamma", "delta_phi", "phi", "heading")
#: the lengths (length_unit; v in length unit per second)
LENGTH_PARAMETERS = ("Z0",)
