"""``sigma_cmd``: the sigma each command reports for the chain's quantities.

The Monte-Carlo tables compare the empirical sigma of every quantity with
the sigma that the commands print for it. Those are not modelled here but
computed by the commands' own code, once, at the chain's setup, so that they
cannot go stale when a command changes:

* the adjustment step (``photogram orient`` / ``calibrate``): the
  :func:`photogram.bundle.adjust` result of the adjustment project,
  i.e. the sigmas of stations.csv (for ``orient`` with the propagated
  covariance of the calibration and the interior-exterior cross-covariances
  when covariance.npz lies beside the cameras file), points.csv and, for
  ``calibrate``, cameras.toml; for ``orient`` the interior sigmas are those
  the calibration reported (its covariance.npz);
* the intersect step (``photogram intersect``):
  :func:`photogram.jump.pipeline.intersect_jump` on the intersect project,
  with the orientation of the adjustment step and, as ``[intersect]
  orientation`` says, the joint covariance the adjustment step writes into
  covariance.npz (computed now, not read from a results folder that may be
  older than the inputs), i.e. the sigmas of points3d.csv and exposures.csv.

With ``truth = "adjusted"`` the orientation is the command's own result, so
these are exactly the numbers the commands write for the current inputs
(tests/test_montecarlo_honest.py compares them with the files). Quantities
no command reports (points aligned with ``align = "plan"``) are NaN.
"""

from __future__ import annotations

import copy
import logging
from pathlib import Path

import numpy as np

from photogram.errors import PhotogramError
from photogram.geometry import matrix_to_opk
from photogram.jump.definitions import PARAMETERS

__all__ = ["command_sigmas"]

log = logging.getLogger("photogram")


def _same_folder(a, b) -> bool:
    return Path(a).resolve() == Path(b).resolve()


def _orientation_for_intersect(prj2, prj1, result):
    """``(labels, matrix)`` as ``photogram intersect`` combines the folders
    of ``[intersect] orientation``, with the adjustment step's results folder
    taken from ``result`` (the covariance its command writes now)."""
    from photogram.project.results_read import read_orientation_covariance
    where = prj2.intersect.orientation
    if where is None:
        return None
    labels, blocks = [], []
    for folder in where:
        if _same_folder(folder, prj1.output_folder()):
            lab = list(result.covariances["orientation_labels"])
            mat = np.asarray(result.covariances["orientation"])
        else:
            lab, mat = read_orientation_covariance(folder)
        labels.append(list(lab))
        blocks.append(mat)
    from photogram.stats.propagation import combine_covariance_blocks
    union, total = combine_covariance_blocks(labels, blocks)   # later folders override
    return union, total


def _intersect_project_at(prj2, bundle, io, R, X0):
    """The intersect project with the adjustment step's orientation."""
    out = copy.deepcopy(prj2)
    k_index = {n: k for k, n in enumerate(bundle.camera_names)}
    for name, cam in out.cameras.items():
        k = k_index[name]
        for pname, v in zip(cam.parameters, io[k]):
            cam.parameters[pname].value = float(v)
    s_index = {n: s for s, n in enumerate(bundle.station_names)}
    rows = np.array([s_index[n] for n in out.stations.names], dtype=int)
    out.stations.position = np.asarray(X0, dtype=float)[rows].copy()
    out.stations.angles = matrix_to_opk(np.asarray(R)[rows])
    return out


def _stage2(chain, prj1, prj2, result):
    """Sigmas of the jumper points and the stick model as ``photogram
    intersect`` reports them, in the order of the chain's outputs."""
    from photogram.jump.pipeline import intersect_jump
    b, li = chain.bundle, chain.intersect
    st = b.start
    project = _intersect_project_at(prj2, b, st.io, st.R, st.X0)
    jr = intersect_jump(project, _orientation_for_intersect(prj2, prj1, result))
    e_index = {e: i for i, e in enumerate(jr.exposures)}
    rows = [e_index[e] for e in li.exposures]
    var_p = np.diagonal(jr.cov_P, axis1=1, axis2=2)[rows]            # (E, 12)
    if jr.model.cov is None:
        var_s = np.full((len(rows), len(PARAMETERS)), np.nan)
    else:
        var_s = np.diagonal(jr.model.cov, axis1=1, axis2=2)[rows]    # (E, 8)
    return np.sqrt(np.clip(np.concatenate([var_p.ravel(), var_s.ravel()]), 0, None))


def command_sigmas(chain, prj1, prj2=None, result=None):
    """``sigma_cmd`` of every output of ``chain`` (internal units).

    Parameters
    ----------
    chain : Chain
        Set up (outputs, bundle, intersect step).
    prj1, prj2 : Project
        The adjustment and intersect projects as read.
    result : BundleResult, optional
        The adjustment command's result if already computed (``truth =
        "adjusted"``); otherwise it is computed here.
    """
    from photogram.bundle import adjust
    b = chain.bundle
    n_out = len(chain.outputs.names)
    out = np.full(n_out, np.nan)
    if result is None:
        try:
            result = adjust(prj1, fix_interior=chain.fix_interior)
        except PhotogramError as exc:          # the simulation still runs
            log.warning("montecarlo: no command sigmas (sigma_cmd): %s", exc)
            return out
    parts = []
    s_index = {n: i for i, n in enumerate(result.project.stations.names)}
    sig = np.asarray(result.station_sigma, dtype=float)
    parts.append(np.concatenate([sig[s_index[n]] for n in b.station_names]))
    K, p = chain.shape_io
    if chain.fix_interior:
        io_sig = np.sqrt(np.clip(np.diag(chain.io_cov), 0, None))
    else:
        io_sig = np.array([[result.camera_sigma[c].get(q, np.nan) for q in names]
                           + [np.nan] * (p - len(names))
                           for c, names in zip(b.camera_names, b.parameter_names)],
                          dtype=float).ravel()
    parts.append(io_sig[chain.io_random])
    if len(chain.collect):
        if chain.settings.align == "plan":
            parts.append(np.full(3 * len(chain.collect), np.nan))
        else:
            p_index = {n: i for i, n in enumerate(result.project.points.ids)}
            ps = np.asarray(result.point_sigma, dtype=float)
            parts.append(np.concatenate([ps[p_index[b.point_ids[i]]] for i in chain.collect]))
    if chain.intersect is not None and prj2 is not None:
        try:
            parts.append(_stage2(chain, prj1, prj2, result))
        except (PhotogramError, OSError, KeyError) as exc:
            log.warning("montecarlo: no command sigmas of the intersect step: %s", exc)
    v = np.concatenate(parts)
    out[:len(v)] = v
    return out
