"""The calibrate/orient pipeline of the one engine, as a library.

read project -> approximate values (chain) -> build problem -> datum check
-> solve -> robust reweighting / data snooping / variance components ->
statistics -> :class:`BundleResult`.

- :mod:`photogram.bundle.run`: :func:`adjust` (the pipeline)
- :mod:`photogram.bundle.approximate`: :func:`approximate_if_needed`
- :mod:`photogram.bundle.statistics`: estimates, sigmas, covariances, weak points
- :mod:`photogram.bundle.result`: :class:`BundleResult`, residual columns,
  the finiteness check

Writing the results folder is the command's job
(:mod:`photogram.commands.bundle`); reading one back is the project layer's
(:mod:`photogram.project.results_read`).
"""

from photogram.bundle.approximate import approximate_if_needed
from photogram.bundle.result import BundleResult, check_finite, residual_columns
from photogram.bundle.run import adjust

__all__ = ["adjust", "approximate_if_needed", "BundleResult", "check_finite",
           "residual_columns"]
