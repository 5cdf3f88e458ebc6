"""The statistics of an adjusted bundle: estimates and a-posteriori sigmas
into a copy of the project, the joint covariance of the orientation (with
that of a fixed calibrated interior, when known), weak points."""

from __future__ import annotations

import copy

import numpy as np

from photogram.bundle.result import BundleResult
from photogram.geometry import matrix_to_opk
from photogram.stats.covariance import (
    camera_covariances, high_correlations, point_covariances, station_covariances)


def flag_weak_points(result, problem, summary):
    """Largest intersection angle per point; points below WEAK_ANGLE_DEG
    are flagged (points.csv ``est_weak_angle``, a summary warning,
    ``summary["weak_points"]``)."""
    from photogram.stats.geometry import (
        WEAK_ANGLE_DEG, problem_intersection_angles, weak_angle_warning, weak_points)
    angles = problem_intersection_angles(problem)
    weak = weak_points(angles)
    ids = result.project.points.ids
    result.point_extra = {"est_angle": angles, "est_weak_angle": weak.astype(int)}
    summary["weak_points"] = {"threshold_deg": WEAK_ANGLE_DEG, "count": int(weak.sum()),
                              "ids": [ids[i] for i in np.flatnonzero(weak)]}
    warning = weak_angle_warning(ids, angles)
    if warning:
        summary["warnings"].append(warning)


def apriori_image_sigma(problem):
    """RMS of the a-priori sigmas of the image observations (image unit), so
    that sigma0 x this is the a-posteriori image sigma (DBAT's "Sigma0
    (pixels)")."""
    sig = [b.sigma[:, 0] for b in problem.blocks if b.name == "image points"]
    return float(np.sqrt(np.mean(np.concatenate(sig) ** 2))) if sig else float("nan")


def with_calibration_covariance(result, built, s0sq, summary):
    """With the interior orientation fixed at calibrated values whose
    covariance is known (covariance.npz beside the cameras file), report the
    covariance of the stations including that uncertainty, with the
    interior-exterior cross-covariances (photogram.stats.interior.py)."""
    from photogram.geometry import angle_increment_map
    from photogram.stats.interior import calibration_covariance, interior_sensitivity
    found = calibration_covariance(result.project)
    if found is None or built is None:
        return
    if getattr(built, "rigs", None) is not None:
        summary["warnings"].append(
            "the covariance of the fixed interior orientation is not propagated to the "
            "stations of a project with rigs (not implemented): station sigmas without it")
        return
    labels, Sio, folder = found
    D, cof = interior_sensitivity(built.problem, built.camera_names, result.project, labels)
    _, E = angle_increment_map(built.problem.state.R)
    n_s = len(E)
    ang = (6 * np.arange(n_s)[:, None] + 3 + np.arange(3)).ravel()
    D[ang] = np.matmul(E, D[ang].reshape(n_s, 3, -1)).reshape(3 * n_s, -1)   # angles
    lab_st = [f"{st}.{p}" for st in result.project.stations.names
              for p in ("X0", "Y0", "Z0", "omega", "phi", "kappa")]
    cols = built.problem.layout.station_cols.ravel()
    Q_st = _angles_in_place(cof.Qcc[np.ix_(cols, cols)], E, 0)
    S_full = s0sq * Q_st + D @ Sio @ D.T
    cov = np.block([[Sio, Sio @ D.T], [D @ Sio, S_full]])
    result.station_sigma = np.sqrt(np.clip(np.diag(S_full), 0, None)).reshape(n_s, 6)
    idx = np.arange(n_s)[:, None] * 6 + np.arange(6)
    result.covariances["stations"] = S_full[idx[:, :, None], idx[:, None, :]]  # (n_s, 6, 6)
    result.covariances.update({"orientation_labels": labels + lab_st, "orientation": cov})
    summary["interior_covariance"] = {
        "from": str(folder), "parameters": labels,
        "note": "station sigmas and covariance.npz include the covariance of the fixed "
                "interior orientation, propagated, with interior-exterior cross-covariances"}


def collect(project, built, cof, s0sq, summary):
    """Estimated values and a-posteriori sigmas into a copy of the project."""
    problem = built.problem
    st = problem.state
    out = copy.deepcopy(project)
    n_s = len(project.stations)         # rigs add their sensor poses after the stations
    out.points.xyz = st.points.copy()
    out.stations.position = st.X0[:n_s].copy()
    out.stations.angles = matrix_to_opk(st.R[:n_s])
    interior = None
    if getattr(built, "interior", None) is not None:     # shared interior parameters
        from photogram.bundle.shared_interior import collect_shared_cameras
        camera_sigma, cams, interior = collect_shared_cameras(out, built, cof, s0sq, summary)
    else:
        camera_sigma, cams = _collect_cameras(out, built, cof, s0sq, summary)
    P = point_covariances(cof, s0sq)
    S = station_covariances(cof, st.R, s0sq)
    if getattr(built, "rigs", None) is not None:
        summary["rigs"] = _rig_sensors(out, built.rigs, st, S[n_s:])
    S = S[:n_s]
    point_sigma = np.sqrt(np.clip(np.diagonal(P, axis1=1, axis2=2), 0, None))
    station_sigma = np.sqrt(np.clip(np.diagonal(S, axis1=1, axis2=2), 0, None))
    if len(built.check):
        d = st.points[built.check] - project.points.xyz[built.check]
        summary["check_points"] = {
            "ids": [project.points.ids[i] for i in built.check],
            "differences": d.tolist(),
            "rmse": np.sqrt(np.mean(d ** 2, axis=0)).tolist()}
    labels, cov = orientation_covariance(cof, problem, project, built.camera_names, s0sq,
                                         interior=getattr(built, "interior", None))
    covariances = {"points": P, "stations": S, "cameras": cams,
                   "orientation_labels": labels, "orientation": cov}
    if interior is not None:
        covariances["interior_labels"], covariances["interior"] = interior
    return BundleResult(out, summary, camera_sigma, station_sigma, point_sigma, {}, covariances)


def _collect_cameras(out, built, cof, s0sq, summary):
    """Each camera's estimated parameters into ``out`` and their sigmas
    (every parameter one value per camera); high correlations into the
    summary. Returns ``(camera_sigma, covariance per camera)``."""
    st = built.problem.state
    cams = camera_covariances(cof, s0sq)
    camera_sigma, corr = {}, {}
    for k, name in enumerate(built.camera_names):
        cam = out.cameras[name]
        for pname, v in zip(cam.parameters, st.io[k]):
            cam.parameters[pname].value = float(v)
        sig = np.sqrt(np.clip(np.diag(cams[k]), 0, None))
        camera_sigma[name] = dict(zip(cam.parameters, sig.tolist()))
        free = cam.free_mask() & (sig > 0)
        names = [n for n, f in zip(cam.parameters, free) if f]
        high = high_correlations(cams[k][np.ix_(free, free)], names)
        for a, b, r in high:
            summary["warnings"].append(f"camera {name}: correlation {a}-{b} = {r:+.3f}")

        corr[name] = high
    summary["high_correlations"] = {k: v for k, v in corr.items() if v}
    return camera_sigma, cams


def orientation_covariance(cof, problem, project, camera_names, s0sq, interior=None):
    """Joint covariance of all interior parameters and exterior orientations
    (X0 Y0 Z0 in length units, omega phi kappa in radians), with the
    cross-covariances between stations, for propagation by later commands.
    With shared interior parameters (``interior``, an InteriorMap) one row
    per camera parameter or per station of a per-station parameter
    (:func:`photogram.bundle.shared_interior.shared_orientation_columns`).
    """
    lay = problem.layout
    if interior is not None:
        from photogram.bundle.shared_interior import shared_orientation_columns
        io_cols, io_labels = shared_orientation_columns(interior, camera_names, project.cameras)
    else:
        io_cols = np.concatenate([c for c in lay.camera_cols]) if lay.camera_cols else \
            np.zeros(0, dtype=int)
        io_labels = [f"{n}.{p}" for n in camera_names for p in project.cameras[n].parameters]
    n_s = len(project.stations)         # rigs add their sensor poses after the stations
    cols = np.concatenate([io_cols, lay.station_cols[:n_s].ravel()])
    Q = cof.Qcc[np.ix_(cols, cols)]
    from photogram.geometry import angle_increment_map
    _, E = angle_increment_map(problem.state.R[:n_s])
    _angles_in_place(Q, E, len(io_cols))
    Q *= s0sq
    labels = list(io_labels)
    labels += [f"{st}.{p}" for st in project.stations.names
               for p in ("X0", "Y0", "Z0", "omega", "phi", "kappa")]
    return labels, Q


def _angles_in_place(Q, E, n_io):
    """``Q <- T Q T^T`` with ``T`` the identity except the 3x3 blocks ``E``
    (n_s, 3, 3) at the rotation rows of the stations (the 6 columns of
    station s start at ``n_io + 6 s``), block by block instead of two dense
    products."""
    n_s = len(E)
    if n_s == 0:
        return Q
    ang = (n_io + 6 * np.arange(n_s)[:, None] + 3 + np.arange(3)).ravel()
    n = len(Q)
    Q[ang] = np.matmul(E, Q[ang].reshape(n_s, 3, n)).reshape(3 * n_s, n)
    Q[:, ang] = np.einsum("nsj,sij->nsi", Q[:, ang].reshape(n, n_s, 3), E).reshape(n, 3 * n_s)
    return Q


def _rig_sensors(out, plan, state, S):
    """The adjusted pose of every rig camera in its rig into ``out.rigs``
    and as rows for summary.json: rig, camera, X0 Y0 Z0 (length unit),
    omega phi kappa (radians) and their a-posteriori sigmas (0: fixed).
    The frames' poses are their reference images' stations."""
    rows = []
    for j, (rig, cam) in enumerate(plan.sensors):
        k = plan.n_stations + j
        angles = matrix_to_opk(state.R[k][None])[0]
        out.rigs[rig].sensors[cam] = (state.X0[k].copy(), angles)
        sig = np.sqrt(np.clip(np.diag(S[j]), 0, None))
        rows.append({"rig": rig, "camera": cam, "reference": out.rigs[rig].reference,
                     "position": state.X0[k].tolist(), "angles_rad": angles.tolist(),
                     "position_sigma": sig[:3].tolist(), "angle_sigma_rad": sig[3:].tolist(),
                     "angle_covariance_rad": S[j][3:, 3:].tolist()})
    return rows
