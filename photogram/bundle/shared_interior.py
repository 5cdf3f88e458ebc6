"""Estimates, sigmas and covariances of shared interior parameters
(:mod:`photogram.adjust.interior_map`): what :func:`~photogram.bundle.
statistics.collect` writes for a project whose cameras share parameters.

* Each camera's parameters in ``cameras.toml`` (``camera_sigma``): shared
  ones (across cameras, ties) with their one value and sigma in every
  camera that uses them; per-station ones with the mean over the
  camera's stations as the value and no sigma (their values and sigmas
  are per station, in ``Camera.station_values`` and the interior table).
* ``covariance.npz`` ``labels``/``matrix`` (the orientation): one row per
  camera parameter (``K1.c``, a parameter shared by K1 and K2 as ``K1.c``
  and ``K2.c``, fully correlated, so that later commands that look up a
  camera's parameters find them) or per station (``K1.x0@S3``), then the
  stations; ``interior_labels``/``interior_matrix``: the covariance of the
  interior unknowns themselves, each shared parameter once
  (:attr:`InteriorMap.labels`).
* ``summary["interior"]``: one row per unknown (:func:`interior_rows`).
"""

from __future__ import annotations

import numpy as np

from photogram.stats.covariance import high_correlations

__all__ = ["collect_shared_cameras", "shared_orientation_columns", "interior_rows"]


def collect_shared_cameras(out, built, cof, s0sq, summary):
    """Estimated values into the cameras of ``out`` (a copy of the project)
    and the camera sigmas; returns ``(camera_sigma, cameras_cov, interior)``
    with ``interior = (labels, covariance)`` of the unknowns."""
    problem, imap = built.problem, built.interior
    st = problem.state
    io_cols = np.arange(imap.n_io)
    cov = s0sq * cof.Qcc[np.ix_(io_cols, io_cols)]
    sig_all = np.sqrt(np.clip(np.diag(cov), 0, None))
    camera_sigma, corr, cams_cov = {}, {}, []
    for k, name in enumerate(built.camera_names):
        cam = out.cameras[name]
        inst = imap.instances_of(k)
        rep = int(inst[0])
        cols = imap.columns[rep]
        names = list(cam.parameters)
        per = {p for p in names if imap.per_station(k, cam, p)}
        sig = {}
        cam.station_values = {}
        for j, p in enumerate(names):
            if p in per:
                values = {imap.station_of(i): float(st.io[i][j]) for i in inst}
                cam.station_values[p] = values
                cam.parameters[p].value = float(np.mean(list(values.values())))
                sig[p] = float("nan")
            else:
                cam.parameters[p].value = float(st.io[rep][j])
                sig[p] = float(sig_all[cols[j]])
        camera_sigma[name] = sig
        cams_cov.append(cov[np.ix_(cols, cols)])
        # correlations among the camera's distinct unknowns (a tie is one)
        seen, keep, labels = set(), [], []
        for j, p in enumerate(names):
            c = int(cols[j])
            if p in per or c in seen or not imap.free[c] or sig_all[c] <= 0:
                continue
            seen.add(c)
            keep.append(c)
            labels.append(p)
        high = high_correlations(cov[np.ix_(keep, keep)], labels)
        for a, b, r in high:
            summary["warnings"].append(f"camera {name}: correlation {a}-{b} = {r:+.3f}")
        corr[name] = high
    summary["high_correlations"] = {k: v for k, v in corr.items() if v}
    summary["interior"] = interior_rows(imap, st, sig_all)
    return camera_sigma, cams_cov, (imap.labels, cov)


def interior_rows(imap, state, sigma):
    """One dict per interior unknown: ``label``, ``cameras``,
    ``parameter``, ``equal`` (parameters tied to it), ``station``,
    ``group``, ``value``, ``free``, ``sigma`` (a-posteriori; None when
    fixed)."""
    value = np.zeros(imap.n_io)
    for i, cols in enumerate(imap.columns):
        value[cols] = state.io[i]
    return [{"label": lab, "cameras": o["cameras"], "parameter": o["parameter"],
             "equal": o["equal"], "station": o["station"], "group": o["group"],
             "value": float(value[c]), "free": bool(imap.free[c]),
             "sigma": float(sigma[c]) if imap.free[c] else None}
            for c, (lab, o) in enumerate(zip(imap.labels, imap.owners))]


def shared_orientation_columns(imap, camera_names, cameras):
    """Columns and labels of the interior part of the orientation
    covariance: per camera and parameter (``K1.c``), per station for
    per-station parameters (``K1.x0@S3``)."""
    cols, labels = [], []
    for k, name in enumerate(camera_names):
        cam = cameras[name]
        inst = imap.instances_of(k)
        for j, p in enumerate(cam.parameters):
            if imap.per_station(k, cam, p):
                for i in inst:
                    cols.append(int(imap.columns[i][j]))
                    labels.append(f"{name}.{p}@{imap.station_of(i)}")
            else:
                cols.append(int(imap.columns[inst[0]][j]))
                labels.append(f"{name}.{p}")
    return np.array(cols, dtype=int), labels
